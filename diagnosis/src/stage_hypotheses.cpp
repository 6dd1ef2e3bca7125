// Diagnosis stage 5, hypotheses (stage_hypotheses.hpp).
#include "stage_hypotheses.hpp"

#include <algorithm>
#include <cstdio>
#include <limits>
#include <numeric>
#include <string>

namespace lw::diagnosis::detail {
namespace {

bool SameEffect(const ModelEval& a, const ModelEval& b) {
  return std::string(EffectName(a.full.spec.effects[0])) == EffectName(b.full.spec.effects[0]);
}

}  // namespace

std::vector<Effect> AvailableEffects(bool has_normal, bool throughput_available) {
  std::vector<Effect> available;
  for (int e = 0; e < kEffectCount; ++e) {
    const auto effect = static_cast<Effect>(e);
    if (effect == Effect::kSqueezeWear && !has_normal) continue;
    if (effect == Effect::kThroughputVariation && !throughput_available) continue;
    available.push_back(effect);
  }
  return available;
}

void Judge(ModelEval& ev, const ModelEval& null_eval, size_t rows, double log_n, double dispersion, double map_harmonic1_sd) {
  const Thresholds th;
  const double p_extra = static_cast<double>(ev.full.spec.ParamCount() - rows);
  ev.delta_bic = (null_eval.full.chi2 - ev.full.chi2) / dispersion - p_extra * log_n;
  ev.ho_gain = (null_eval.ho_chi2 - ev.ho_chi2) / dispersion;
  ev.ho_rel = null_eval.ho_chi2 > 0 ? ev.ho_gain / null_eval.ho_chi2 : 0;
  ev.significance = std::numeric_limits<double>::max();
  for (Effect e : ev.full.spec.effects)
    ev.significance = std::min(ev.significance, Significance(ev.full, e, dispersion, map_harmonic1_sd));
  ev.accepted = ev.delta_bic > th.min_delta_bic && ev.ho_gain > th.min_holdout_gain && ev.ho_rel > th.min_holdout_rel &&
                ev.significance > th.min_significance;
  ev.score = ev.delta_bic + ev.ho_gain;
}

std::vector<size_t> PairCandidates(const std::vector<ModelEval>& evals) {
  std::vector<size_t> order(evals.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return evals[a].score > evals[b].score; });
  std::vector<size_t> top;
  for (size_t k : order) {
    bool same_effect = false;  // the weaker form of an effect already in the list
    for (size_t t : top)
      if (SameEffect(evals[t], evals[k])) same_effect = true;
    if (evals[k].delta_bic > 0 && top.size() < 3 && !same_effect) top.push_back(k);
  }
  return top;
}

double Dispersion(const ModelEval& null_eval, const std::vector<ModelEval>& evals, size_t rows) {
  double best_reduced =
      null_eval.full.chi2 / std::max(1.0, static_cast<double>(null_eval.full.n_train) - static_cast<double>(rows));
  for (const ModelEval& ev : evals) {
    const double dof_m = std::max(1.0, static_cast<double>(ev.full.n_train) - static_cast<double>(ev.full.spec.ParamCount()));
    best_reduced = std::min(best_reduced, ev.full.chi2 / dof_m);
  }
  return std::max(1.0, best_reduced);
}

void ApplyPairRules(Hypotheses& h, double log_n) {
  const Thresholds th;
  std::vector<ModelEval>& evals = h.evals;
  const size_t singles = h.singles;
  // A pair must beat both of its single effects on both criteria.
  for (size_t k = singles; k < evals.size(); ++k) {
    ModelEval& ev = evals[k];
    for (size_t part : {h.pair_parts[k - singles].first, h.pair_parts[k - singles].second}) {
      const double gain = (evals[part].full.chi2 - ev.full.chi2) / h.dispersion -
                          static_cast<double>(ev.full.spec.ParamCount() - evals[part].full.spec.ParamCount()) * log_n;
      if (gain < th.pair_delta_bic || ev.ho_chi2 > evals[part].ho_chi2) ev.accepted = false;
    }
    // Parsimony: a pair that predicts held-out data worse than an accepted single effect is not
    // preferred to it (two effects can mimic a third one in-sample: hardening + squeeze wear
    // together look like a moving profile).
    for (size_t m = 0; m < singles; ++m)
      if (evals[m].accepted && ev.ho_chi2 > evals[m].ho_chi2) ev.accepted = false;
  }
}

int BestAccepted(const std::vector<ModelEval>& evals) {
  // A pair when accepted, else the best single.
  int best = -1;
  for (size_t k = 0; k < evals.size(); ++k) {
    if (!evals[k].accepted) continue;
    if (best < 0 || evals[k].score > evals[static_cast<size_t>(best)].score) best = static_cast<int>(k);
  }
  return best;
}

Encompassing PreferEncompassing(const Hypotheses& h, double dispersion, double map_harmonic1_sd) {
  constexpr double kExplainedAwaySe = 1.0;
  Encompassing out;
  out.best = h.best;
  if (h.best < 0 || static_cast<size_t>(h.best) >= h.singles) return out;
  const auto a = static_cast<size_t>(h.best);
  const ModelEval& ea = h.evals[a];
  int accepted_b = -1, other_b = -1;
  for (size_t k = h.singles; k < h.evals.size(); ++k) {
    const auto [p, q] = h.pair_parts[k - h.singles];
    if (p != a && q != a) continue;
    const size_t b = p == a ? q : p;
    const ModelEval& eb = h.evals[b];
    if (eb.ho_chi2 > ea.ho_chi2) continue;
    const FitResult& joint = h.evals[k].full;
    // Within one standard error of nothing once B is fitted, while B is not: A was B's shadow.
    const double sig_a = Significance(joint, ea.full.spec.effects[0], dispersion, map_harmonic1_sd);
    const double sig_b = Significance(joint, eb.full.spec.effects[0], dispersion, map_harmonic1_sd);
    if (!(sig_a < kExplainedAwaySe && sig_b >= kExplainedAwaySe)) continue;
    int& slot = eb.accepted ? accepted_b : other_b;
    if (slot < 0 || eb.score > h.evals[static_cast<size_t>(slot)].score) slot = static_cast<int>(b);
  }
  if (accepted_b >= 0 || other_b >= 0) {
    out.explained_away = h.best;
    out.by = accepted_b >= 0 ? accepted_b : other_b;
    out.best = accepted_b;  // -1: what A fitted is real, but no effect is determined
  }
  return out;
}

void RequireStressShape(Hypotheses& h, const Problem& prob, const NullModel& null, const std::vector<Fold>& folds, double k_scale,
                        std::vector<std::string>& notes) {
  std::vector<ModelEval>& evals = h.evals;
  for (size_t k = 0; k < h.singles; ++k) {
    ModelEval& ev = evals[k];
    if (!ev.accepted || ev.full.spec.effects[0] != Effect::kSqueezeWear) continue;
    Problem broad = prob;
    for (ModelPoint& p : broad.points) p.normal_i = p.broad_i;
    ModelEval alt = Evaluate(broad, ev.full.spec, {}, null.fit, folds, k_scale);
    char text[400];
    // The bar every hypothesis clears held out against the refit baseline, here in and out of sample.
    const double bar = Thresholds{}.min_holdout_gain * h.dispersion;
    if (alt.full.chi2 - ev.full.chi2 > bar && alt.ho_chi2 - ev.ho_chi2 > bar) {
      std::snprintf(text, sizeof text,
                    "squeeze_wear follows the normal stress: the map smoothed like the stress, in the stress's place, fits "
                    "worse (chi-square %.1f against %.1f, held out %.1f against %.1f; by more than %.1f each)",
                    alt.full.chi2, ev.full.chi2, alt.ho_chi2, ev.ho_chi2, bar);
      notes.push_back(text);
      continue;
    }
    ev.accepted = false;
    for (size_t q = h.singles; q < evals.size(); ++q) {
      const auto [a, b] = h.pair_parts[q - h.singles];
      if (a == k || b == k) evals[q].accepted = false;
    }
    std::snprintf(text, sizeof text,
                  "squeeze_wear not named: the map smoothed like the normal stress, in the stress's place, fits about as "
                  "well (chi-square %.1f against %.1f, held out %.1f against %.1f; squeeze wear must be better by more "
                  "than %.1f in both): what it fitted is the map's smoothing scale, not normal stress",
                  alt.full.chi2, ev.full.chi2, alt.ho_chi2, ev.ho_chi2, bar);
    notes.push_back(text);
  }
}

Hypotheses TestHypotheses(const Problem& prob, const Baseline& base, const NullModel& null, const std::vector<Fold>& folds,
                          const std::vector<Effect>& available, bool try_pairs, DiagnosisResult& result) {
  Hypotheses h;
  std::vector<ModelEval>& evals = h.evals;
  // Over-dispersion (quasi-likelihood): when even the best model leaves chi2/dof > 1, the noise model
  // is too optimistic for this data, and every chi-square gain is divided by that factor. 1 until
  // every model is fitted.
  auto judge = [&](ModelEval& ev) { Judge(ev, null.eval, prob.rows, null.log_n, h.dispersion, prob.map_harmonic1_sd); };
  for (Effect e : available) {
    ModelSpec spec = base.spec;
    spec.effects = {e};
    ModelEval ev = Evaluate(prob, spec, {}, null.fit, folds, base.k_scale);
    judge(ev);
    evals.push_back(std::move(ev));
  }
  h.singles = evals.size();
  // Pairs among the most promising single effects.
  if (try_pairs) {
    const std::vector<size_t> top = PairCandidates(evals);
    for (size_t a = 0; a < top.size(); ++a) {
      for (size_t b = a + 1; b < top.size(); ++b) {
        // Two forms of the same effect are alternatives, not a pair.
        if (SameEffect(evals[top[a]], evals[top[b]])) continue;
        ModelSpec spec = base.spec;
        spec.effects = {evals[top[a]].full.spec.effects[0], evals[top[b]].full.spec.effects[0]};
        ModelEval ev = Evaluate(prob, spec, {&evals[top[a]].full, &evals[top[b]].full}, null.fit, folds, base.k_scale);
        judge(ev);
        h.pair_parts.push_back({top[a], top[b]});
        evals.push_back(std::move(ev));
      }
    }
  }
  h.dispersion = Dispersion(null.eval, evals, prob.rows);
  result.noise["dispersion"] = Round(h.dispersion, 3);
  for (ModelEval& ev : evals) judge(ev);
  RequireStressShape(h, prob, null, folds, base.k_scale, result.notes);
  ApplyPairRules(h, null.log_n);
  h.best = BestAccepted(evals);
  h.encompassing = PreferEncompassing(h, h.dispersion, prob.map_harmonic1_sd);
  h.best = h.encompassing.best;
  return h;
}

}  // namespace lw::diagnosis::detail
