#pragma once
/// Global wear reconstruction, seed paper Eq. 9: W(x) = W_i(x) * W_s0 / W_i0 per row, with the
/// row scale interpolated along z between row centres (not stepped) and DEM per-face noise smoothed.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/bundle.hpp"

namespace lw::core {

struct SensorWear {
  std::string sensor_id;
  double wear_mm = 0;  ///< thickness_new - measured thickness lower bound (+0.5 for interval centre)
};

struct RowSummary {
  std::string row;
  double scale_mm_per_unit = 0;  ///< W_s0 / W_i0 for the row
  double min_thickness_mm = 0;
  size_t min_face = 0;
  double min_z_m = 0;
  double min_theta_deg = 0;
  double mean_wear_mm = 0;
  size_t sensors_used = 0;
};

struct ReconstructionOptions {
  bool interpolate_between_rows = true;
  double smoothing_radius_m = 0.15;  ///< DEM per-face noise: area-weighted mean within this radius (0 = off)
  bool interval_centre = true;      ///< use thickness + 0.5 mm (centre of [n, n+1)) as the estimate
};

struct Reconstruction {
  Eigen::VectorXd wear_mm;       ///< per face
  Eigen::VectorXd remaining_mm;  ///< per face: thickness_new - wear
  std::vector<RowSummary> rows;
  double min_thickness_mm = 0;
  size_t min_face = 0;
};

/// Everything about a map and crusher that does not depend on the readings, computed once
/// (smoothing is the expensive part); Reconstruct(plan, ...) is then a pass over the faces.
struct ReconstructionPlan {
  const CrusherConfig* crusher = nullptr;
  const WearMap* map = nullptr;
  ReconstructionOptions options;
  Eigen::VectorXd intensity;           ///< per face, smoothed when options.smoothing_radius_m > 0
  Eigen::VectorXd sensor_intensity;    ///< per sensor (crusher order), from the smoothed intensity
  std::vector<int> face_row;           ///< row index of each face by z (-1 outside every row)
};

ReconstructionPlan PrepareReconstruction(const CrusherConfig& crusher, const WearMap& map,
                                         const ReconstructionOptions& options = {});
Reconstruction Reconstruct(const ReconstructionPlan& plan, const std::vector<SensorWear>& sensor_wear);
/// The same, into `result`, reusing its per-face arrays when they already have the map's size
/// (fresh 8 MB arrays per million faces cost more in page faults than the pass itself).
void ReconstructInto(const ReconstructionPlan& plan, const std::vector<SensorWear>& sensor_wear, Reconstruction* result);

/// Area-weighted mean of `values` over faces within `radius_m` (surface distance in z and arc
/// length) of each face. Grid-bucketed: linear in the face count for a fixed radius.
Eigen::VectorXd SmoothOverSurface(const WearMap& map, const Eigen::VectorXd& values, double radius_m);

/// Index into `readings` of each sensor's latest reading up to `at` (the thinner of two at the
/// same time, since wear only goes one way), in crusher.sensors order; sensors without readings
/// are left out. The selection SensorWearAt uses.
std::vector<size_t> LatestReadingIndices(const CrusherConfig& crusher, const std::vector<Reading>& readings, TimePoint at);

/// Current wear per sensor from readings up to `at` (latest reading of each sensor):
/// wear = thickness_new - (reading + 0.5 when interval_centre). Sensors without readings are left out.
std::vector<SensorWear> SensorWearAt(const CrusherConfig& crusher, const std::vector<Reading>& readings,
                                     TimePoint at, bool interval_centre = true);

/// Map-intensity at each sensor position (area-weighted over faces within `radius_m` of it, or the
/// nearest face when none is that close). Same order as crusher.sensors.
Eigen::VectorXd IntensityAtSensors(const CrusherConfig& crusher, const WearMap& map, double radius_m = 0.05);

/// Eq. 9 reconstruction from each sensor's current wear.
Reconstruction Reconstruct(const CrusherConfig& crusher, const WearMap& map,
                           const std::vector<SensorWear>& sensor_wear,
                           const ReconstructionOptions& options = {});

}  // namespace lw::core
