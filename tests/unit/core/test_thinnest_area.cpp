#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>

#include "core/angles.hpp"
#include "core/reconstruction.hpp"
#include "core/thinnest_area.hpp"
#include "unit/core/bundle_fixture.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw::core;
using lw::test::TwoRows;

namespace {

/// The TwoRows cylinder with per-face sampling noise of relative scatter ~0.46 (uniform 0.2-1.8 x
/// the smooth field 2 - z/2), as a finite DEM run gives.
WearMap NoisyMap(int nt = 72, int nz = 40) {
  WearMap m = lw::test::CylinderMap(nt, nz, [](double z) { return 2.0 - 0.5 * z; });
  uint64_t state = 12345;
  for (Eigen::Index i = 0; i < m.wear.size(); ++i) {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    m.wear[i] *= 0.2 + 1.6 * (static_cast<double>(state >> 11) / 9007199254740992.0);
  }
  return m;
}

std::vector<Reading> Used(const CrusherConfig& c, double r1001, double r1002) {
  const TimePoint t = AddDays(c.installed_at, 60);
  return {{t, "1001", r1001, 0}, {t, "1002", r1002, 0}};
}

std::vector<SensorWear> WearOf(const std::vector<Reading>& used) {
  std::vector<SensorWear> w;
  for (const Reading& r : used) w.push_back({r.sensor_id, 120.0 - (r.thickness_mm + 0.5)});
  return w;
}

}  // namespace

TEST_GROUP(ThinnestArea){};

// Heavy wear on a noisy map: single faces' bands reach 0 mm, which alone says nothing about the
// liner. The headline is an area whose band meets the target, at a patch larger than a face.
TEST(ThinnestArea, AFacesBandAtZeroIsNoWornThroughAreaTheHeadlineIsTheSupportedPatch) {
  const CrusherConfig c = TwoRows();
  const WearMap m = NoisyMap();
  const ReconstructionPlan plan = PrepareReconstruction(c, m);
  const std::vector<Reading> used = Used(c, 40, 70);
  const Reconstruction rec = Reconstruct(plan, WearOf(used));
  CHECK(rec.maybe_worn_through_faces > 0);  // face-level: the band of some faces reaches 0
  const ThinnestAreas a = FindThinnestAreas(plan, rec, used);
  CHECK_FALSE(a.liner.worn_through);
  // Supported within the target, or said not to be and the sensors' own reading given.
  CHECK(a.liner.supported == (a.liner.half_width_mm <= c.thinnest_area.band_half_width_mm + 1e-9));
  CHECK(a.liner.supported || a.liner.sensor_fallback.has_value());
  CHECK(a.liner.thickness_mm > rec.min_thickness_mm);
  CHECK(a.liner.lo_mm <= a.liner.thickness_mm && a.liner.thickness_mm <= a.liner.hi_mm);
  STRCMP_EQUAL("LDWN", a.liner.row.c_str());
  CHECK(a.liner.z_m <= 0.5);  // the map wears most at the bottom (a whole row: LDWN's mid-height)
  LONGS_EQUAL(2, a.rows.size());
  // The liner's area is its thinnest row's.
  CHECK(a.rows[0].thickness_mm <= a.rows[1].thickness_mm);
}

// The row scale is one number per row: averaging more faces does not narrow its part of the band.
// A crusher whose rows are scaled by a map value that is itself uncertain at the sensor cannot be
// supported to a band tighter than that part, whatever the patch.
TEST(ThinnestArea, TheRowScalesErrorIsNotAveragedAwayOverAPatch) {
  CrusherConfig c = TwoRows();
  const WearMap m = NoisyMap();
  const ReconstructionPlan plan = PrepareReconstruction(c, m);
  const std::vector<Reading> used = Used(c, 40, 70);
  const Reconstruction rec = Reconstruct(plan, WearOf(used));
  const ThinnestAreas a = FindThinnestAreas(plan, rec, used);
  // At the area's faces, the scale's part of the band alone: 2 sd of it, over the row's faces.
  double scale_part = std::numeric_limits<double>::max();
  for (Eigen::Index i = 0; i < m.z.size(); ++i)
    if (plan.face_row[static_cast<size_t>(i)] == 0) scale_part = std::min(scale_part, rec.scale_sd_mm[i]);
  CHECK(scale_part > 0);
  CHECK(0.5 * (a.rows[0].hi_mm - a.rows[0].lo_mm) >= 2.0 * scale_part * 0.99);
}

// A band target no patch and no whole row can meet: not supported, and the sensors' own thinnest
// reading is what is shown beside it.
TEST(ThinnestArea, NoPatchUpToTheWholeRowMeetsTheTargetFallsBackToTheSensors) {
  CrusherConfig c = TwoRows();
  c.thinnest_area.band_half_width_mm = 0.01;
  const WearMap m = NoisyMap();
  const ReconstructionPlan plan = PrepareReconstruction(c, m);
  const std::vector<Reading> used = Used(c, 40, 70);
  const ThinnestAreas a = FindThinnestAreas(plan, Reconstruct(plan, WearOf(used)), used);
  CHECK_FALSE(a.liner.supported);
  CHECK_TRUE(a.liner.whole_row);
  CHECK(std::isnan(a.liner.theta_deg));
  CHECK(a.liner.sensor_fallback.has_value());
  STRCMP_EQUAL("1001", a.liner.sensor_fallback->sensor.c_str());
  DOUBLES_EQUAL(40.0, a.liner.sensor_fallback->thickness_mm, 1e-12);
  CHECK(a.liner.sensor_fallback->time == used[0].time);
  CHECK_FALSE(a.rows[1].supported);
  STRCMP_EQUAL("1002", a.rows[1].sensor_fallback->sensor.c_str());
  const nlohmann::ordered_json j = ThinnestAreaJson(a.liner);
  CHECK_FALSE(j["supported"].get<bool>());
  CHECK(j["theta_deg"].is_null());
  STRCMP_EQUAL("1001", j["sensor_fallback"]["sensor"].get<std::string>().c_str());
}

// The thinnest area is at the discharge edge, 0.5 m below the only sensor of its row: extrapolated
// from the map with the default reach, not with a reach that covers it.
TEST(ThinnestArea, AnAreaBeyondTheSensorsReachIsLabelledExtrapolatedWithItsDistance) {
  CrusherConfig c = TwoRows();
  c.thinnest_area.sensor_reach_m = 0.1;
  const WearMap m = lw::test::CylinderMap(72, 40, [](double z) { return 2.0 - 0.5 * z; });
  const ReconstructionPlan plan = PrepareReconstruction(c, m);
  const std::vector<Reading> used = Used(c, 80, 100);
  const Reconstruction rec = Reconstruct(plan, WearOf(used));
  ThinnestAreas a = FindThinnestAreas(plan, rec, used);
  CHECK_TRUE(a.liner.supported);
  CHECK(a.liner.z_m < 0.2);
  CHECK_TRUE(a.liner.extrapolated);
  // Sensor 1001 at z 0.5, theta 0 on a 1 m cylinder: at least its height above the area's centre.
  CHECK(a.liner.nearest_sensor_m >= 0.5 - a.liner.z_m - 1e-9);
  CHECK(a.liner.nearest_sensor_m > 0.5 * a.liner.patch_m + c.thinnest_area.sensor_reach_m);
  CHECK(ThinnestAreaText(a.liner).find("extrapolated from the DEM map, nearest sensor") != std::string::npos);
  c.thinnest_area.sensor_reach_m = 5.0;
  a = FindThinnestAreas(plan, rec, used);
  CHECK_FALSE(a.liner.extrapolated);
}

// Worn through is stated where the supported area's whole band is at 0 mm.
TEST(ThinnestArea, WornThroughOnlyWhereTheSupportedBandSaysSo) {
  const CrusherConfig c = TwoRows();
  const WearMap m = lw::test::CylinderMap(72, 40, [](double) { return 1.0; });
  const ReconstructionPlan plan = PrepareReconstruction(c, m);
  const std::vector<Reading> used = Used(c, 0, 0);  // both sensors at their last loop
  ThinnestAreas a = FindThinnestAreas(plan, Reconstruct(plan, WearOf(used)), used);
  CHECK_TRUE(a.liner.supported);
  CHECK_FALSE(a.liner.worn_through);  // 0.5 mm left, +/- the quantisation: not all of the band is 0
  const std::vector<SensorWear> beyond = {{"1001", 130.0}, {"1002", 130.0}};  // past the liner
  a = FindThinnestAreas(plan, Reconstruct(plan, beyond), used);
  CHECK_TRUE(a.liner.worn_through);
}

// An estimate past worn through whose band is wide: the band clipped to [0, new] is narrow (it
// cannot go below 0 mm), but the data do not say whether the area is 0 or tens of mm thick. Seen on
// a LIGGGHTS map (c7815-tall, two sensors per row): "0.0 mm, band 0.0-10.9 mm, supported" where the
// truth had 61 mm left and the unclipped band was +/-86 mm. Neither supported nor worn through:
// the sensors' own reading is shown.
TEST(ThinnestArea, ABandClippedAtZeroIsNotSupportedByItsClippedWidth) {
  const CrusherConfig c = TwoRows();
  WearMap m = NoisyMap();
  for (Eigen::Index i = 0; i < m.wear.size(); ++i)
    if (m.z[i] < 0.2) m.wear[i] *= 3.0;  // a discharge-edge band far below the sensor at z 0.5
  // The map model's error as it is (no point error: with one sensor a row it is the model's error
  // of a sensor predicted from one row mate), so that the sweep reaches a band clipped at 0 mm.
  ReconstructionOptions o;
  o.calibration_prior_dof = 0;
  const ReconstructionPlan plan = PrepareReconstruction(c, m, o);
  const double target = c.thinnest_area.band_half_width_mm;
  int seen = 0;
  for (double r1001 = 70; r1001 >= 0; r1001 -= 1) {
    const std::vector<Reading> used = Used(c, r1001, 110);
    const ThinnestAreas a = FindThinnestAreas(plan, Reconstruct(plan, WearOf(used)), used);
    for (const ThinnestArea* x : {&a.liner, &a.rows[0]}) {
      DOUBLES_EQUAL(std::clamp(x->raw_hi_mm, 0.0, c.thickness_new_mm), x->hi_mm, 1e-9);
      DOUBLES_EQUAL(std::clamp(x->raw_lo_mm, 0.0, c.thickness_new_mm), x->lo_mm, 1e-9);
      if (!(x->lo_mm <= 0 && x->raw_hi_mm > 0 && 0.5 * (x->hi_mm - x->lo_mm) <= target && x->half_width_mm > target)) continue;
      ++seen;
      CHECK_FALSE(x->supported);
      CHECK_FALSE(x->worn_through);
      CHECK(x->sensor_fallback.has_value());
    }
  }
  CHECK(seen > 0);  // the sweep reaches such a band
}

TEST(ThinnestArea, NoSensorsGivesNoNumber) {
  const CrusherConfig c = TwoRows();
  const WearMap m = lw::test::CylinderMap(36, 20, [](double) { return 1.0; });
  const ReconstructionPlan plan = PrepareReconstruction(c, m);
  const ThinnestAreas a = FindThinnestAreas(plan, Reconstruct(plan, {}), {});
  CHECK(std::isnan(a.liner.thickness_mm));
  CHECK_FALSE(a.liner.supported);
  CHECK(ThinnestAreaJson(a.liner)["thickness_mm"].is_null());
}

// A map that knows the height profile and nothing around the circumference (each face's noise
// independent, no pattern around): a thin band at the bottom, with the sensors that agree with the
// map. The square patches are too noisy for the target; a ring all around at the bottom is not,
// and it is where the band is.
TEST(ThinnestArea, WhereNoSquarePatchIsNarrowEnoughARingAllAroundIs) {
  CrusherConfig c = TwoRows();
  c.sensors = {{"1001", "LDWN", 0.4, 0.0, 120, {}}, {"1003", "LDWN", 0.6, 120.0, 120, {}}, {"1005", "LDWN", 0.8, 240.0, 120, {}},
               {"1002", "LUP", 1.3, 60.0, 120, {}}, {"1004", "LUP", 1.5, 180.0, 120, {}},  {"1006", "LUP", 1.7, 300.0, 120, {}}};
  WearMap m = lw::test::CylinderMap(72, 40, [](double z) { return z < 0.2 ? 2.0 : 1.0; });
  uint64_t state = 99;
  for (Eigen::Index i = 0; i < m.wear.size(); ++i) {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    m.wear[i] *= 0.1 + 1.8 * (static_cast<double>(state >> 11) / 9007199254740992.0);
  }
  const ReconstructionPlan plan = PrepareReconstruction(c, m);
  std::vector<Reading> used;
  std::vector<SensorWear> wear;
  const TimePoint t = AddDays(c.installed_at, 60);
  for (size_t s = 0; s < c.sensors.size(); ++s) {
    const double w = 40.0 * plan.sensor_intensity[static_cast<Eigen::Index>(s)];
    used.push_back({t, c.sensors[s].id, std::floor(120.0 - w), 0});
    wear.push_back({c.sensors[s].id, 120.0 - (std::floor(120.0 - w) + 0.5)});
  }
  const Reconstruction rec = Reconstruct(plan, wear);
  const ThinnestAreas a = FindThinnestAreas(plan, rec, used);
  CHECK_TRUE(a.liner.supported);
  CHECK(a.liner.shape == AreaShape::kRing);
  CHECK_FALSE(a.liner.whole_row);
  CHECK(a.liner.patch_m < 1.0);                      // a band, not the whole 1 m row
  CHECK(a.liner.z_m - 0.5 * a.liner.patch_m < 0.2);  // it reaches into the worn band at the bottom
  CHECK(std::isnan(a.liner.theta_deg));
  // Its number is the mean of the faces it names.
  DOUBLES_EQUAL(a.liner.thickness_mm, AreaMean(plan, rec.remaining_mm, a.liner), 1e-6);
  const nlohmann::ordered_json j = ThinnestAreaJson(a.liner);
  STRCMP_EQUAL("ring", j["shape"].get<std::string>().c_str());
  CHECK(j["theta_deg"].is_null());
  CHECK(ThinnestAreaText(a.liner).find("band all around") != std::string::npos);
}

// A check reads the truth where the product reports: the mean over the faces of the reported square
// is the reported number (no face estimated beyond the liner), and the thinnest patch of a field on
// the same grid is the one the product finds when the field is its own estimate.
TEST(ThinnestArea, AreaMeanAndThinnestPatchOfReadAFieldAsTheSearchReadsItsEstimate) {
  const CrusherConfig c = TwoRows();
  const WearMap m = NoisyMap();
  const ReconstructionPlan plan = PrepareReconstruction(c, m);
  const std::vector<Reading> used = Used(c, 60, 90);
  const Reconstruction rec = Reconstruct(plan, WearOf(used));
  CHECK(rec.worn_through_faces == 0);
  const ThinnestAreas a = FindThinnestAreas(plan, rec, used);
  for (const ThinnestArea& area : a.rows) {
    DOUBLES_EQUAL(area.thickness_mm, AreaMean(plan, rec.remaining_mm, area), 1e-6);
    if (area.shape != AreaShape::kSquare) continue;
    const int row = area.row == "LDWN" ? 0 : 1;
    const ThinnestArea same = ThinnestPatchOf(plan, rec.remaining_mm, row, area.patch_m);
    DOUBLES_EQUAL(area.thickness_mm, same.thickness_mm, 1e-6);
    DOUBLES_EQUAL(area.z_m, same.z_m, 1e-9);
  }
}

// An unsupported area says what would narrow its band: with two sensors, more sensors; with three
// or more that still leave the scale this uncertain, the sensors disagree with the map's pattern.
TEST(ThinnestArea, AnUnsupportedAreaSaysWhatWouldNarrowItsBand) {
  ThinnestArea a;
  a.row = "LDWN";
  a.thickness_mm = 62.0;
  a.lo_mm = 0.0;
  a.hi_mm = 120.0;
  a.shape = AreaShape::kRow;
  a.whole_row = true;
  a.scale_sd_mm = 25.0;
  a.map_sd_mm = 5.0;
  a.row_sensors = 2;
  const std::string two = ThinnestAreaJson(a)["detail"].get<std::string>();
  STRCMP_CONTAINS("set by 2 sensors (more sensors in this row", two.c_str());
  a.row_sensors = 4;
  const std::string four = ThinnestAreaJson(a)["detail"].get<std::string>();
  STRCMP_CONTAINS("its 4 sensors disagree with the DEM map's pattern", four.c_str());
  a.scale_sd_mm = 1.0;
  const std::string map = ThinnestAreaJson(a)["detail"].get<std::string>();
  STRCMP_CONTAINS("the DEM map's own error here", map.c_str());
}

// The setting opens by the concave's wear at its discharge ring: the lowest ring_height_m of the
// lowest row, all around. Its opening is the new thickness less the ring's mean remaining
// thickness as the estimate has it there, its band the ring's band read from the other side, and
// with crusher.json's css_mm the setting itself follows. Without a row scale there is no number.
TEST(ThinnestArea, TheSettingOpensByTheDischargeRingsWear) {
  CrusherConfig c = TwoRows();
  c.setting.css_mm = 125;
  c.setting.ring_height_m = 0.1;
  const WearMap m = lw::test::CylinderMap(72, 40, [](double z) { return 2.0 - 0.5 * z; });
  const ReconstructionPlan plan = PrepareReconstruction(c, m);
  const std::vector<Reading> used = Used(c, 40, 70);
  const Reconstruction rec = Reconstruct(plan, WearOf(used));
  const SettingEstimate s = EstimateSetting(plan, rec, used);
  STRCMP_EQUAL("LDWN", s.ring.row.c_str());
  DOUBLES_EQUAL(0.05, s.ring.z_m, 1e-9);
  DOUBLES_EQUAL(0.1, s.ring.patch_m, 1e-9);
  CHECK(s.ring.shape == AreaShape::kRing);
  DOUBLES_EQUAL(120.0 - AreaMean(plan, rec.remaining_mm, s.ring), s.opening_mm, 1e-6);
  // The map wears 2 - z/2: the ring (z 0-0.1) about 1.975 / 1.75 times the sensor's 79.5 mm.
  DOUBLES_EQUAL(79.5 * 1.975 / 1.75, s.opening_mm, 2.0);
  CHECK(s.opening_lo_mm <= s.opening_mm && s.opening_mm <= s.opening_hi_mm);
  DOUBLES_EQUAL(120.0 - s.ring.hi_mm, s.opening_lo_mm, 1e-9);
  DOUBLES_EQUAL(120.0 - s.ring.lo_mm, s.opening_hi_mm, 1e-9);
  const nlohmann::ordered_json j = SettingJson(s);
  DOUBLES_EQUAL(125.0 + s.opening_mm, j["css_mm"].get<double>(), 0.01);
  DOUBLES_EQUAL(125.0, j["css_set_mm"].get<double>(), 0);
  STRCMP_CONTAINS("mantle", j["basis"].get<std::string>().c_str());
  STRCMP_CONTAINS("CSS about", SettingText(s).c_str());
  // Unsupported, it names no CSS: the clipped band would look precise (on data/dem/c6275-std it
  // read "120.0..120.0" beside a half-width of 137 mm).
  SettingEstimate unsupported = s;
  unsupported.ring.supported = false;
  STRCMP_CONTAINS("not supported", SettingText(unsupported).c_str());
  CHECK(SettingText(unsupported).find("CSS") == std::string::npos);

  // A measured setting anchors the CSS: the latest check up to the time asked, the CSS its
  // measurement plus the opening since, the band shifted by the opening at the check.
  const TimePoint t0 = c.installed_at;
  const std::vector<SettingCheck> checks = {{t0 + std::chrono::hours(24 * 10), 130, s.opening_mm - 5, "ops"},
                                            {t0 + std::chrono::hours(24 * 20), 128, s.opening_mm - 2, "ops"},
                                            {t0 + std::chrono::hours(24 * 40), 127, std::nan(""), "ops"}};
  SettingEstimate checked = s;
  ApplySettingChecks(checks, t0 + std::chrono::hours(24 * 25), &checked);
  CHECK(checked.check.has_value());
  DOUBLES_EQUAL(128.0, checked.check->css_mm, 0);
  DOUBLES_EQUAL(2.0, checked.OpeningSince(), 1e-9);
  const nlohmann::ordered_json cj = SettingJson(checked);
  DOUBLES_EQUAL(130.0, cj["css_mm"].get<double>(), 0.011);
  DOUBLES_EQUAL(128.0 + s.opening_lo_mm - (s.opening_mm - 2), cj["css_band_mm"][0].get<double>(), 0.011);
  DOUBLES_EQUAL(128.0 + s.opening_hi_mm - (s.opening_mm - 2), cj["css_band_mm"][1].get<double>(), 0.011);
  DOUBLES_EQUAL(125.0, cj["css_set_mm"].get<double>(), 0);  // crusher.json's stays as it was
  DOUBLES_EQUAL(128.0, cj["checked"]["css_mm"].get<double>(), 0);
  DOUBLES_EQUAL(2.0, cj["opening_since_mm"].get<double>(), 0.011);
  STRCMP_CONTAINS("since it was measured 128 mm on", SettingText(checked).c_str());
  ApplySettingChecks(checks, t0 + std::chrono::hours(24 * 5), &checked);  // before the first: crusher.json's
  CHECK_FALSE(checked.check.has_value());
  DOUBLES_EQUAL(125.0 + s.opening_mm, SettingJson(checked)["css_mm"].get<double>(), 0.011);
  ApplySettingChecks(checks, t0 + std::chrono::hours(24 * 50), &checked);  // a check whose opening is not known
  CHECK(SettingJson(checked)["css_mm"].is_null());
  CHECK(std::isnan(checked.OpeningSince()));
  STRCMP_CONTAINS("the opening since is not known", SettingText(checked).c_str());
  // A check whose ring was not supported then keeps its central estimate: the CSS counts from it, and says so.
  const std::vector<SettingCheck> rough = {{t0 + std::chrono::hours(24 * 10), 130, s.opening_mm - 4, "ops", false}};
  ApplySettingChecks(rough, t0 + std::chrono::hours(24 * 25), &checked);
  DOUBLES_EQUAL(4.0, checked.OpeningSince(), 1e-9);
  DOUBLES_EQUAL(134.0, SettingJson(checked)["css_mm"].get<double>(), 0.011);
  CHECK_FALSE(SettingJson(checked)["checked"]["opening_supported"].get<bool>());
  STRCMP_CONTAINS("central estimate of a ring not supported then", SettingText(checked).c_str());

  c.setting.css_mm.reset();
  const ReconstructionPlan plain = PrepareReconstruction(c, m);
  const nlohmann::ordered_json k = SettingJson(EstimateSetting(plain, Reconstruct(plain, WearOf(used)), used));
  CHECK(k["css_mm"].is_null());
  CHECK(k["css_band_mm"].is_null());
  CHECK(k["opening_mm"].is_number());
  const Reconstruction none = Reconstruct(plain, {});
  const SettingEstimate n = EstimateSetting(plain, none, {});
  CHECK(std::isnan(n.opening_mm));
  CHECK(SettingJson(n)["opening_mm"].is_null());
}

namespace {

/// TwoRows with three sensors high in LDWN (z 0.85, around) and LUP's one: the discharge edge is
/// 0.8 m below every sensor, beyond the default reach.
CrusherConfig ThreeHighInLdwn() {
  CrusherConfig c = TwoRows();
  c.sensors = {{"1001", "LDWN", 0.85, 0.0, 120, {}},
               {"1003", "LDWN", 0.85, 120.0, 120, {}},
               {"1004", "LDWN", 0.85, 240.0, 120, {}},
               {"1002", "LUP", 1.5, 90.0, 120, {}}};
  return c;
}

/// Latest readings of ThreeHighInLdwn's sensors: LDWN's three `ldwn`, LUP's `lup`.
std::vector<Reading> ReadingsOf(const CrusherConfig& c, const std::vector<double>& ldwn, double lup) {
  const TimePoint t = AddDays(c.installed_at, 60);
  return {{t, "1001", ldwn[0], 0}, {t, "1003", ldwn[1], 0}, {t, "1004", ldwn[2], 0}, {t, "1002", lup, 0}};
}

}  // namespace

// Sensors of one row that disagree with each other about the map's pattern (each predicted from
// its row mates 10-25 % off) say how far off the map is at a point no sensor checks. A row with
// one sensor has no scatter of its own: its scale carries that error, not none.
TEST(ThinnestArea, AOneSensorRowsScaleCarriesThePatternErrorTheOtherRowsSensorsShow) {
  const CrusherConfig c = ThreeHighInLdwn();
  const WearMap m = NoisyMap();
  const ReconstructionPlan plan = PrepareReconstruction(c, m);
  const Reconstruction rec = Reconstruct(plan, WearOf(ReadingsOf(c, {60, 80, 72}, 80)));
  CHECK_TEXT(rec.calibration.point_rel_sd > 0.05, std::to_string(rec.calibration.point_rel_sd).c_str());
  const RowSummary& lup = rec.rows[1];
  LONGS_EQUAL(1, lup.sensors_used);
  CHECK_TEXT(lup.scale_sd >= lup.scale_mm_per_unit * rec.calibration.point_rel_sd * (1 - 1e-9),
             (std::to_string(lup.scale_sd) + " " + std::to_string(lup.scale_mm_per_unit)).c_str());
  // Sensors that agree with the map leave the one-sensor row's scale as its own error says.
  const Reconstruction agree = Reconstruct(plan, WearOf(ReadingsOf(c, {71, 71, 71}, 80)));
  CHECK(agree.rows[1].scale_sd < lup.scale_sd);
}

// The thinnest area lies at the discharge edge, beyond every sensor's reach. When the sensors
// disagree with the map's pattern more than its window spread says, the edge area carries that
// error in its map part: a small patch there is no longer "supported" on the map's spread alone.
TEST(ThinnestArea, AnExtrapolatedAreaCarriesTheMapErrorTheSensorsShow) {
  CrusherConfig c = ThreeHighInLdwn();
  c.thinnest_area.band_half_width_mm = 1e9;  // every area meets it: the thinnest 0.1 m patch is reported
  c.thinnest_area.sensor_reach_m = 0.3;
  const WearMap m = NoisyMap();
  const ReconstructionPlan plan = PrepareReconstruction(c, m);
  const std::vector<Reading> disagree = ReadingsOf(c, {60, 80, 72}, 80);
  const Reconstruction rec = Reconstruct(plan, WearOf(disagree));
  const ThinnestArea a = FindThinnestAreas(plan, rec, disagree).rows[0];
  CHECK_TEXT(a.extrapolated, ThinnestAreaText(a).c_str());
  // At least the sensors' point error over the area, less what averaging over its size keeps away.
  const double wear = c.thickness_new_mm - a.thickness_mm;
  CHECK_TEXT(
      a.map_sd_mm >= 0.3 * wear * rec.calibration.point_rel_sd,
      (std::to_string(a.map_sd_mm) + " wear " + std::to_string(wear) + " point " + std::to_string(rec.calibration.point_rel_sd))
          .c_str());
  // The same area within a sensor's reach keeps the map's own (calibrated) error: narrower.
  c.thinnest_area.sensor_reach_m = 5.0;
  const ThinnestArea within = FindThinnestAreas(plan, Reconstruct(plan, WearOf(disagree)), disagree).rows[0];
  CHECK_FALSE(within.extrapolated);
  DOUBLES_EQUAL(a.z_m, within.z_m, 1e-12);
  CHECK_TEXT(a.map_sd_mm > 1.2 * within.map_sd_mm,
             (std::to_string(a.map_sd_mm) + " vs " + std::to_string(within.map_sd_mm)).c_str());
}

namespace {

/// Three rows on the noisy cylinder (LDWN 0-0.7 m, LMID 0.7-1.4, LUP 1.4-2): two sensors in LDWN,
/// one in each of the others (2 / 1 / 1).
CrusherConfig ThreeRows() {
  CrusherConfig c = TwoRows();
  c.rows = {{"LDWN", 0.0, 0.7}, {"LMID", 0.7, 1.4}, {"LUP", 1.4, 2.0}};
  c.sensors = {{"1001", "LDWN", 0.35, 0.0, 120, {}},
               {"1003", "LDWN", 0.35, 180.0, 120, {}},
               {"1002", "LMID", 1.05, 90.0, 120, {}},
               {"1004", "LUP", 1.7, 270.0, 120, {}}};
  return c;
}

}  // namespace

// A sensor that goes stale leaves fewer sensors to check the map with, so no band may narrow: with
// its row's mate gone no row holds two sensors, and the point error the one-sensor rows' scales and
// the faces beyond every sensor's reach carry is the model's own (a sensor predicted from one row
// mate as uncertain as itself), not none. The LDWN pair reads 40 mm a unit of the map model's
// intensity, each off by the model's own error at it (one up, one down); LMID and LUP the map.
// Above LMID's centre the estimate does not depend on LDWN's sensors: the same faces and LUP's
// area, compared directly.
TEST(ThinnestArea, LosingTheOnlyPairsSecondSensorNarrowsNoBand) {
  const CrusherConfig c = ThreeRows();
  const WearMap m = NoisyMap();
  const ReconstructionPlan plan = PrepareReconstruction(c, m);
  const TimePoint t = AddDays(c.installed_at, 60);
  std::vector<SensorWear> wear;
  std::vector<Reading> used;
  for (size_t s = 0; s < c.sensors.size(); ++s) {
    const double rel =
        plan.sensor_intensity_sd[static_cast<Eigen::Index>(s)] / plan.sensor_intensity[static_cast<Eigen::Index>(s)];
    const double off = s == 0 ? 0.5 * rel : s == 1 ? -0.5 * rel : 0.0;
    const double w = 40.0 * plan.sensor_intensity[static_cast<Eigen::Index>(s)] * (1.0 + off);
    wear.push_back({c.sensors[s].id, w});
    used.push_back({t, c.sensors[s].id, 120.0 - w, 0});
  }
  const Reconstruction pair = Reconstruct(plan, wear);
  const ThinnestAreas pair_areas = FindThinnestAreas(plan, pair, used);
  LONGS_EQUAL(2, pair.calibration.sensors);
  wear.erase(wear.begin() + 1);  // 1003 stale
  used.erase(used.begin() + 1);
  const Reconstruction single = Reconstruct(plan, wear);
  const ThinnestAreas single_areas = FindThinnestAreas(plan, single, used);
  LONGS_EQUAL(0, single.calibration.sensors);
  CHECK_TEXT(single.calibration.point_rel_sd > 0, std::to_string(single.calibration.point_rel_sd).c_str());
  size_t compared = 0;
  for (Eigen::Index i = 0; i < m.z.size(); ++i) {
    if (m.z[i] < 1.05) continue;
    DOUBLES_EQUAL(pair.remaining_mm[i], single.remaining_mm[i], 1e-9);
    CHECK_TEXT(
        single.remaining_sd_mm[i] >= pair.remaining_sd_mm[i] * (1 - 1e-9),
        (std::to_string(i) + ": " + std::to_string(single.remaining_sd_mm[i]) + " < " + std::to_string(pair.remaining_sd_mm[i]))
            .c_str());
    ++compared;
  }
  CHECK(compared > 1000);
  const ThinnestArea &before = pair_areas.rows[2], &after = single_areas.rows[2];
  DOUBLES_EQUAL(before.thickness_mm, after.thickness_mm, 1e-9);
  CHECK_TEXT(after.half_width_mm >= before.half_width_mm * (1 - 1e-9),
             (ThinnestAreaText(after) + " vs " + ThinnestAreaText(before)).c_str());
  CHECK(single.rows[2].scale_sd >= pair.rows[2].scale_sd * (1 - 1e-9));
}

// The per-face band carries the floor an area beyond every sensor's reach carries: a face there
// (the discharge edge, 0.8 m below every sensor) has a map error of at least point_rel_sd x its
// wear, so no face's band is narrower than its area's says the map is off there.
TEST(ThinnestArea, AFaceBeyondEverySensorsReachCarriesThePointErrorInItsOwnBand) {
  CrusherConfig c = ThreeHighInLdwn();
  c.thinnest_area.sensor_reach_m = 0.3;
  const WearMap m = NoisyMap();
  const ReconstructionPlan plan = PrepareReconstruction(c, m);
  const Reconstruction rec = Reconstruct(plan, WearOf(ReadingsOf(c, {60, 80, 72}, 80)));
  const double point = rec.calibration.point_rel_sd;
  CHECK_TEXT(point > 0.05, std::to_string(point).c_str());
  size_t beyond = 0;
  for (Eigen::Index i = 0; i < m.z.size(); ++i) {
    double nearest = std::numeric_limits<double>::infinity();
    for (const SensorInfo& s : c.sensors)  // on the 1 m cylinder: along z and the arc
      nearest = std::min(nearest, std::hypot(m.z[i] - s.z_m, AngleDiffDeg(m.theta_deg[i], s.theta_deg) * M_PI / 180.0));
    if (nearest <= c.thinnest_area.sensor_reach_m) continue;
    ++beyond;
    CHECK_TEXT(
        rec.remaining_sd_mm[i] >= point * rec.wear_estimate_mm[i] * (1 - 1e-9),
        (std::to_string(i) + ": " + std::to_string(rec.remaining_sd_mm[i]) + " wear " + std::to_string(rec.wear_estimate_mm[i]))
            .c_str());
  }
  CHECK(beyond > 1000);
}
