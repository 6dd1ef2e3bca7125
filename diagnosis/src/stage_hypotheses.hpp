#pragma once
/// Diagnosis stage 5, hypotheses: every available effect fitted and judged against the refit
/// baseline (information criterion, held-out gain, significance), pairs of the most promising
/// ones, the over-dispersion of the best model, and the chosen model.
#include <utility>
#include <vector>

#include "diagnosis/diagnose.hpp"
#include "model_fit.hpp"
#include "stage_baseline.hpp"
#include "stage_mismatch.hpp"

namespace lw::diagnosis::detail {

/// What the encompassing rule (PreferEncompassing) decided.
struct Encompassing {
  int best = -1;            ///< the chosen model after the rule
  int explained_away = -1;  ///< the best-scoring single effect, explained away by `by` in their joint fit, or -1
  int by = -1;              ///< the single effect that explains it away (accepted: it is `best`; not: nothing is named)
};

struct Hypotheses {
  std::vector<ModelEval> evals;                       ///< single effects (in Effect order), then pairs
  size_t singles = 0;                                 ///< how many of `evals` are single effects
  std::vector<std::pair<size_t, size_t>> pair_parts;  ///< per pair (evals[singles + k]): its single effects
  double dispersion = 1;      ///< best reduced chi-square, at least 1: every chi-square gain is divided by it
  int best = -1;              ///< index of the chosen model in `evals`, -1 when none is accepted
  Encompassing encompassing;  ///< the encompassing rule's decision (PreferEncompassing)
  const ModelEval* Chosen() const { return best >= 0 ? &evals[static_cast<size_t>(best)] : nullptr; }
};

/// The effects the data can test: squeeze_wear needs normal stress, throughput_variation a varying tonnage log.
std::vector<Effect> AvailableEffects(bool has_normal, bool throughput_available);

/// Sets ev's delta_bic, held-out gain, significance, score and accepted, against `null_eval`.
/// `map_harmonic1_sd`: the map's own first-harmonic error (Problem::map_harmonic1_sd), added to
/// feed segregation's standard error.
void Judge(ModelEval& ev, const ModelEval& null_eval, size_t rows, double log_n, double dispersion, double map_harmonic1_sd);

/// Squeeze wear must be the normal stress's: on a real DEM map the stress follows the wear (the same
/// contacts), so I + beta n is mostly the map blended with a broader smoothing of itself. An accepted
/// squeeze_wear (and every pair holding it) is refused, with a note, when the same model with the map
/// smoothed like the stress (ModelPoint::broad_i) in the stress's place fits about as well: squeeze wear must beat
/// it by more than Thresholds::min_holdout_gain (x the dispersion) both in-sample and held out.
void RequireStressShape(Hypotheses& h, const Problem& prob, const NullModel& null, const std::vector<Fold>& folds, double k_scale,
                        std::vector<std::string>& notes);

/// Up to three single effects (indices into `evals`), best score first, with delta_bic > 0 and one
/// form per effect: the candidates for pairs.
std::vector<size_t> PairCandidates(const std::vector<ModelEval>& evals);

/// Over-dispersion: the smallest reduced chi-square over the baseline and `evals`, at least 1.
double Dispersion(const ModelEval& null_eval, const std::vector<ModelEval>& evals, size_t rows);

/// A pair stays accepted only when it beats both its single effects (pair_delta_bic and held out)
/// and predicts held-out data no worse than any accepted single effect.
void ApplyPairRules(Hypotheses& h, double log_n);

/// The accepted model with the highest score, -1 when none.
int BestAccepted(const std::vector<ModelEval>& evals);

/// Encompassing: when the chosen model `h.best` is a single effect A and another single effect B,
/// fitted together with A (their pair), keeps its size at least one standard error from zero while
/// A's falls within one (B explains what A fitted; A does not explain B), and B alone predicts the
/// held-out data at least as well as A alone, A is not the explanation. If B is accepted on its own,
/// B is (the best-scoring such B); if not, nothing is named (`best` -1, `unexplained`): the mismatch
/// A fitted is real, but which effect it is the data do not determine. Information criteria prefer
/// the effect with fewer parameters when two fit alike; the joint fit and the held-out data say
/// which one the data need.
Encompassing PreferEncompassing(const Hypotheses& h, double dispersion, double map_harmonic1_sd);

/// The whole stage (writes noise["dispersion"]).
Hypotheses TestHypotheses(const Problem& prob, const Baseline& base, const NullModel& null, const std::vector<Fold>& folds,
                          const std::vector<Effect>& available, bool try_pairs, DiagnosisResult& result);

}  // namespace lw::diagnosis::detail
