#pragma once
/// Where to cast the next liner's sensors (`linerwatch plan`, GET .../plan): K positions that narrow
/// the live wear's band most, judged by the live wear's own band model (core::Reconstruct and
/// core::FindThinnestAreas) on the crusher's DEM map model.
///
/// A layout's expected band is the band the live wear would give at the reline point (the liner's
/// thinnest area at the minimum thickness) if every sensor read what the map predicts there: with
/// such readings every layout gives the same estimate, and its band differs only by the row scales'
/// errors (how many sensors a row has, the map's intensity and error at each of them), the part a
/// layout decides. The map's error is the map model's as it is measured from the DEM run's
/// independent windows (the factor the sensors measure in a campaign is left at 1: planned sensors
/// have no readings). Layouts are compared on one area: the thinnest square of the size the live
/// wear reports with the crusher.json layout at the reline point (the whole row when it reports a
/// row). The objective is the mean half-width (band_sigmas sd) over the liner's thinnest area and
/// each row's: a row's reline date band is its area's band over its wear rate.
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "estimate/model.hpp"
#include "estimate/window.hpp"

namespace lw::estimate {

struct PlanOptions {
  size_t sensors = 0;              ///< K, the sensors to place (1..candidates)
  double edge_margin_m = 0.1;      ///< no sensor closer than this to a row's top or bottom edge
  double joint_clearance_deg = 5;  ///< no sensor closer than this to a joint (concave.joints_theta_deg)
  int z_levels = 5;                ///< candidate heights per row, evenly within the margins
  double theta_step_deg = 15;      ///< candidate angles around the circumference
};

struct PlannedSensor {
  std::string row;
  double z_m = 0, theta_deg = 0;
  std::string keeps;  ///< the crusher.json sensor whose position this is (empty: a new position)
};

/// One row's expected band half-width (mm; NaN: no number), with the crusher.json layout and the proposed one.
struct RowPlan {
  std::string row;
  size_t current_sensors = 0, proposed_sensors = 0;
  double current_mm = 0, proposed_mm = 0;
};

/// What a laser scan now would do to a running campaign's bands (the live wear with a scan takes the
/// scan as the wear pattern: core::ApplyScan), for a scan that reads the wear the live map shows now.
struct ScanAdvice {
  std::string at;                              ///< the latest reading's time (ISO-8601): the scan's date
  double liner_now_mm = 0, liner_scan_mm = 0;  ///< the liner's thinnest-area band half-width
  struct Row {
    std::string row;
    double now_mm = 0, scan_mm = 0;      ///< the row's thinnest-area band half-width
    double now_days = 0, scan_days = 0;  ///< its reline date band (latest - earliest), NaN without both dates
  };
  std::vector<Row> rows;
  std::string first_row;  ///< the row that reaches the minimum first (the reline), empty when none has a date
};

struct SensorPlan {
  std::string crusher_id;
  std::vector<PlannedSensor> sensors;
  double current_mm = 0, proposed_mm = 0;              ///< the objective (NaN current: crusher.json has no sensor)
  double liner_current_mm = 0, liner_proposed_mm = 0;  ///< the liner's thinnest area alone
  std::vector<RowPlan> rows;
  bool compared_on_row = false;  ///< compared on whole rows (else squares of compared_patch_m)
  double compared_patch_m = 0;
  size_t candidates = 0;
  std::optional<ScanAdvice> scan;  ///< a running campaign's (readings given)
};

/// The band the live wear would give from a DEM map (`linerwatch dem --until-band`): that of the
/// liner's thinnest square patch of side `patch_m` at the reline point (the wear scaled so that the
/// patch's mean reaches thickness_min_mm), with crusher.json's sensors reading what the map predicts
/// there, as core::FindThinnestAreas computes it: half_width_mm = band_sigmas x sqrt(scale_sd^2 +
/// map_sd^2), the factor the sensors measure in a campaign left at 1. Both parts come from the map's
/// error (the windows' spread): map_sd_mm is its pattern and sampling error averaged over the
/// patch; scale_sd_mm the row scale's, the map's error at the row's sensors with the readings'
/// quantisation (its floor: a longer run cannot narrow that part). Without sensors in crusher.json,
/// candidate positions over every row stand in.
struct MapBand {
  double patch_m = 0;
  double half_width_mm = 0;  ///< band_sigmas x hypot(scale_sd_mm, map_sd_mm)
  double map_sd_mm = 0, scale_sd_mm = 0;
  double band_sigmas = 2;
  double thickness_mm = 0;  ///< the patch mean at the reline point (thickness_min_mm)
  std::string row;
  double z_m = 0, theta_deg = 0;  ///< the patch's centre
};
/// Throws std::invalid_argument naming --patch when it is not in (0, the tallest row's height] or no
/// square of that side holds enough faces.
MapBand MapBandAt(const CrusherModel& model, double patch_m);
/// The first check of MapBandAt, before any map exists: `patch_m` in (0, the tallest row's height].
void CheckMapBandPatch(const core::CrusherConfig& crusher, double patch_m);

/// The plan for `model`'s crusher. Throws std::invalid_argument naming the option when K is out of
/// range, or a row is too low for the edge margin.
SensorPlan PlanSensors(const CrusherModel& model, const PlanOptions& options);
/// What a scan now would do to the bands, from the campaign's readings; nullopt when no reading sets a scale.
std::optional<ScanAdvice> AdviseScan(const CrusherModel& model, const std::vector<Sample>& readings);

/// {"sensors": [{"row", "z_m", "theta_deg", "keeps"}], "expected_band_mm": {"current", "proposed"},
/// "liner_band_mm", "rows", "compared_on", "candidates", "objective", "scan_now"}; NaN is null.
nlohmann::ordered_json PlanJson(const SensorPlan& plan);
/// The same in sentences a reliability engineer acts on.
std::string PlanText(const SensorPlan& plan);

}  // namespace lw::estimate
