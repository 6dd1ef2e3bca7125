#include <cmath>

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
  CHECK(a.liner.supported == (a.liner.hi_mm - a.liner.lo_mm <= 2 * c.thinnest_area.band_half_width_mm + 1e-9));
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

TEST(ThinnestArea, NoSensorsGivesNoNumber) {
  const CrusherConfig c = TwoRows();
  const WearMap m = lw::test::CylinderMap(36, 20, [](double) { return 1.0; });
  const ReconstructionPlan plan = PrepareReconstruction(c, m);
  const ThinnestAreas a = FindThinnestAreas(plan, Reconstruct(plan, {}), {});
  CHECK(std::isnan(a.liner.thickness_mm));
  CHECK_FALSE(a.liner.supported);
  CHECK(ThinnestAreaJson(a.liner)["thickness_mm"].is_null());
}
