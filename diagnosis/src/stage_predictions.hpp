#pragma once
/// Diagnosis stage 8, predictions and report data: each sensor's curves (readings, baseline and
/// improved model), each scan's residual grids before and after, the prediction at a given time,
/// and the unwrapped-liner maps of the HTML report.
#include <vector>

#include "diagnosis/diagnose.hpp"
#include "stage_baseline.hpp"
#include "stage_mismatch.hpp"
#include "stage_setup.hpp"

namespace lw::diagnosis::detail {

struct PredictionInput {
  const core::Bundle& bundle;
  const DiagnoseOptions& options;
  const ProblemSetup& setup;
  const Baseline& base;       ///< the Eq. 9 baseline (curves and predictions "baseline")
  const NullModel& null;      ///< the refit baseline (residual grids "before")
  const FitResult& model;     ///< the improved model: the chosen one, else the refit baseline, else Eq. 9
  bool use_improved = false;  ///< a model was chosen or something found: intensity errors and material loss applied
  /// Whether `model` carries findings (physics). Without, the improved faces are Eq. 9's: the refit
  /// baseline's gain is its per-sensor map-noise terms, known at the sensors only, and its row scales,
  /// weighted by those terms, carried the sensors' own misfit to the faces of their rows (measured
  /// worse than Eq. 9's away from the sensors on five of six real-map libraries; docs/diagnosis.md).
  bool model_has_findings = false;
};

/// The model point of every configured sensor (configuration order).
std::vector<ModelPoint> SensorPoints(const ProblemSetup& setup);
/// The model point of every map face.
std::vector<ModelPoint> FacePoints(const core::Bundle& bundle, const ProblemSetup& setup);

/// Every sensor's readings and modelled thickness over time (about 120 samples up to the last
/// reading or the prediction time).
std::vector<SensorCurve> SensorCurves(const PredictionInput& in);
/// Every scan's measured wear and the misses of the refit baseline and the improved model per cell.
std::vector<ResidualGrid> ResidualGrids(const PredictionInput& in);
/// Every sensor's thickness and every face's wear at `at`, baseline and improved. The faces take
/// the latest scan at or before `at` as ground truth at its date (with the live map's weights from
/// `used`, the readings the diagnosis kept: UsedReadings) and each model carries it forward.
Prediction PredictAt(const PredictionInput& in, const std::vector<ModelPoint>& face_points,
                     const std::vector<core::Reading>& used, core::TimePoint at);

/// The whole stage: curves, grids, the prediction (when options.predict_at) and the liner report.
void Predict(const PredictionInput& in, DiagnosisResult& result);

}  // namespace lw::diagnosis::detail
