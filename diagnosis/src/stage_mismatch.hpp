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

/// The mismatch test calibrated on the residuals themselves. Per observation type (sensor events,
/// sensor priors, scan cells), the refit's chi-square is split into groups (a sensor; a scan's
/// sixth of the circumference in the lower or upper half). Each group's chi-square is divided by
/// the chi-square per observation the *other* groups of its type show (the type's variance scale,
/// held out), so a group whose residuals are no larger than the rest's counts as its observations.
/// The groups' spread about that gives each type's effective correlation b (how many observations
/// share one error, at least 1); z = sum(calibrated chi2 - n) / sqrt(2 sum(b n)). A type with fewer
/// than 3 groups keeps the modelled noise (scale 1, b 1).
struct MismatchCalibration {
  double z = 0;
  double scale[3] = {1, 1, 1};            ///< modelled chi-square per observation, all groups
  double correlation[3] = {1, 1, 1};      ///< b
  double chi2_calibrated[3] = {0, 0, 0};  ///< sum of the groups' held-out-scaled chi-square
  size_t n[3] = {0, 0, 0}, groups[3] = {0, 0, 0};
  bool learned[3] = {false, false, false};  ///< scale learned (>= 3 groups)
};

struct NullModel {
  FitResult fit;                   ///< the baseline refitted on every observation, noise model on
  Eigen::MatrixXd w;               ///< its simulated wear (points x steps)
  double mismatch_z = 0;           ///< the calibrated excess (MismatchCalibration::z)
  double log_n = 0;                ///< ln(observations): the BIC charge per parameter
  ModelEval eval;                  ///< the refit baseline evaluated on the folds
  Chi2Parts parts;                 ///< its chi-square by observation type
  double mismatch_z_modelled = 0;  ///< the same excess under the modelled noise, uncalibrated
  MismatchCalibration calibration;
};

/// Rescales the problem's noise to the learned one: each learned type's variance times its scale
/// and its effective correlation (b observations sharing one error count as one).
void ApplyLearnedNoise(Problem& prob, const MismatchCalibration& cal);

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
