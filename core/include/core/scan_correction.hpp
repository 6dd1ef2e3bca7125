#pragma once
/// A laser scan improves the live map: the scan is ground truth at its date, so between the sensors
/// the wear pattern it measured replaces (precision-weighted) the DEM map's pattern.
///
/// Live wear is Eq. 9: wear(face, t) = k_row(t) x I(face), with I the map model's intensity and
/// k_row(t) from the row's sensors. At the scan's date the scan gives wear(face) directly, so
/// I_scan(face) = wear_scan(face) / k_row(t_scan) is a measured intensity with the scan's error
/// (points' scatter, a registration floor) and the row scale's. Each face's intensity becomes the
/// inverse-variance mean of the map model's and the scan's; the sensors' intensities are corrected
/// by the same ratio around them, so Eq. 9 stays consistent (at the scan date the live map then
/// reproduces the scan; later the sensors scale the scan's pattern). Faces the scan did not cover
/// keep the map model's intensity.
#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "core/bundle.hpp"
#include "core/reconstruction.hpp"

namespace lw::core {

/// A scan's wear per face: each point is assigned to the nearest face centroid on the unwrapped
/// surface (within two face sizes), its wear is its depth behind the as-new face along the face's
/// inward normal; per face the median and a standard error (scatter / sqrt(n), floor `floor_mm`).
struct ScanFaces {
  Eigen::VectorXd wear_mm;  ///< NaN where no point fell
  Eigen::VectorXd sd_mm;
  std::vector<int> points;
  size_t points_used = 0, points_total = 0;
};
ScanFaces ProjectScanToFaces(const WearMap& map, const Scan& scan, double floor_mm = 0.5);

struct ScanCorrection {
  size_t faces_corrected = 0;
  size_t faces_filled = 0;         ///< faces no scan point fell on, given their corrected neighbours' ratio
  double median_ratio = 1;         ///< median over corrected faces of corrected / model intensity
  double map_model_error_rel = 0;  ///< the map pattern's relative error the scan revealed (beyond noise)
  std::string detail;              ///< why nothing was done (empty when applied)
  /// Per face (empty when nothing was done): the scan's weight in the face's corrected intensity,
  /// 1 / var_scan over 1 / var_map + 1 / var_scan (0 where no scan point fell on the face), and the
  /// corrected intensity over the map model's (1 where the face was left as it was; a filled face's
  /// is its neighbours'). What a model other than Eq. 9 needs to take the scan as its ground truth
  /// at the scan's date with the same weights (the diagnosis' predictions).
  Eigen::VectorXd face_weight;
  Eigen::VectorXd face_ratio;
};

/// The latest scan at or before `at` of `scans` (sorted by date, as LoadScans returns them); nullptr
/// when there is none.
const Scan* LatestScanAt(const std::vector<Scan>& scans, TimePoint at);

/// Corrects `plan` (its per-face and per-sensor intensities and their errors) with a scan, given
/// the sensors' wear at the scan's date (SensorWearAt(crusher, readings, scan.date)).
ScanCorrection ApplyScan(ReconstructionPlan& plan, const ScanFaces& scan, const std::vector<SensorWear>& wear_at_scan);

}  // namespace lw::core
