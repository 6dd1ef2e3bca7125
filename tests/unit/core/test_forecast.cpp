// Remaining-life forecast: fitted wear curves, reach dates and bands, from quantised readings.
#include <cmath>

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

TEST(Forecast, RowsFollowTheirThinnestFace) {
  const CrusherConfig c = Crusher();
  std::vector<Reading> all = Ladder(c, "1", 40, [](double t) { return 120.0 - t; });
  const auto up = Ladder(c, "2", 40, [](double t) { return 120.0 - 0.25 * t; });
  all.insert(all.end(), up.begin(), up.end());
  std::vector<SensorForecast> sensors = {ForecastSensor(c, c.sensors[0], all), ForecastSensor(c, c.sensors[1], all)};
  // A reconstruction whose LDWN thinnest face has worn 1.5x its sensor (60 vs 40 mm).
  Reconstruction rec;
  rec.rows = {{"LDWN", 0, 60.0, 0, 0, 0, 0, 1}, {"LUP", 0, 110.0, 0, 0, 0, 0, 1}};
  const std::vector<SensorWear> wear = {{"1", 40.0}, {"2", 10.0}};
  const auto rows = ForecastRows(c, rec, wear, sensors, AddDays(c.installed_at, 40));
  LONGS_EQUAL(2, rows.size());
  CHECK_TRUE(rows[0].ok);
  DOUBLES_EQUAL(1.5, rows[0].rate_mm_per_day, 0.1);
  // 30 mm left at 1.5 mm/day: 20 days after day 40.
  DOUBLES_EQUAL(60.0, DaysTo(c, rows[0].reach), 2.0);
  CHECK(DaysTo(c, rows[0].reach_earliest) <= DaysTo(c, rows[0].reach));
  // LUP: 80 mm left at 0.25 x 1.0 (face 10 mm worn = its sensor) = 0.25 mm/day: day ~360.
  DOUBLES_EQUAL(360.0, DaysTo(c, rows[1].reach), 15.0);
}
