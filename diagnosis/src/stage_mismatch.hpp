#pragma once
/// Diagnosis stage 4, mismatch test: the baseline refitted on all observations with the noise model
/// (per-sensor intensity error profiled out), its chi-square excess in sigmas, and its hold-out
/// evaluation (what every hypothesis is compared with). Also the benchmarks' oracle: the true
/// effect with its true parameters against that refit baseline.
#include <optional>
#include <vector>

#include "diagnosis/diagnose.hpp"
#include "model_fit.hpp"
#include "stage_baseline.hpp"

namespace lw::diagnosis::detail {

/// The refit baseline's chi-square split by observation type: sensor events, the sensors'
/// intensity-error priors (u^2 / sigma_u^2), scan cells (with the band offsets' priors). Each type
/// has its own noise terms, so each is checked against its own count.
struct Chi2Parts {
  double events = 0, priors = 0, scan = 0;
  size_t n_events = 0, n_priors = 0, n_scan = 0;
};

struct NullModel {
  FitResult fit;          ///< the baseline refitted on every observation, noise model on
  Eigen::MatrixXd w;      ///< its simulated wear (points x steps)
  double mismatch_z = 0;  ///< (chi2 - dof) / sqrt(2 dof)
  double log_n = 0;       ///< ln(observations): the BIC charge per parameter
  ModelEval eval;         ///< the refit baseline evaluated on the folds
  Chi2Parts parts;        ///< its chi-square by observation type
};

/// Whether the refit baseline's fit is usable (parameters and map-noise terms finite).
bool RefitUsable(const NullModel& null);

NullModel TestMismatch(const Problem& prob, const Baseline& base, const std::vector<Fold>& folds);

/// The oracle's effect (a form's name or an effect's: its first form). Throws std::invalid_argument
/// on an unknown effect or a missing parameter; nullopt without an oracle.
std::optional<Effect> ParseOracle(const std::optional<OracleEffect>& oracle);

/// What `effect` with the oracle's parameters, only the row scales fitted, explains beyond `null`.
OracleResult MeasureOracle(const Problem& prob, const Baseline& base, const NullModel& null, Effect effect,
                           const OracleEffect& oracle);

}  // namespace lw::diagnosis::detail
