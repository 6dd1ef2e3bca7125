// Remaining-life forecast: fitted wear curves, reach dates and bands, from quantised readings.
#include <cmath>
#include <set>

#include "core/forecast.hpp"

#include <CppUTest/TestHarness.h>  // last

using namespace lw::core;

namespace {

CrusherConfig Crusher() {
  CrusherConfig c;
  c.crusher_id = std::string("crusher");  // (a 1-char literal trips GCC 12's -Wrestrict false positive)
  c.installed_at = *ParseIsoTime("2026-01-01T00:00:00Z");
  c.thickness_new_mm = 120;
  c.thickness_min_mm = 30;
  c.rows = {{"LDWN", 0, 1}, {"LUP", 1, 2}};
  c.sensors = {{"1", "LDWN", 0.5, 0, 120, std::nullopt}, {"2", "LUP", 1.5, 0, 120, std::nullopt}};
  return c;
}

/// Ladder readings (floored to whole mm) every 6 h of a true thickness curve.
template <typename F>
std::vector<Reading> Ladder(const CrusherConfig& c, const std::string& id, double days, F thickness) {
  std::vector<Reading> out;
  for (double t = 0; t <= days; t += 0.25) {
    out.push_back({AddDays(c.installed_at, t), id, std::floor(thickness(t)), 0});
  }
  return out;
}

double DaysTo(const CrusherConfig& c, const std::optional<TimePoint>& t) {
  return DaysBetween(c.installed_at, *t);
}

/// A row's thinnest area with a band of +/- `half` mm.
ThinnestArea Area(const std::string& row, double thickness, double half = 0.0) {
  ThinnestArea a;
  a.row = row;
  a.thickness_mm = thickness;
  a.lo_mm = thickness - half;
  a.hi_mm = thickness + half;
  a.supported = true;
  return a;
}

/// Row forecasts of both rows from the sensors' readings up to day `day`, their areas where the
/// sensors are (ratio 1), as the server computes them at each refresh.
std::vector<RowForecast> RowsAt(const CrusherConfig& c, const std::vector<Reading>& all, double day) {
  std::vector<Reading> upto;
  for (const Reading& r : all)
    if (r.time <= AddDays(c.installed_at, day)) upto.push_back(r);
  std::vector<SensorForecast> sensors;
  std::vector<SensorWear> wear;
  std::vector<ThinnestArea> areas;
  for (const SensorInfo& s : c.sensors) {
    sensors.push_back(ForecastSensor(c, s, upto));
    const double mm = sensors.back().last_reading_mm + 0.5;
    wear.push_back({s.id, 120.0 - mm});
    areas.push_back(Area(s.row, mm, 1.0));
  }
  return ForecastRows(c, areas, wear, sensors, AddDays(c.installed_at, day));
}

}  // namespace

TEST_GROUP(Forecast){};

TEST(Forecast, LinearWearReachesTheMinimumWhenTheLineSays) {
  const CrusherConfig c = Crusher();
  // 1 mm/day: 120 - t reaches 30 mm on day 90.
  const auto f = ForecastSensor(c, c.sensors[0], Ladder(c, "1", 40, [](double t) { return 120.0 - t; }));
  CHECK_TRUE(f.ok);
  DOUBLES_EQUAL(1.0, f.rate_mm_per_day, 0.05);
  DOUBLES_EQUAL(90.0, DaysTo(c, f.reach), 2.0);
  CHECK(DaysTo(c, f.reach_earliest) <= DaysTo(c, f.reach));
  CHECK(DaysTo(c, f.reach_latest) >= DaysTo(c, f.reach));
  CHECK(DaysTo(c, f.reach_latest) - DaysTo(c, f.reach_earliest) < 30.0);
  // The curve starts at the last reading and its band brackets the central estimate.
  CHECK_FALSE(f.points.empty());
  for (const auto& p : f.points) CHECK(p.lo_mm <= p.thickness_mm && p.thickness_mm <= p.hi_mm);
  DOUBLES_EQUAL(80.0, f.last_reading_mm, 0);
}

TEST(Forecast, AcceleratingWearIsForecastEarlierThanAStraightLineWould) {
  const CrusherConfig c = Crusher();
  // Wear accelerates: w = 0.5 t + 0.01 t^2 (a softer core): 90 mm at t ~ 73.4 days.
  const auto accel = [](double t) { return 120.0 - (0.5 * t + 0.01 * t * t); };
  const auto f = ForecastSensor(c, c.sensors[0], Ladder(c, "1", 50, accel));
  const double truth = (-0.5 + std::sqrt(0.25 + 4 * 0.01 * 90)) / (2 * 0.01);
  DOUBLES_EQUAL(truth, DaysTo(c, f.reach), 3.0);
  // A line through the installation and the last reading (70 mm at day 50) would say day ~90.
  CHECK(DaysTo(c, f.reach) < 85.0);
}

TEST(Forecast, EarlyFlatteningIsNotExtrapolatedAsDeceleration) {
  const CrusherConfig c = Crusher();
  // Work hardening: fast at first, then a steady 0.8 mm/day. The forecast must not bend upwards.
  const auto hardening = [](double t) { return 120.0 - (0.8 * t + 6.0 * (1 - std::exp(-t / 6.0))); };
  const auto f = ForecastSensor(c, c.sensors[0], Ladder(c, "1", 60, hardening));
  CHECK(f.curve.c[2] >= 0.0);
  DOUBLES_EQUAL(0.8, f.rate_mm_per_day, 0.1);
}

TEST(Forecast, TooFewReadingsSaySo) {
  const CrusherConfig c = Crusher();
  const auto none = ForecastSensor(c, c.sensors[0], {});
  CHECK_FALSE(none.ok);
  STRCMP_EQUAL("no readings", none.note.c_str());
  const auto early = ForecastSensor(c, c.sensors[0], Ladder(c, "1", 0.5, [](double t) { return 120.0 - t; }));
  CHECK_FALSE(early.ok);
}

TEST(Forecast, RowsFollowTheirThinnestArea) {
  const CrusherConfig c = Crusher();
  std::vector<Reading> all = Ladder(c, "1", 40, [](double t) { return 120.0 - t; });
  const auto up = Ladder(c, "2", 40, [](double t) { return 120.0 - 0.25 * t; });
  all.insert(all.end(), up.begin(), up.end());
  std::vector<SensorForecast> sensors = {ForecastSensor(c, c.sensors[0], all), ForecastSensor(c, c.sensors[1], all)};
  // Thinnest areas: LDWN's has worn 1.5x its sensor (60 vs 40 mm).
  const std::vector<ThinnestArea> areas = {Area("LDWN", 60.0), Area("LUP", 110.0)};
  const std::vector<SensorWear> wear = {{"1", 40.0}, {"2", 10.0}};
  const auto rows = ForecastRows(c, areas, wear, sensors, AddDays(c.installed_at, 40));
  LONGS_EQUAL(2, rows.size());
  CHECK_TRUE(rows[0].ok);
  DOUBLES_EQUAL(1.5, rows[0].rate_mm_per_day, 0.1);
  // 30 mm left at 1.5 mm/day: 20 days after day 40.
  DOUBLES_EQUAL(60.0, DaysTo(c, rows[0].reach), 2.0);
  CHECK(DaysTo(c, rows[0].reach_earliest) <= DaysTo(c, rows[0].reach));
  // LUP: 80 mm left at 0.25 x 1.0 (face 10 mm worn = its sensor) = 0.25 mm/day: day ~360.
  DOUBLES_EQUAL(360.0, DaysTo(c, rows[1].reach), 15.0);
}

// A row past its minimum says since when, and gives no reach date (not one equal to the latest
// reading, "0 days after").
TEST(Forecast, ARowPastItsMinimumSaysBelowMinimumSince) {
  const CrusherConfig c = Crusher();
  std::vector<Reading> all = Ladder(c, "1", 100, [](double t) { return 120.0 - t; });
  const auto up = Ladder(c, "2", 100, [](double t) { return 120.0 - 0.25 * t; });
  all.insert(all.end(), up.begin(), up.end());
  const std::vector<RowForecast> rows = RowsAt(c, all, 100);
  CHECK_TRUE(rows[0].below_minimum_since.has_value());
  // 120 - t reaches 30 mm at day 90 (the interval centre: day 89.5).
  DOUBLES_EQUAL(89.5, DaysTo(c, rows[0].below_minimum_since), 1.0);
  CHECK_FALSE(rows[0].reach.has_value());
  CHECK_FALSE(rows[0].reach_earliest.has_value());
  CHECK(rows[0].reach_note.find("below minimum since 2026-") == 0);
  CHECK_FALSE(rows[1].below_minimum_since.has_value());
  CHECK_TRUE(rows[1].reach.has_value());
}

// A slow row that has lost no loop in its fit window: its rate's band reaches zero, so a central
// date would be anywhere; it says so and gives only the earliest date.
// A row whose map band is too wide for any smaller area reports its whole row: that mean wears
// slower than the row's thinnest sensor, which then sets the row's date (the demo's LDWN: a 62 mm
// row mean beside a sensor reading 35 mm).
TEST(Forecast, ARowIsDueNoLaterThanItsThinnestSensor) {
  const CrusherConfig c = Crusher();
  // 1 mm/day: the sensor reads 40 mm at day 80 and reaches 30 mm at day 90.
  const auto all = Ladder(c, "1", 80, [](double t) { return 120.0 - t; });
  const std::vector<SensorForecast> sensors = {ForecastSensor(c, c.sensors[0], all), ForecastSensor(c, c.sensors[1], all)};
  // The whole row's mean: 80 mm left, worn half the sensor's 80 mm: alone it would say day ~180.
  const std::vector<ThinnestArea> areas = {Area("LDWN", 80.0, 30.0), Area("LUP", 110.0)};
  const std::vector<SensorWear> wear = {{"1", 79.5}};
  const auto rows = ForecastRows(c, areas, wear, sensors, AddDays(c.installed_at, 80));
  CHECK_TRUE(rows[0].ok);
  STRCMP_EQUAL("1", rows[0].reach_set_by.c_str());
  DOUBLES_EQUAL(90.0, DaysTo(c, rows[0].reach), 2.0);
  CHECK(DaysTo(c, rows[0].reach_latest) <= DaysTo(c, sensors[0].reach_latest) + 1e-6);
  CHECK(DaysTo(c, rows[0].reach_earliest) <= DaysTo(c, rows[0].reach));
  CHECK(rows[0].reach_note.find("sensor 1") != std::string::npos);
  // A row whose area sets an earlier date than its sensor keeps the area's.
  const auto thin = ForecastRows(c, {Area("LDWN", 35.0, 1.0), Area("LUP", 110.0)}, wear, sensors, AddDays(c.installed_at, 80));
  CHECK_TRUE(thin[0].reach_set_by.empty());
  CHECK(DaysTo(c, thin[0].reach) < 88.0);

  // Past the minimum at the sensor (20 mm at day 100): the row is below it since the sensor's day 90.
  const auto later = Ladder(c, "1", 100, [](double t) { return 120.0 - t; });
  const std::vector<SensorForecast> past = {ForecastSensor(c, c.sensors[0], later), ForecastSensor(c, c.sensors[1], later)};
  const auto rows2 =
      ForecastRows(c, {Area("LDWN", 70.0, 30.0), Area("LUP", 110.0)}, {{"1", 99.5}}, past, AddDays(c.installed_at, 100));
  CHECK_TRUE(rows2[0].below_minimum_since.has_value());
  DOUBLES_EQUAL(90.0, DaysTo(c, rows2[0].below_minimum_since), 2.0);
  CHECK_FALSE(rows2[0].reach.has_value());
  STRCMP_EQUAL("1", rows2[0].reach_set_by.c_str());
}

TEST(Forecast, ARateNotDistinguishableFromZeroIsBeyondForecastWithTheReason) {
  const CrusherConfig c = Crusher();
  std::vector<Reading> all = Ladder(c, "1", 42, [](double t) { return 120.0 - t; });
  const auto up = Ladder(c, "2", 42, [](double t) { return 119.99 - 0.02 * t; });
  all.insert(all.end(), up.begin(), up.end());
  const std::vector<RowForecast> rows = RowsAt(c, all, 42);
  CHECK(rows[1].rate_mm_per_day - 2.0 * rows[1].rate_sd_mm_per_day <= 0.0);
  CHECK_FALSE(rows[1].reach.has_value());
  CHECK_FALSE(rows[1].reach_latest.has_value());
  CHECK_TRUE(rows[1].reach_earliest.has_value());
  CHECK(rows[1].reach_note.find("not distinguishable from zero") != std::string::npos);
  CHECK_TRUE(rows[0].reach.has_value());
  CHECK(rows[0].reach_note.empty());
}

// The same readings refreshed give the same date; a slow row refreshed daily as loops break
// (readings within their quantisation of a straight line) keeps its published date while each new
// estimate lies within the band, instead of one date per refresh.
TEST(Forecast, RelineDatesHoldStillWhileNewEstimatesStayInsideTheirBand) {
  const CrusherConfig c = Crusher();
  std::vector<Reading> all = Ladder(c, "1", 120, [](double t) { return 120.0 - 0.6 * t; });
  const auto up = Ladder(c, "2", 120, [](double t) { return 119.7 - 0.15 * t; });
  all.insert(all.end(), up.begin(), up.end());
  std::vector<RowForecast> published = RowsAt(c, all, 60);
  for (int k = 0; k < 5; ++k) {  // no new reading: the same dates
    std::vector<RowForecast> again = RowsAt(c, all, 60);
    HoldRowForecasts(published, &again);
    CHECK(again[1].reach == published[1].reach);
    published = again;
  }
  std::set<int64_t> raw_dates, held_dates;
  for (double day = 60.25; day <= 90; day += 0.25) {
    std::vector<RowForecast> now = RowsAt(c, all, day);
    raw_dates.insert(std::chrono::duration_cast<std::chrono::hours>(now[1].reach->time_since_epoch()).count() / 24);
    HoldRowForecasts(published, &now);
    held_dates.insert(std::chrono::duration_cast<std::chrono::hours>(now[1].reach->time_since_epoch()).count() / 24);
    // A held date lies inside the new band, the new estimate inside the previous band.
    CHECK(!now[1].reach_earliest || *now[1].reach >= *now[1].reach_earliest);
    published = now;
  }
  CHECK(raw_dates.size() > 10);  // each refresh's own estimate moves
  CHECK(held_dates.size() <= 3);
}
