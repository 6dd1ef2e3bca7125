#include <cmath>
#include <string>

#include "core/forecast.hpp"
#include "core/reconstruction.hpp"
#include "unit/core/bundle_fixture.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw::core;
using lw::test::TwoRows;

TEST_GROUP(Reconstruction){};

// Intensity 2 - z/2: 1.75 at the lower sensor, 1.25 at the upper one.
TEST(Reconstruction, Eq9ScalesEachRowBySensorOverIntensity) {
  const CrusherConfig c = TwoRows();
  const WearMap m = lw::test::CylinderMap(36, 40, [](double z) { return 2.0 - 0.5 * z; });
  const Eigen::VectorXd at = IntensityAtSensors(c, m, 0.05);
  DOUBLES_EQUAL(1.75, at[0], 0.02);
  DOUBLES_EQUAL(1.25, at[1], 0.02);
  ReconstructionOptions o;
  o.interpolate_between_rows = false;
  const Reconstruction r = Reconstruct(c, m, {{"1001", 35.0}, {"1002", 12.5}}, o);
  // Row scale = W_s0 / W_i0: 20 mm per unit below, 10 above.
  DOUBLES_EQUAL(20.0, r.rows[0].scale_mm_per_unit, 0.3);
  DOUBLES_EQUAL(10.0, r.rows[1].scale_mm_per_unit, 0.2);
  // Worst spot: the bottom edge, intensity 2 - 0.025 = 1.975 -> wear 39.5 mm.
  DOUBLES_EQUAL(120 - 1.975 * 20, r.min_thickness_mm, 0.6);
  CHECK(m.z[static_cast<Eigen::Index>(r.min_face)] < 0.1);
  DOUBLES_EQUAL(r.min_thickness_mm, r.rows[0].min_thickness_mm, 1e-12);
  LONGS_EQUAL(1, r.rows[0].sensors_used);
}

TEST(Reconstruction, ScaleIsInterpolatedAlongZBetweenRowCentres) {
  const CrusherConfig c = TwoRows();
  const WearMap m = lw::test::CylinderMap(36, 40, [](double) { return 1.0; });
  const Reconstruction r = Reconstruct(c, m, {{"1001", 30.0}, {"1002", 10.0}});
  for (Eigen::Index i = 0; i < m.z.size(); ++i) {
    const double z = m.z[i];
    const double expected = z <= 0.5 ? 30.0 : (z >= 1.5 ? 10.0 : 30.0 - 20.0 * (z - 0.5));
    DOUBLES_EQUAL(expected, r.wear_mm[i], 1e-9);
    DOUBLES_EQUAL(120.0 - expected, r.remaining_mm[i], 1e-9);
  }
}

TEST(Reconstruction, RowWithoutSensorsTakesItsScaleFromItsNeighbours) {
  CrusherConfig c = TwoRows();
  c.rows.push_back({"LTOP", 2.0, 3.0});
  const WearMap m = lw::test::CylinderMap(12, 20, [](double) { return 1.0; });
  const Reconstruction r = Reconstruct(c, m, {{"1001", 30.0}});  // only the lower row reports
  for (Eigen::Index i = 0; i < m.z.size(); ++i) DOUBLES_EQUAL(30.0, r.wear_mm[i], 1e-9);
  LONGS_EQUAL(0, r.rows[1].sensors_used);
}

TEST(Reconstruction, SensorWearUsesTheIntervalCentreOfTheLatestReading) {
  const CrusherConfig c = TwoRows();
  const auto t0 = *ParseIsoTime("2026-01-01");
  std::vector<Reading> rs = {{t0, "1001", 110, 0}, {AddDays(t0, 2), "1001", 100, 0}, {AddDays(t0, 5), "1001", 90, 0}};
  auto w = SensorWearAt(c, rs, AddDays(t0, 3));
  LONGS_EQUAL(1, w.size());
  DOUBLES_EQUAL(19.5, w[0].wear_mm, 1e-12);
  w = SensorWearAt(c, rs, AddDays(t0, 3), false);
  DOUBLES_EQUAL(20.0, w[0].wear_mm, 1e-12);
}

// Both sensors report every 6 hours; 1002 dies on day 3 while 1001 goes on to day 10. Its latest
// reading (day 3) is 7 days behind the newest, more than max(1 day, 8 x 0.25 days): stale.
TEST(Reconstruction, ASensorWhoseReadingsStoppedSetsNoScale) {
  const CrusherConfig c = TwoRows();
  const auto t0 = *ParseIsoTime("2026-01-01");
  std::vector<Reading> rs;
  for (int k = 0; k <= 40; ++k) rs.push_back({AddDays(t0, 0.25 * k), "1001", 110.0 - 0.5 * k, 0});
  for (int k = 0; k <= 12; ++k) rs.push_back({AddDays(t0, 0.25 * k), "1002", 115.0 - 0.25 * k, 0});
  std::vector<std::string> stale;
  const auto fresh = FreshSensorWearAt(c, rs, AddDays(t0, 10), {}, &stale);
  LONGS_EQUAL(1, fresh.size());
  STRCMP_EQUAL("1001", fresh[0].sensor_id.c_str());
  LONGS_EQUAL(1, stale.size());
  STRCMP_EQUAL("1002", stale[0].c_str());
  LONGS_EQUAL(2, SensorWearAt(c, rs, AddDays(t0, 10)).size());  // the plain selection keeps both
  // At day 3.5 both are fresh (1002's last reading is half a day old).
  LONGS_EQUAL(2, FreshReadingIndices(c, rs, AddDays(t0, 3.5)).size());
  // The reference is the newest reading, not the time asked for: a scan long after the last
  // readings (the gateway was down) still finds both sensors at day 3.
  std::vector<Reading> early;
  for (const Reading& r : rs)
    if (r.time <= AddDays(t0, 3)) early.push_back(r);
  LONGS_EQUAL(2, FreshReadingIndices(c, early, AddDays(t0, 30)).size());
  // A longer reporting period stretches the limit: with 2-day periods 7 days is within 8 periods.
  std::vector<Reading> slow;
  for (int k = 0; k <= 5; ++k) slow.push_back({AddDays(t0, 2.0 * k), "1001", 110.0 - k, 0});
  slow.push_back({AddDays(t0, 3), "1002", 114, 0});
  slow.push_back({AddDays(t0, 1), "1002", 115, 0});
  LONGS_EQUAL(2, FreshReadingIndices(c, slow, AddDays(t0, 10)).size());
}

namespace {

// Readings every 6 hours from day 0 to day `days` of one sensor whose thickness is `thickness(t)`
// (floored to whole loops, as the sensor reads).
template <typename F>
void Report(std::vector<Reading>& rs, TimePoint t0, const std::string& id, double days, F thickness) {
  for (int k = 0; 0.25 * k <= days; ++k) rs.push_back({AddDays(t0, 0.25 * k), id, std::floor(thickness(0.25 * k)), 0});
}

// TwoRows with 1003 and 1004 added to the lower row (1001, 1003, 1004 there; 1002 above), installed at t0.
CrusherConfig ThreeInTheLowerRow(TimePoint t0) {
  CrusherConfig c = TwoRows();
  c.sensors.push_back({"1003", "LDWN", 0.6, 180.0, 120, {}});
  c.sensors.push_back({"1004", "LDWN", 0.4, 270.0, 120, {}});
  c.installed_at = t0;
  return c;
}

// 100 days of ThreeInTheLowerRow: 1001, 1002 and 1004 wear 1.0, 0.3 and 0.9 mm a day, 1003 as `third`.
template <typename F>
std::vector<Reading> HundredDays(TimePoint t0, F third) {
  std::vector<Reading> rs;
  Report(rs, t0, "1001", 100, [](double t) { return 119.9 - 1.0 * t; });
  Report(rs, t0, "1002", 100, [](double t) { return 119.9 - 0.3 * t; });
  Report(rs, t0, "1003", 100, third);
  Report(rs, t0, "1004", 100, [](double t) { return 119.9 - 0.9 * t; });
  return rs;
}

std::vector<std::string> Stuck(const CrusherConfig& c, const std::vector<Reading>& rs, TimePoint at) {
  std::vector<std::string> stale, stuck;
  const std::vector<size_t> live = LiveReadingIndices(c, rs, at, &stale, &stuck);
  CHECK_TRUE(stale.empty());
  LONGS_EQUAL(FreshReadingIndices(c, rs, at).size(), live.size() + stuck.size());
  return stuck;
}

}  // namespace

// Three sensors in the lower row wear about 1 mm a day; from day 10, 1003 keeps reporting 108 mm
// (moisture across its loops). By day 20 its mates have worn 10 mm more, and it wore as much as they
// had by day 10: it should have lost about 11 mm. It is stuck, sets no scale, and is named. Each
// condition of the rule, removed in turn, keeps it.
TEST(Reconstruction, ASensorReportingOneValueWhileItsRowWearsIsStuck) {
  CrusherConfig c = TwoRows();
  c.sensors.push_back({"1003", "LDWN", 0.6, 180.0, 120, {}});
  c.sensors.push_back({"1004", "LDWN", 0.4, 270.0, 120, {}});
  const auto t0 = *ParseIsoTime("2026-01-01");
  const TimePoint at = AddDays(t0, 20);
  auto campaign = [&](auto stuck_sensor, auto mate) {
    std::vector<Reading> rs;
    Report(rs, t0, "1001", 20, [](double t) { return 119.9 - 1.0 * t; });
    Report(rs, t0, "1002", 20, [](double t) { return 119.9 - 0.3 * t; });
    Report(rs, t0, "1003", 20, stuck_sensor);
    Report(rs, t0, "1004", 20, mate);
    return rs;
  };
  const auto steady = [](double t) { return 119.9 - 0.9 * t; };
  const auto stuck_at_108 = [](double t) { return 119.9 - 1.1 * std::min(t, 10.0); };
  std::vector<std::string> stuck = Stuck(c, campaign(stuck_at_108, steady), at);
  LONGS_EQUAL(1, stuck.size());
  STRCMP_EQUAL("1003", stuck[0].c_str());
  // Its wear no longer sets the lower row's scale: the live selection holds 1001, 1002 and 1004.
  const std::vector<Reading> rs = campaign(stuck_at_108, steady);
  const auto wear = SensorWearFrom(c, rs, LiveReadingIndices(c, rs, at));
  LONGS_EQUAL(3, wear.size());
  for (const SensorWear& w : wear) CHECK_TRUE(w.sensor_id != "1003");
  // Day 14: the mates have worn 4 mm since it stopped (4.4 expected of it), too little to tell.
  CHECK_TRUE(Stuck(c, campaign(stuck_at_108, steady), AddDays(t0, 14)).empty());
  // A slow sensor is not stuck: at a quarter of its mates' rate its value holds for 4 days at most,
  // in which a quarter of their wear is 1 mm.
  CHECK_TRUE(Stuck(c, campaign([](double t) { return 119.9 - 0.25 * t; }, steady), at).empty());
  // Consumed (0 mm): its wear is the whole sensor; not judged.
  CHECK_TRUE(Stuck(c, campaign([](double t) { return std::max(0.0, 119.9 - 12.0 * t); }, steady), at).empty());
  // Two stuck sensors in a row of three do not vouch for each other: both are named, against 1001.
  const auto stuck_at_107 = [](double t) { return 119.9 - 1.0 * std::min(t, 12.0); };
  const std::vector<std::string> both = Stuck(c, campaign(stuck_at_108, stuck_at_107), at);
  CHECK_TEXT(both == (std::vector<std::string>{"1003", "1004"}), (both.empty() ? "none" : both.front()).c_str());
  // A sensor at a slow spot still on its first loop (reads 119, so it wore 0-1 mm) while its mates
  // wear 1.8 mm a day: on day 23 (the window from day 2, when they had worn 3.6 mm) its share of
  // their 38 mm since is taken at 0 mm of its own, not the interval centre's 0.5 mm (5.3 mm).
  std::vector<Reading> first_loop;
  Report(first_loop, t0, "1001", 23, [](double t) { return 119.9 - 1.8 * t; });
  Report(first_loop, t0, "1004", 23, [](double t) { return 119.9 - 1.8 * t; });
  Report(first_loop, t0, "1003", 23, [](double t) { return 119.9 - 0.03 * t; });
  Report(first_loop, t0, "1002", 23, [](double t) { return 119.9 - 0.3 * t; });
  CHECK_TRUE(Stuck(c, first_loop, AddDays(t0, 23)).empty());
  // A crack cuts 11 loops of a slow sensor on day 8 (0.1 mm a day): its value (108) waits for the
  // wear to catch up. That is a crack (the diagnosis names it), not a stuck value, although its
  // inflated wear would make its share of its mates' wear 7 mm by day 13.75.
  CHECK_TRUE(
      Stuck(c, campaign([](double t) { return 119.9 - 0.1 * t - (t > 8 ? 10.5 : 0.0); }, steady), AddDays(t0, 13.75)).empty());
  // A mate's spall (a 12 mm step on day 18) is not wear a slow sensor should have followed: at a
  // fifth of the fast mate's rate it holds 116 mm from day 14.5 to 19.25, in which the spalled mate
  // loses 1.4 mm gradually (13.4 with the step; expected of the slow one 1.1, or 10.4).
  const auto slow = [](double t) { return 119.9 - 0.2 * t; };
  const auto spalled = [](double t) { return 119.9 - 0.3 * t - (t > 18 ? 12.0 : 0.0); };
  const TimePoint before_step_counts = AddDays(t0, 19.25);
  CHECK_TRUE(Stuck(c, campaign(slow, spalled), before_step_counts).empty());
  std::vector<Reading> spall_only = campaign(slow, spalled);  // the spalled mate alone
  std::erase_if(spall_only, [](const Reading& r) { return r.sensor_id == "1001"; });
  CHECK_TRUE(Stuck(c, spall_only, before_step_counts).empty());
  // A sensor alone in its row is not judged: 1002 (upper row) flat from day 5 stays.
  std::vector<Reading> alone = campaign(steady, steady);
  std::erase_if(alone, [](const Reading& r) { return r.sensor_id == "1002"; });
  Report(alone, t0, "1002", 20, [](double t) { return 119.9 - 0.3 * std::min(t, 5.0); });
  CHECK_TRUE(Stuck(c, alone, at).empty());
}

TEST(Reconstruction, AScansScalesLeaveOutASensorAlreadyFrozenAtItsDate) {
  // 1003 froze on day 5 (114); a scan on day 30; now day 100, 1003 stuck. Its reading at the scan
  // (114: 5.5 mm of wear instead of about 33) is its frozen value: left out of the scan's scales.
  const auto t0 = *ParseIsoTime("2026-01-01");
  const CrusherConfig c = ThreeInTheLowerRow(t0);
  auto campaign = [&](auto third) { return HundredDays(t0, third); };
  const TimePoint scan = AddDays(t0, 30), now = AddDays(t0, 100);
  const auto ids = [](const std::vector<SensorWear>& w) {
    std::vector<std::string> out;
    for (const SensorWear& s : w) out.push_back(s.sensor_id);
    return out;
  };
  const std::vector<Reading> early = campaign([](double t) { return 119.9 - 1.1 * std::min(t, 5.0); });
  const std::vector<std::string> all{"1001", "1002", "1003", "1004"}, without{"1001", "1002", "1004"};
  CHECK_TRUE(ids(ScanSensorWear(c, early, scan, {"1003"}, now)) == without);
  CHECK_TRUE(ids(ScanSensorWear(c, early, scan, {}, now)) == all);
  // Frozen on day 60, after the scan: its reading at the scan was still wear. Kept.
  const std::vector<Reading> late = campaign([](double t) { return 119.9 - 1.1 * std::min(t, 60.0); });
  const std::vector<SensorWear> kept = ScanSensorWear(c, late, scan, {"1003"}, now);
  CHECK_TRUE(ids(kept) == all);
  DOUBLES_EQUAL(120.0 - (std::floor(119.9 - 33.0) + 0.5), kept[2].wear_mm, 1e-9);
  // Frozen on day 30.5, within the loop it read at the scan (day 30: 86.9 -> 86; it would have read
  // 85 from day 30.8): its value then was right, but the value alone cannot tell. Left out; its
  // mates set the row's scale at the scan.
  const std::vector<Reading> same_loop = campaign([](double t) { return 119.9 - 1.1 * std::min(t, 30.5); });
  CHECK_TRUE(ids(ScanSensorWear(c, same_loop, scan, {"1003"}, now)) == without);
}

// Day 100 of a campaign: the rule reads the last 40 days (from day 60) and, before them, each
// sensor's record lows. 1003 froze on day 4 at 115 mm, when it and its mates had worn about 4 mm:
// at their rate it should have lost about 85 mm since. From the window alone (the run taken from day
// 60, where its mates had worn 54 mm) its share of their 36 mm since would be 2.7 mm: not named.
TEST(Reconstruction, AValueFrozenBeforeTheWindowIsJudgedFromWhenItFroze) {
  const auto t0 = *ParseIsoTime("2026-01-01");
  const CrusherConfig c = ThreeInTheLowerRow(t0);
  auto campaign = [&](auto third) { return HundredDays(t0, third); };
  const TimePoint now = AddDays(t0, 100);
  const std::vector<std::string> stuck = Stuck(c, campaign([](double t) { return 119.9 - 1.1 * std::min(t, 4.0); }), now);
  CHECK_TEXT(stuck == std::vector<std::string>{"1003"}, stuck.empty() ? "none" : stuck.front().c_str());
  // A loop that reads intact again before the window restarts the run: the same sensor reading 116
  // for a day on day 30 is judged from day 31, when its mates had worn 28-32 mm (its share of their
  // wear since, about 9 mm: named).
  const auto flicker = [](double t) { return 119.9 - 1.1 * std::min(t, 4.0) + (t >= 30 && t < 31 ? 1 : 0); };
  CHECK_TRUE(Stuck(c, campaign(flicker), now) == std::vector<std::string>{"1003"});
  // So a loop read open once, long ago, does not stretch a slow sensor's run back to it: at a slow
  // spot (119 to day 50, then 118) with one reading of 118 on day 5, the run is from day 50 (its
  // share about 1 mm), not day 5 (when its mates had worn 5-6 mm: 16 mm).
  const auto open_once = [](double t) { return t < 50 && !(t >= 5 && t < 5.2) ? 119.9 : 118.9; };
  CHECK_TRUE(Stuck(c, campaign(open_once), now).empty());
  // A slow spot (a twentieth of its mates' rate) holds each loop for 22 days, reaching back before
  // the window; its share of its mates' wear over that run is about 1 mm. Not named.
  CHECK_TRUE(Stuck(c, campaign([](double t) { return 119.9 - 0.045 * t; }), now).empty());
  // A crack cuts 10 loops of a slow sensor on day 4 (0.1 mm a day): its value (109) waits for the
  // wear to catch up, flat from day 4 to the end. The run began with a 10 mm step (from the record
  // low before it): a crack, not a stuck value (the window alone shows only the flat run, and its
  // share of its mates' wear in the window, 6.5 mm, would name it).
  const auto cracked = [](double t) { return t > 4 ? std::min(119.9 - 0.1 * t, 109.0) : 119.9 - 0.1 * t; };
  CHECK_TRUE(Stuck(c, campaign(cracked), now).empty());
  // A radio outage from day 20 to 24, after which the value stays at its day-24 reading (the
  // moisture that cut the radio): a fall of 4 mm between its readings, which its own rate (1.1 mm
  // a day) explains over the 4 days. No crack: named.
  std::vector<Reading> outage = campaign([](double t) { return 119.9 - 1.1 * std::min(t, 24.0); });
  std::erase_if(outage,
                [&](const Reading& r) { return r.sensor_id == "1003" && r.time > AddDays(t0, 20) && r.time < AddDays(t0, 24); });
  CHECK_TRUE(Stuck(c, outage, now) == std::vector<std::string>{"1003"});
  // A slow spot (2 % of its mates' rate) whose first loop sits 0.84 mm deeper than the as-new
  // thickness puts it (casting): it reads 118 from day 5 to day 88, when its mates had worn 4 mm
  // and it 1 (taken low: 0 with the mounting tolerance, not 1, a quarter of their wear). Not named.
  std::vector<Reading> offset;
  Report(offset, t0, "1001", 80, [](double t) { return 119.9 - 0.6 * t; });
  Report(offset, t0, "1002", 80, [](double t) { return 119.9 - 0.3 * t; });
  Report(offset, t0, "1003", 80, [](double t) { return 119.06 - 0.012 * t; });
  Report(offset, t0, "1004", 80, [](double t) { return 119.9 - 0.54 * t; });
  CHECK_TRUE(Stuck(c, offset, AddDays(t0, 80)).empty());
}

// A reline: the sensors of the new liner keep their ids, installed_at moves to its installation
// (day 100.5, half a day after the old boards' last reports), and the previous liner's 100 days of
// readings stay in the history. They are no part of this liner, those in the day of clock slack
// before installed_at included (they show wear a liner cannot have before it is installed): on its
// day 100 the same frozen 1003 (115 mm from its day 4) is named, which the old liner's record lows
// (down to 30 mm) would hide; the latest readings, the stale rule and the forecast are its own; a
// reading of a new sensor in the day before installed_at still counts.
TEST(Reconstruction, APreviousLinersReadingsCountForNothingAfterAReline) {
  const auto t0 = *ParseIsoTime("2026-01-01");
  const TimePoint t1 = AddDays(t0, 100.5);
  const CrusherConfig c = ThreeInTheLowerRow(t1);
  std::vector<Reading> rs = HundredDays(t0, [](double t) { return 119.9 - 0.9 * t; });
  const size_t previous = rs.size();
  const std::vector<Reading> now_liner = HundredDays(t1, [](double t) { return 119.9 - 1.1 * std::min(t, 4.0); });
  rs.insert(rs.end(), now_liner.begin(), now_liner.end());
  const TimePoint now = AddDays(t1, 100);
  CHECK_TRUE(Stuck(c, rs, now) == std::vector<std::string>{"1003"});
  // Five days after the reline 1004 has not reported yet: it has no reading of this liner (its last
  // one, the old liner's 30 mm, is neither its wear nor a stale sensor's). 1001 has been silent for
  // 1.5 days, under 8 of its 6-hour periods: not stale (the old liner's board reported every 10
  // minutes in its last days: 8 of those periods would make it so).
  const TimePoint early = AddDays(t1, 5);
  std::vector<Reading> silent = rs;
  std::erase_if(silent, [&](const Reading& r) {
    return r.time >= t1 && (r.sensor_id == "1004" || (r.sensor_id == "1001" && r.time > AddDays(t1, 3.5)));
  });
  for (int k = 0; k < 10 * 144; ++k) silent.push_back({AddDays(t1, -12 + k / 144.0), "1001", 40.0, 0});
  const std::vector<size_t> latest = LatestReadingIndices(c, silent, early);
  LONGS_EQUAL(3, latest.size());
  for (const size_t i : latest) CHECK_TRUE(i >= previous && silent[i].sensor_id != "1004");
  std::vector<std::string> stale;
  LONGS_EQUAL(3, LiveReadingIndices(c, silent, early, &stale).size());
  CHECK_TRUE(stale.empty());
  const SensorForecast f = ForecastSensor(c, c.sensors[0], rs);
  LONGS_EQUAL(401, f.readings_used);                    // the new liner's 401 readings of 1001 (every 6 hours, days 0-100)
  rs.push_back({AddDays(t1, -0.9), "1001", 119.0, 0});  // a new board (as new), its clock a little ahead
  rs.push_back({AddDays(t1, -0.8), "1001", 60.0, 0});   // the old board, 60 mm: the previous liner's
  rs.push_back({AddDays(t1, -1.1), "1001", 119.0, 0});  // more than a day before: the previous liner's
  LONGS_EQUAL(402, ForecastSensor(c, c.sensors[0], rs).readings_used);
}

TEST(Reconstruction, SmoothingRemovesFaceNoiseButKeepsTheMean) {
  WearMap m = lw::test::CylinderMap(72, 40, [](double) { return 1.0; });
  for (Eigen::Index i = 0; i < m.wear.size(); ++i) m.wear[i] = (i % 2) ? 1.2 : 0.8;
  const Eigen::VectorXd s = SmoothOverSurface(m, m.wear, 0.15);
  double max_dev = 0;
  for (Eigen::Index i = 0; i < s.size(); ++i) max_dev = std::max(max_dev, std::abs(s[i] - 1.0));
  CHECK(max_dev < 0.05);
  DOUBLES_EQUAL(1.0, s.mean(), 0.01);
}

TEST(Reconstruction, SmoothingFindsEveryNeighbourWithinTheRadiusOnAStronglyTaperedCone) {
  // Radius 0.4 m at the bottom to 2.4 m at the top: at the bottom the arc per degree is six times
  // smaller than at the top. Compare with a brute-force area-weighted mean over all faces.
  WearMap m = lw::test::ConeMap(90, 12, 0.4, 2.4, [](double z) { return 1.0 + z; });
  for (Eigen::Index i = 0; i < m.wear.size(); ++i) m.wear[i] += 0.3 * std::sin(7.0 * static_cast<double>(i));
  const double radius = 0.3;
  const Eigen::VectorXd fast = SmoothOverSurface(m, m.wear, radius);
  double worst = 0;
  for (Eigen::Index i = 0; i < m.wear.size(); ++i) {
    double sw = 0, swv = 0;
    for (Eigen::Index j = 0; j < m.wear.size(); ++j) {
      double dth = std::fabs(m.theta_deg[j] - m.theta_deg[i]);
      dth = std::min(dth, 360.0 - dth);
      const double arc = 0.5 * (m.radius[i] + m.radius[j]) * dth * M_PI / 180.0;
      const double dz = m.z[j] - m.z[i];
      if (dz * dz + arc * arc <= radius * radius) {
        sw += m.areas[j];
        swv += m.areas[j] * m.wear[j];
      }
    }
    worst = std::max(worst, std::fabs(fast[i] - swv / sw));
  }
  DOUBLES_EQUAL(0.0, worst, 1e-9);
}

// Issue 14: a count-limited map (noise ~ its mean, one edge spike) is smoothed at a scale the data
// choose, Eq. 9 at the sensor equals the sensor, outputs stay physical, and no sensor means no number.
TEST(Reconstruction, NoisyMapIsSmoothedAtADataChosenScaleAndOutputsArePhysical) {
  const CrusherConfig c = TwoRows();
  WearMap m = lw::test::CylinderMap(72, 40, [](double z) { return 2.0 - 0.5 * z; });
  uint64_t state = 12345;
  auto uniform = [&] {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(state >> 11) / 9007199254740992.0;
  };
  for (Eigen::Index i = 0; i < m.wear.size(); ++i) m.wear[i] *= 0.2 + 1.6 * uniform();  // CV about 0.46
  m.wear[5] *= 40;                                                                      // a discharge-edge spike
  const ReconstructionPlan plan = PrepareReconstruction(c, m);
  CHECK(plan.model.bandwidth_m > 0.05);  // smoothed, not left at face size
  CHECK(plan.model.outlier_faces >= 1);
  CHECK(plan.model.face_cv > 0.2 && plan.model.face_cv < 0.8);
  const Reconstruction r = Reconstruct(plan, {{"1001", 35.0}, {"1002", 12.5}});
  // At the lower sensor the reconstruction equals the sensor (same kernel at faces and sensor).
  const MapModel::Point at = plan.model.At(0.5, 0.0);
  DOUBLES_EQUAL(35.0, at.intensity * r.rows[0].scale_mm_per_unit, 1e-6);
  CHECK(r.min_thickness_mm >= 0.0);
  CHECK(r.min_thickness_lo_mm <= r.min_thickness_mm && r.min_thickness_mm <= r.min_thickness_hi_mm);
  // Without the smoothing the spike would put the thinnest point at 120 - 40 * 2 * 20 < 0.
  CHECK(r.min_thickness_mm > 60.0);
  // Extreme wear: clamped at 0, counted as worn through, never negative.
  const Reconstruction worn = Reconstruct(plan, {{"1001", 119.0}, {"1002", 119.0}});
  CHECK(worn.worn_through_faces > 0);
  CHECK(worn.remaining_mm.minCoeff() >= 0.0);
  // No sensor: no number.
  const Reconstruction none = Reconstruct(plan, {});
  STRCMP_EQUAL(kStatusNoSensors, none.status.c_str());
  CHECK(std::isnan(none.min_thickness_mm));
}

namespace {

/// A cylinder with per-face sampling noise (relative scatter ~0.46), and a crusher with three
/// sensors in each of its two rows.
WearMap NoisyCylinder() {
  WearMap m = lw::test::CylinderMap(72, 40, [](double z) { return 2.0 - 0.5 * z; });
  uint64_t state = 777;
  for (Eigen::Index i = 0; i < m.wear.size(); ++i) {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    m.wear[i] *= 0.2 + 1.6 * (static_cast<double>(state >> 11) / 9007199254740992.0);
  }
  return m;
}

CrusherConfig SixSensors() {
  CrusherConfig c = TwoRows();
  c.sensors = {{"1001", "LDWN", 0.3, 0.0, 120, {}}, {"1003", "LDWN", 0.5, 120.0, 120, {}}, {"1005", "LDWN", 0.7, 240.0, 120, {}},
               {"1002", "LUP", 1.3, 60.0, 120, {}}, {"1004", "LUP", 1.5, 180.0, 120, {}},  {"1006", "LUP", 1.7, 300.0, 120, {}}};
  return c;
}

/// Each sensor's wear = the row's scale x the map model at it x (1 + rel[k]).
std::vector<SensorWear> WearAgainstMap(const CrusherConfig& c, const ReconstructionPlan& plan, const std::vector<double>& rel) {
  std::vector<SensorWear> w;
  for (size_t s = 0; s < c.sensors.size(); ++s) {
    const double scale = c.sensors[s].row == "LDWN" ? 30.0 : 15.0;
    w.push_back({c.sensors[s].id, scale * plan.sensor_intensity[static_cast<Eigen::Index>(s)] * (1.0 + rel[s])});
  }
  return w;
}

}  // namespace

// Sensors that agree with the map far better than the map's own error model says: the factor
// falls below 1, held up by the model's pseudo-sensors, and every band narrows by it.
TEST(Reconstruction, SensorsThatAgreeWithTheMapNarrowTheMapsErrorByTheFactorTheyMeasure) {
  const CrusherConfig c = SixSensors();
  const WearMap m = NoisyCylinder();
  const ReconstructionPlan plan = PrepareReconstruction(c, m);
  const std::vector<SensorWear> w = WearAgainstMap(c, plan, {0, 0, 0, 0, 0, 0});
  const Reconstruction r = Reconstruct(plan, w);
  LONGS_EQUAL(6, r.calibration.sensors);
  // No error at any sensor beyond quantisation: c^2 = prior / (n + prior) = 2 / 8.
  DOUBLES_EQUAL(0.5, r.calibration.factor, 0.02);
  ReconstructionPlan off = plan;
  off.options.calibration_prior_dof = 0;
  const Reconstruction u = Reconstruct(off, w);
  DOUBLES_EQUAL(1.0, u.calibration.factor, 1e-12);
  LONGS_EQUAL(0, u.calibration.sensors);
  // The map's part of a face's sd halves; the estimate itself does not move.
  for (Eigen::Index i = 0; i < m.z.size(); i += 97) {
    DOUBLES_EQUAL(u.remaining_mm[i], r.remaining_mm[i], 1e-9);
    CHECK(r.remaining_sd_mm[i] < 0.75 * u.remaining_sd_mm[i]);
  }
  CHECK(r.rows[0].scale_sd < u.rows[0].scale_sd);
}

// Sensors that disagree with the map by more than its error model allows widen every band.
TEST(Reconstruction, SensorsThatDisagreeWithTheMapWidenItsError) {
  const CrusherConfig c = SixSensors();
  const WearMap m = NoisyCylinder();
  const ReconstructionPlan plan = PrepareReconstruction(c, m);
  const Reconstruction calm = Reconstruct(plan, WearAgainstMap(c, plan, {0, 0, 0, 0, 0, 0}));
  const Reconstruction r = Reconstruct(plan, WearAgainstMap(c, plan, {0.8, -0.6, 0.7, -0.7, 0.9, -0.5}));
  LONGS_EQUAL(6, r.calibration.sensors);
  CHECK(r.calibration.factor > 1.0);
  CHECK(r.calibration.factor <= 4.0);
  CHECK(r.remaining_sd_mm[100] > calm.remaining_sd_mm[100]);
}

// One sensor per row: nothing to predict a sensor from, the model's error as it is.
TEST(Reconstruction, OneSensorPerRowLeavesTheMapsErrorAsTheModelSaysIt) {
  const CrusherConfig c = TwoRows();
  const WearMap m = NoisyCylinder();
  const Reconstruction r = Reconstruct(PrepareReconstruction(c, m), {{"1001", 35.0}, {"1002", 12.5}});
  LONGS_EQUAL(0, r.calibration.sensors);
  DOUBLES_EQUAL(1.0, r.calibration.factor, 1e-12);
}

// The point error is the sensors' squared excess errors over their squared predictions: a sensor
// where the map predicts almost no wear (0.1 mm, reading a loop more) adds its millimetre to the
// sum, and is no ratio of 250 that stands for all the others (a mean of ratios put the figure at
// its cap of 1, every one-sensor row's scale then as uncertain as the scale itself).
TEST(Reconstruction, ASensorWhereTheMapPredictsAlmostNoWearDoesNotSetThePointError) {
  CrusherConfig c = TwoRows();
  c.sensors = {{"1001", "LDWN", 0.75, 0.0, 120, {}},   {"1003", "LDWN", 0.85, 120.0, 120, {}},
               {"1005", "LDWN", 0.95, 240.0, 120, {}}, {"1002", "LUP", 1.3, 60.0, 120, {}},
               {"1004", "LUP", 1.5, 180.0, 120, {}},   {"1006", "LUP", 1.7, 300.0, 120, {}}};
  WearMap m = NoisyCylinder();
  for (Eigen::Index i = 0; i < m.wear.size(); ++i)
    if (m.z[i] < 0.5) m.wear[i] *= 0.001;  // the map predicts almost nothing there
  ReconstructionOptions o;
  o.calibration_prior_dof = 1e-9;  // the sensors' figure alone, no pseudo-sensors at the model's
  const ReconstructionPlan plan = PrepareReconstruction(c, m, o);
  // The six sensors 10 % off the map each way.
  std::vector<SensorWear> w = WearAgainstMap(c, plan, {0.1, -0.1, 0.1, -0.1, 0.1, -0.1});
  const Reconstruction without = Reconstruct(plan, w);
  CHECK_TEXT(without.calibration.point_rel_sd > 0.03 && without.calibration.point_rel_sd < 0.3,
             std::to_string(without.calibration.point_rel_sd).c_str());
  CrusherConfig c7 = c;
  c7.sensors.push_back({"1007", "LDWN", 0.1, 60.0, 120, {}});
  const ReconstructionPlan plan7 = PrepareReconstruction(c7, m, o);
  const double predicted = 30.0 * plan7.sensor_intensity[6];
  CHECK_TEXT(predicted > 0 && predicted < 0.2, std::to_string(predicted).c_str());
  w.push_back({"1007", predicted + 1.0});
  const Reconstruction with = Reconstruct(plan7, w);
  LONGS_EQUAL(7, with.calibration.sensors);
  CHECK_TEXT(with.calibration.point_rel_sd < 0.5, std::to_string(with.calibration.point_rel_sd).c_str());
  DOUBLES_EQUAL(without.calibration.point_rel_sd, with.calibration.point_rel_sd, 0.25 * without.calibration.point_rel_sd);
}
