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

struct NullModel {
  FitResult fit;          ///< the baseline refitted on every observation, noise model on
  Eigen::MatrixXd w;      ///< its simulated wear (points x steps)
  double mismatch_z = 0;  ///< (chi2 - dof) / sqrt(2 dof)
  double log_n = 0;       ///< ln(observations): the BIC charge per parameter
  ModelEval eval;         ///< the refit baseline evaluated on the folds
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
