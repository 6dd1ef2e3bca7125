#pragma once
/// The thinnest area the data support: for the liner and for each row, the thinnest area of the
/// smallest size on a ladder whose band half-width is at most the target. The ladder goes by
/// height (ThinnestAreaConfig::patches_m): at each size a square patch of that side, then a ring
/// (the band of that height all around the circumference), then the whole row. A finite DEM run
/// cannot place a face-sized hot spot, but it can place a larger area: the per-face minimum of a
/// noisy map is a noise spike, while an area's mean carries less of the map's error. Height comes
/// first because a gyratory concave's thinnest wear is a band around it (the discharge edge): a
/// ring of the band's height averages the map's error around the circumference without mixing in
/// the thicker liner above. This is the number the server's headline, its rows, the forecast and
/// `linerwatch reconstruct` report; the per-face values and their band stay in the faces array and
/// the VTK.
///
/// An area's band has two parts (core/reconstruction.hpp), both scaled by the map's error as the
/// sensors measure it (MapCalibration):
///  * the row scale's error (sensor quantisation, the map at the sensors): one number per row, so
///    fully correlated over an area: its sd is the area-weighted mean of the faces';
///  * the map's error after smoothing (its pattern error, the part of the cross-validated error
///    that sampling noise does not explain, and its sampling noise carried through the kernel):
///    correlated over about l = 2 sqrt(pi) x the kernel's sd (at least a face) per axis and no
///    further, so an area of extent L_z x L_arc keeps l_z / (l_z + L_z) x l_arc / (l_arc + L_arc)
///    of a face's variance. Averaging narrows this part, never the scale's.
/// The band of the thinnest of many areas is [min lo, min hi] over them, as for faces.
#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/bundle.hpp"
#include "core/reconstruction.hpp"

namespace lw::core {

/// What a row's sensors show themselves, for a row (or liner) whose band is too wide at every
/// patch: its thinnest latest reading (the reading n: thickness in [n, n+1) mm) and when.
struct SensorFallback {
  std::string sensor;
  double thickness_mm = 0;
  TimePoint time{};
};

/// An area's form: a square patch of side patch_m; a ring, the band of height patch_m all around the
/// circumference; the whole row.
enum class AreaShape { kSquare, kRing, kRow };

struct ThinnestArea {
  std::string row;          ///< the row it lies in (the liner's: the row of its thinnest area)
  double thickness_mm = 0;  ///< area-mean remaining thickness (NaN: no row scale)
  double lo_mm = 0;         ///< band (band_sigmas sd), in [0, new]
  double hi_mm = 0;
  /// band_sigmas sd before the band is clipped to [0, new]: what the data say about the area. A band
  /// clipped at 0 mm (an estimate past worn through) or at the new thickness is narrower than that
  /// only because thickness cannot leave [0, new]; support is judged on this half-width.
  double half_width_mm = 0;
  double raw_lo_mm = 0, raw_hi_mm = 0;  ///< the band's edges before clipping (half_width_mm is half their gap)
  double patch_m = 0;                   ///< side of the square patch (m); a whole row: the row's height
  AreaShape shape = AreaShape::kSquare;
  bool whole_row = false;                         ///< the area is the whole row (no angle): shape kRow
  double z_m = 0;                                 ///< centre (a whole row: its mid-height)
  double theta_deg = 0;                           ///< centre (NaN for a ring or a whole row)
  bool supported = false;                         ///< half_width_mm is within the target at patch_m
  bool extrapolated = false;                      ///< the centre is beyond the sensors' reach (from the DEM map alone)
  double nearest_sensor_m = 0;                    ///< surface distance from the centre to the nearest scale-setting sensor
  bool worn_through = false;                      ///< supported and the band's thick edge is at 0
  std::optional<SensorFallback> sensor_fallback;  ///< when not supported: what the sensors show
  /// The band's two parts (one sd each, of the area whose number is given): the row scale's, and the
  /// map's (its pattern and sampling error averaged over the area); what would narrow the band.
  double scale_sd_mm = 0, map_sd_mm = 0;
  size_t row_sensors = 0;  ///< sensors that set the area's row scale
};

struct ThinnestAreas {
  ThinnestArea liner;
  std::vector<ThinnestArea> rows;  ///< crusher.rows order
};

/// Thinnest areas of `rec` (from `plan`). `used` are the readings that set the scales (one per
/// sensor, as LiveReadingIndices selects them): their positions give the sensors' reach, their
/// values the fallback. Faces outside every row are not part of any area.
ThinnestAreas FindThinnestAreas(const ReconstructionPlan& plan, const Reconstruction& rec, const std::vector<Reading>& used);

/// Area-weighted mean of a per-face field (a true remaining thickness, say) over `area` as
/// FindThinnestAreas reads its own estimate there: the faces of its row within half a patch of its
/// centre along z and around (a whole row: all of the row's faces). How a check reads the truth at
/// the reported area. NaN when the area has no faces or no row.
double AreaMean(const ReconstructionPlan& plan, const Eigen::VectorXd& values, const ThinnestArea& area);
/// The thinnest square patch of side `patch_m` (or ring of that height, or row: `shape`) of a
/// per-face field `remaining` on the grid FindThinnestAreas searches, in row index `row` (-1: every row): its mean (thickness_mm,
/// and lo and hi the same), centre and row. How a check finds the truth's own thinnest area at the reported patch size.
ThinnestArea ThinnestPatchOf(const ReconstructionPlan& plan, const Eigen::VectorXd& remaining, int row, double patch_m,
                             AreaShape shape = AreaShape::kSquare);

/// How far the closed-side setting has opened with the concave's wear (docs/wear.md, Setting): the
/// discharge ring (the lowest `setting.ring_height_m` of the lowest row, all around) as an area of
/// FindThinnestAreas (the same sums, band and support), and the opening its wear makes. The
/// mantle's wear is not measured, so the opening is the concave's part.
/// A closed-side setting measured on the crusher (POST .../setting/checks, docs/wear.md): the CSS
/// an operator measured at `time`, after raising the mantle say, and the concave's opening this
/// estimate gave at that time. It anchors the CSS from then on: CSS = css_mm + the opening since.
struct SettingCheck {
  TimePoint time{};
  double css_mm = 0;
  double opening_mm = 0;  ///< the opening (since installation) estimated at `time`; NaN: not known
  std::string by;         ///< who recorded it (the token's name)
  /// False: opening_mm is the central estimate of a discharge ring that was not supported then
  /// (its band wider than the thinnest-area target); the opening since is counted from it all the same.
  bool opening_supported = true;
};
struct SettingEstimate {
  ThinnestArea ring;                  ///< the discharge ring: mean remaining thickness, band, support, reach
  double opening_mm = 0;              ///< thickness_new - ring thickness (NaN: no scale)
  double opening_lo_mm = 0;           ///< band: new - the ring's hi edge
  double opening_hi_mm = 0;           ///< new - the ring's lo edge
  std::optional<double> css_set_mm;   ///< crusher.json's setting.css_mm
  std::optional<SettingCheck> check;  ///< the latest measured setting up to the estimate's time, if any
  /// The opening since the CSS was last known (the check, else installation): what the
  /// setting_open rule compares and what the CSS adds to its base. NaN when not known.
  double OpeningSince() const;
};
SettingEstimate EstimateSetting(const ReconstructionPlan& plan, const Reconstruction& rec, const std::vector<Reading>& used);
/// The latest of `checks` at or before `at` into `setting` (none: crusher.json's css_mm stays the base).
void ApplySettingChecks(const std::vector<SettingCheck>& checks, TimePoint at, SettingEstimate* setting);
/// {"opening_mm", "opening_band_mm", "css_set_mm", "css_mm", "css_band_mm" (null without css_mm),
/// "supported", "half_width_mm", "ring": {...}, "basis", "detail", "checked" (the SettingCheck
/// anchoring the CSS: time, css_mm, opening_mm, opening_supported, by; null: none),
/// "opening_since_mm"}; NaN is null.
nlohmann::ordered_json SettingJson(const SettingEstimate& setting);
/// One line for people: "setting: opened 12.3 mm (band ...) ...: CSS about 137 mm (set 125)".
std::string SettingText(const SettingEstimate& setting);

/// The one JSON form (REST `.../wear` and its rows, the retained MQTT `.../wear`, `linerwatch
/// reconstruct --json`): {"thickness_mm", "band_mm": [lo, hi], "patch_m", "z_m", "theta_deg" (null
/// for a whole row), "supported", "extrapolated", "nearest_sensor_m" (null: no sensor), "row",
/// "whole_row", "worn_through", "detail", "sensor_fallback" (when not supported)}. NaN is null.
nlohmann::ordered_json ThinnestAreaJson(const ThinnestArea& area);
/// {"factor", "sensors"}: the map's error as the sensors measure it (core/reconstruction.hpp
/// MapCalibration), in `.../wear` and `linerwatch reconstruct --json` as "map_error_at_sensors".
nlohmann::ordered_json MapCalibrationJson(const MapCalibration& calibration);
/// The same in words, one line: what a planner reads (the headline's wording).
std::string ThinnestAreaText(const ThinnestArea& area);

}  // namespace lw::core
