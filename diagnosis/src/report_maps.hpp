#pragma once
/// Data for the HTML report's unwrapped-liner maps and thinnest points (DiagnosisResult::liner):
/// the map's faces (or raster cells) in (theta, z), per-face wear measured by each scan and predicted
/// by the baseline and the improved model, the live reconstruction's thinnest point with its band,
/// and the per-row reline dates of the core forecast.
#include <Eigen/Core>
#include <functional>
#include <vector>

#include "core/bundle.hpp"
#include "diagnosis/diagnose.hpp"
#include "fields.hpp"

namespace lw::diagnosis::detail {

/// Per-face wear (mm, in [0, thickness]) of the baseline (improved = false) or the improved model
/// at `t_days` since installation.
using FaceWearAt = std::function<Eigen::VectorXd(bool improved, double t_days)>;

/// The readings a diagnosis kept (faults excluded), from its sensor curves, sorted by sensor and
/// time; `last_days` (when given) gets the latest one's day since installation. The live wear, the
/// forecast and the scan the predictions take as ground truth use these.
std::vector<core::Reading> UsedReadings(const core::CrusherConfig& crusher, const std::vector<SensorCurve>& curves,
                                        double* last_days = nullptr);

/// Fills result.liner and the sensors' positions in result.curves. Needs result.curves (the
/// readings the diagnosis used) and result.prediction (when there is one) already filled.
void FillLinerReport(const core::Bundle& bundle, const MapFields& fields, const std::vector<ScanCells>& scans,
                     const FaceWearAt& face_wear, DiagnosisResult& result);

}  // namespace lw::diagnosis::detail
