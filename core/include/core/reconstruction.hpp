#pragma once
/// Global wear reconstruction, seed paper Eq. 9: W(x) = W_i(x) * W_s0 / W_i0 per row, with the
/// row scale interpolated along z between row centres (not stepped). W_i is the map model's
/// smoothed intensity (core/map_model.hpp: noise law, outliers capped, data-chosen kernel), the
/// same at the faces and at the sensors, so at a row's sensor the reconstruction equals the sensor.
/// Outputs are physical: remaining thickness in [0, new] (a face worn through is counted as such),
/// the thinnest point with a band from map noise, sensor quantisation and the row scale, and a
/// status that says when the map or the sensors cannot support a number.
#include <Eigen/Core>
#include <limits>
#include <string>
#include <cstdint>
#include <vector>

#include "core/bundle.hpp"
#include "core/map_model.hpp"
#include "core/surface_distance.hpp"

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
  double scale_sd = 0;             ///< standard error of scale_mm_per_unit
  double min_thickness_lo_mm = 0;  ///< band of the row's thinnest point (band_sigmas sd), in [0, new]
  double min_thickness_hi_mm = 0;
  size_t worn_through_faces = 0;  ///< faces whose estimated wear reaches the as-new thickness
};

struct ReconstructionOptions {
  bool interpolate_between_rows = true;
  MapModelOptions map_model;    ///< smoothing scale (default: chosen from the map's own noise), outliers
  bool interval_centre = true;  ///< use thickness + 0.5 mm (centre of [n, n+1)) as the estimate
  double band_sigmas = 2.0;     ///< half-width of the thinnest-point band in standard deviations
  /// The map's error as the sensors measure it (MapCalibration): pseudo-sensors at the model's own
  /// error that the sensors' evidence is pooled with; 0 or less: the model's error as it is.
  double calibration_prior_dof = 2.0;
  /// Above this relative standard error of the thinnest point's wear the number is not supported
  /// (status "unsupported"): the band is still given.
  double max_rel_sd = 0.5;
};

/// Whether a reconstruction supports a number: "ok"; "unsupported" (the band is wider than the
/// map and sensors can support, or the map has no intensity where sensors are); "no_sensors".
inline constexpr const char* kStatusOk = "ok";
inline constexpr const char* kStatusUnsupported = "unsupported";
inline constexpr const char* kStatusNoSensors = "no_sensors";

/// The map model's error (noise and smoothing, core/map_model.hpp) measured at the sensors: each
/// sensor in a row with others predicted from the others alone, its error against the model's sd
/// for that prediction. `factor` multiplies the map's part of every standard error (faces, row
/// scales, bands); 1 when no row has two reporting sensors.
struct MapCalibration {
  double factor = 1.0;
  size_t sensors = 0;  ///< sensors predicted from their row mates
  /// Relative sd of a point's wear predicted from its row mates (quantisation apart): the sensors'
  /// squared excess errors over their squared predictions (those above 0), pooled with the model's
  /// own as a prior. With no such prediction (no row with two reporting sensors), the prior alone:
  /// the model's relative error of a sensor predicted from one row mate as uncertain as itself. A
  /// row with one sensor carries it in its scale, a face beyond every scale-setting sensor's reach in
  /// its map part. 0 only when the calibration is off (ReconstructionOptions::calibration_prior_dof).
  double point_rel_sd = 0.0;
};

struct Reconstruction {
  Eigen::VectorXd wear_mm;       ///< per face, in [0, thickness_new]
  Eigen::VectorXd remaining_mm;  ///< per face: thickness_new - wear, never negative
  /// Per face: standard error of remaining_mm; its map part at least calibration.point_rel_sd x the
  /// wear where the face lies beyond every scale-setting sensor's reach (sensor_reach_m).
  Eigen::VectorXd remaining_sd_mm;
  /// Per face: the row scale's part of remaining_sd_mm (intensity x the scale's sd): one error per
  /// row, shared by its faces (the rest is the map's, core/thinnest_area.hpp).
  Eigen::VectorXd scale_sd_mm;
  /// Per face: intensity x scale before wear_mm's clamp to [0, new] (beyond new: the estimate says
  /// worn through by that much), for areas whose band must say so (core/thinnest_area.hpp).
  Eigen::VectorXd wear_estimate_mm;
  std::vector<RowSummary> rows;
  double min_thickness_mm = 0;
  size_t min_face = 0;
  double min_thickness_lo_mm = 0;       ///< band of the thinnest point: the true thinnest point lies in
  double min_thickness_hi_mm = 0;       ///< [lo, hi] when every face is within band_sigmas sd
  size_t worn_through_faces = 0;        ///< estimated wear >= thickness_new
  size_t maybe_worn_through_faces = 0;  ///< band reaches 0
  MapCalibration calibration;           ///< the map's error factor the bands use, and from how many sensors
  std::string status = kStatusOk;       ///< kStatusOk, kStatusUnsupported, kStatusNoSensors
  std::string status_detail;            ///< why, in words (empty when ok)
};

/// Everything about a map and crusher that does not depend on the readings, computed once
/// (smoothing is the expensive part); Reconstruct(plan, ...) is then a pass over the faces.
struct ReconstructionPlan {
  const CrusherConfig* crusher = nullptr;
  const WearMap* map = nullptr;
  ReconstructionOptions options;
  MapModel model;                       ///< the map as data with its uncertainty
  Eigen::VectorXd intensity;            ///< per face: model.intensity
  Eigen::VectorXd intensity_rel_sd;     ///< per face: relative standard error of `intensity`
  Eigen::VectorXd sensor_intensity;     ///< per sensor (crusher order): the model at the sensor, same kernel
  Eigen::VectorXd sensor_intensity_sd;  ///< per sensor: its standard error
  std::vector<int> face_row;            ///< row index of each face by z (-1 outside every row)
  RadiusProfile radius;                 ///< the map's radius by height, for surface distances
  /// Per sensor, per face: 1 when the face lies within `within_reach_m` (the crusher's
  /// thinnest_area.sensor_reach_m when the plan was made) of the sensor, over the surface. Once
  /// per plan: every reconstruction asks it of every face.
  std::vector<std::vector<uint8_t>> within_reach;
  double within_reach_m = 0;
};

/// The map model's part of face `i`'s standard error (mm) at wear estimate `w_est`: its relative
/// error times the calibration factor (Reconstruct raises it beyond the sensors' reach).
inline double ModelMapSd(const ReconstructionPlan& plan, const MapCalibration& calibration, Eigen::Index i, double w_est) {
  return w_est * plan.intensity_rel_sd[i] * calibration.factor;
}

/// Surface distance (as SurfaceDistance) from (z, theta) to the nearest of `sensors`, the arc at the
/// map's radius midway between the two heights; along z only when `around` is false (a ring, a
/// whole row: `theta_deg` is not read). Sensors farther than `within_m` are not looked for:
/// infinity when none is nearer.
double NearestSensorDistance(const std::vector<const SensorInfo*>& sensors, const RadiusProfile& radius, double z_m,
                             double theta_deg, bool around = true, double within_m = std::numeric_limits<double>::infinity());

ReconstructionPlan PrepareReconstruction(const CrusherConfig& crusher, const WearMap& map,
                                         const ReconstructionOptions& options = {});
/// The same with a map model built elsewhere (the diagnosis builds one per bundle).
ReconstructionPlan PrepareReconstruction(const CrusherConfig& crusher, const WearMap& map, MapModel model,
                                         const ReconstructionOptions& options = {});
Reconstruction Reconstruct(const ReconstructionPlan& plan, const std::vector<SensorWear>& sensor_wear);
/// The same, into `result`, reusing its per-face arrays when they already have the map's size
/// (fresh 8 MB arrays per million faces cost more in page faults than the pass itself).
void ReconstructInto(const ReconstructionPlan& plan, const std::vector<SensorWear>& sensor_wear, Reconstruction* result);

/// Area-weighted mean of `values` over faces within `radius_m` (surface distance in z and arc
/// length) of each face (a top-hat; the map model uses a Gaussian kernel). Linear in the face count.
Eigen::VectorXd SmoothOverSurface(const WearMap& map, const Eigen::VectorXd& values, double radius_m);

/// Index into `readings` of each sensor's latest reading up to `at` (the thinner of two at the
/// same time, since wear only goes one way), in crusher.sensors order; sensors without readings
/// are left out. The selection SensorWearAt uses.
std::vector<size_t> LatestReadingIndices(const CrusherConfig& crusher, const std::vector<Reading>& readings, TimePoint at);

/// Current wear per sensor from readings up to `at` (latest reading of each sensor):
/// wear = thickness_new - (reading + 0.5 when interval_centre). Sensors without readings are left out.
std::vector<SensorWear> SensorWearAt(const CrusherConfig& crusher, const std::vector<Reading>& readings, TimePoint at,
                                     bool interval_centre = true);

/// When a sensor's latest reading is too old to set a row's scale: more than max(min_days, periods x
/// the sensor's median interval between readings) before the newest reading of any sensor up to the
/// time asked for (the diagnosis' dropout rule). A dead sensor, or one whose readings were all
/// flagged since it stuck, would otherwise give the wear of that older day, too little, and scale
/// its row's faces too thin a wear. The median interval is a property of the sensor: it is taken
/// over its readings in the `history_days` up to its newest reading (whatever the time asked for),
/// so the server's in-memory state (which keeps at least the last 21 days of each sensor) and a
/// full recompute over every stored reading agree.
struct Staleness {
  double min_days = 1.0;
  double periods = 8.0;
  double history_days = 21.0;
};

/// LatestReadingIndices without the stale sensors (Staleness); their ids go to `stale` when given.
/// The newest sensor is never stale, so a crusher with readings always keeps at least one.
std::vector<size_t> FreshReadingIndices(const CrusherConfig& crusher, const std::vector<Reading>& readings, TimePoint at,
                                        const Staleness& rule = {}, std::vector<std::string>* stale = nullptr);

/// Wear per sensor from the readings at `indices` (one per sensor, as LatestReadingIndices or
/// FreshReadingIndices select them): wear = thickness_new - (reading + 0.5 when interval_centre).
std::vector<SensorWear> SensorWearFrom(const CrusherConfig& crusher, const std::vector<Reading>& readings,
                                       const std::vector<size_t>& indices, bool interval_centre = true);

/// SensorWearAt over FreshReadingIndices: the wear that sets the scales at `at` (live wear, a scan's
/// correction at its date).
std::vector<SensorWear> FreshSensorWearAt(const CrusherConfig& crusher, const std::vector<Reading>& readings, TimePoint at,
                                          const Staleness& rule = {}, std::vector<std::string>* stale = nullptr,
                                          bool interval_centre = true);

/// When a sensor that keeps reporting is stuck ("stuck value": moisture bridging its loops, a
/// frozen shift register): its value has not moved over its last `min_readings` or more readings,
/// while at the rate its row mates set it should have lost at least `expected_mm`. A mate's share:
/// the wear it showed over those days times the sensor's wear over the mate's when the run began
/// (their ratio since installation: the sensor's own place in its row's wear pattern, with no
/// history needed; the sensor's wear taken low, new - n - 1 - `mounting_mm`, the mate's high,
/// new - n, so that neither quantisation nor the sensor's mounting makes a slow sensor look stuck);
/// the median over the row mates that set a
/// scale, had worn at least `min_mate_wear_mm` then and are not suspects themselves (a suspect: a
/// sensor whose largest share reaches `expected_mm`; two stuck sensors must not vouch for each
/// other); with two mates, the smaller. A mate's wear over the days is read gradually, through the
/// running minimum of its thickness: a fall of more than `max_step_mm` between two readings (a
/// spall, a crack cutting loops early) does not count, nor does a loop that reads intact again. A
/// sensor whose run began with such a fall (a crack: its value waits for the wear to catch up),
/// beyond what its own mean rate explains over the days since the reading before (a radio outage),
/// is not judged, nor is one without such mates or at 0 mm (consumed). A sensor that really wears
/// slowly has a small ratio and keeps losing loops at it; 5 mm expected means several loops. Of
/// each sensor's readings up to its latest, those in the forecast's window count (max(`history_days`,
/// `history_fraction` x the days since installation)) and, before it, its record lows (each new
/// lowest thickness when first read): its running minimum at any earlier time. So a value that froze
/// before the window is judged from when it froze, against its mates' wear then and their gradual
/// wear since; and the server, which keeps the window and the record lows in memory, agrees with a
/// full recompute.
struct StuckRule {
  double expected_mm = 5.0;
  size_t min_readings = 3;
  double min_mate_wear_mm = 3.0;
  double max_step_mm = 2.0;
  /// How far a sensor's first loop may sit from where its as-new thickness puts it (casting, the
  /// top loop ground near flush): its own wear is taken this much lower still. Early in a campaign
  /// a sensor's and its mates' wear are a few mm, and one mm of offset would change its share of
  /// their wear several-fold.
  double mounting_mm = 1.0;
  double history_days = 21.0;     ///< = ForecastOptions::window_min_days
  double history_fraction = 0.4;  ///< = ForecastOptions::window_fraction
};

/// `indices` (one reading per sensor, as FreshReadingIndices selects them) without the stuck sensors
/// (StuckRule); their ids go to `stuck` when given.
std::vector<size_t> WithoutStuckSensors(const CrusherConfig& crusher, const std::vector<Reading>& readings,
                                        std::vector<size_t> indices, const StuckRule& rule = {},
                                        std::vector<std::string>* stuck = nullptr);

/// The readings that set the live map's scales at `at`: FreshReadingIndices, then WithoutStuckSensors
/// (the server's live wear, `linerwatch reconstruct`, the report's live map). The scan's correction at
/// its date cannot judge that date's readings (what the server keeps of the days before a scan is
/// each sensor's reading at its date, not its history): ScanSensorWear leaves out the sensors stuck
/// now whose value had already frozen then.
std::vector<size_t> LiveReadingIndices(const CrusherConfig& crusher, const std::vector<Reading>& readings, TimePoint at,
                                       std::vector<std::string>* stale = nullptr, std::vector<std::string>* stuck = nullptr);

/// The sensors' wear that sets the scales at a scan's date, for its correction: FreshSensorWearAt
/// there, without each sensor of `stuck` (stuck now, as LiveReadingIndices names them) whose reading
/// at the scan's date is already the value it is stuck at (its latest up to `now`): frozen then, whose
/// wear would set its row's scale at the scan too low and the correction would carry the error on;
/// or still on its last genuine loop then (frozen within one loop after the scan: the value alone
/// cannot tell), when its reading was right and is left out all the same, its row mates setting the
/// scale there.
std::vector<SensorWear> ScanSensorWear(const CrusherConfig& crusher, const std::vector<Reading>& readings, TimePoint scan_date,
                                       const std::vector<std::string>& stuck, TimePoint now = TimePoint::max(),
                                       bool interval_centre = true);

/// Raw map intensity at each sensor position (area-weighted over faces within `radius_m` of it, or
/// the nearest face when none is that close). Same order as crusher.sensors. (The reconstruction
/// uses the map model instead; this is the simulator's truth model.)
Eigen::VectorXd IntensityAtSensors(const CrusherConfig& crusher, const WearMap& map, double radius_m = 0.05);

/// Eq. 9 reconstruction from each sensor's current wear.
Reconstruction Reconstruct(const CrusherConfig& crusher, const WearMap& map, const std::vector<SensorWear>& sensor_wear,
                           const ReconstructionOptions& options = {});

}  // namespace lw::core
