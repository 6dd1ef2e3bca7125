// estimate/window.hpp: a reading window gives Estimate() exactly what every reading gives, whether
// readings are added one by one in any order or loaded through a store's walks up to a time; the
// UsableForWear rule leaves faults and a previous liner's readings out.
#include <algorithm>
#include <random>
#include <string>
#include <vector>

#include "core/time.hpp"
#include "estimate/estimate.hpp"
#include "estimate/model.hpp"
#include "estimate/window.hpp"
#include "sim/campaign.hpp"
#include "support/temp_directory.hpp"

#include <CppUTest/TestHarness.h>  // last: its leak-detection macros clash with std headers

namespace {

using lw::estimate::Point;
using lw::estimate::Sample;

/// A 60-day campaign (its scan on day 40): long enough for the window to leave readings out.
struct Campaign {
  lw::test::TempDirectory dir{"lw-estimate-window"};
  lw::core::Bundle bundle;
  std::unique_ptr<lw::estimate::CrusherModel> model;
  Campaign() {
    lw::sim::CampaignSpec spec;
    spec.days = 60;
    spec.scan_day = 40;
    lw::sim::GenerateCampaign(spec, 11).WriteBundle(dir.File("b"));
    bundle = lw::core::LoadBundle(dir.File("b"));
    model = lw::estimate::CrusherModel::FromBundle(bundle);
  }
};

Campaign& Data() {
  static Campaign c;
  return c;
}

int64_t Unix(lw::core::TimePoint t) {
  return t.time_since_epoch().count();
}

/// What a store's time index walk gives: `samples` of `sensor` with time in [from, to], by (time, seq).
lw::estimate::ReadingWindow::Walk WalkOf(const std::vector<Sample>& samples, const std::string& sensor) {
  return [&samples, sensor](int64_t from, int64_t to, bool newest_first, const std::function<bool(const Point&)>& visit) {
    std::vector<Point> points;
    for (const Sample& s : samples)
      if (s.sensor == sensor && s.time_s >= from && s.time_s <= to) points.push_back(s);
    std::sort(points.begin(), points.end(),
              [](const Point& a, const Point& b) { return a.time_s < b.time_s || (a.time_s == b.time_s && a.seq < b.seq); });
    if (newest_first) std::reverse(points.begin(), points.end());
    for (const Point& p : points)
      if (!visit(p)) return;
  };
}

/// The estimates' numbers agree to the last bit.
void CheckSameEstimate(const lw::estimate::WearEstimate& want, const lw::estimate::WearEstimate& got) {
  CHECK_TRUE(want.has_wear);
  CHECK_TRUE(got.has_wear);
  CHECK(want.time == got.time);
  CHECK(want.stale == got.stale);
  CHECK(want.stuck == got.stuck);
  CHECK(lw::core::ThinnestAreaJson(want.areas.liner) == lw::core::ThinnestAreaJson(got.areas.liner));
  DOUBLES_EQUAL(want.reconstruction.min_thickness_mm, got.reconstruction.min_thickness_mm, 0);
  DOUBLES_EQUAL(0, (want.reconstruction.remaining_mm - got.reconstruction.remaining_mm).cwiseAbs().maxCoeff(), 0);
  CHECK_EQUAL(want.scan != nullptr, got.scan != nullptr);
  LONGS_EQUAL(want.row_forecasts.size(), got.row_forecasts.size());
  for (size_t k = 0; k < want.row_forecasts.size(); ++k) {
    CHECK(want.row_forecasts[k].reach == got.row_forecasts[k].reach);
    CHECK(want.row_forecasts[k].reach_earliest == got.row_forecasts[k].reach_earliest);
  }
}

}  // namespace

TEST_GROUP(ReadingWindow){};

TEST(ReadingWindow, ReadingsAddedInAnyOrderEstimateAsEveryReading) {
  const Campaign& c = Data();
  std::vector<Sample> all = lw::estimate::SamplesOf(c.bundle.readings);
  std::vector<Sample> shuffled = all;
  std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937(5));
  lw::estimate::ReadingWindow window(*c.model);
  for (const Sample& s : shuffled) CHECK_TRUE(window.Add(s.sensor, s));
  const std::vector<Sample> kept = window.Readings();
  CHECK_TEXT(kept.size() * 2 < all.size(), "the window holds the forecast window, not every reading");
  CheckSameEstimate(lw::estimate::Estimate(*c.model, all), lw::estimate::Estimate(*c.model, window));
  CHECK(window.LatestUsableTime() && *window.LatestUsableTime() == Unix(lw::estimate::Estimate(*c.model, all).time));
}

// A past time's window (GET .../wear?at=TIME) loaded through a store's walks up to it estimates as
// the readings up to it, added one by one.
TEST(ReadingWindow, LoadedUpToATimeEstimatesAsTheReadingsUpToIt) {
  const Campaign& c = Data();
  const std::vector<Sample> all = lw::estimate::SamplesOf(c.bundle.readings);
  for (const double day : {30.0, 50.0}) {
    const lw::core::TimePoint at = lw::core::AddDays(c.bundle.crusher.installed_at, day);
    lw::estimate::ReadingWindow loaded(*c.model), added(*c.model);
    for (const auto& s : c.bundle.crusher.sensors) loaded.Load(s.id, Unix(at), WalkOf(all, s.id));
    std::vector<Sample> upto;
    for (const Sample& s : all)
      if (s.time_s <= Unix(at)) {
        added.Add(s.sensor, s);
        upto.push_back(s);
      }
    const lw::estimate::WearEstimate want = lw::estimate::Estimate(*c.model, upto, at);
    CheckSameEstimate(want, lw::estimate::Estimate(*c.model, loaded, at));
    CheckSameEstimate(want, lw::estimate::Estimate(*c.model, added, at));
    CHECK(want.time <= at);
    CHECK_EQUAL(day > 40, want.scan != nullptr);  // the scans up to the time only
    // Later readings given to Estimate are left out at `at`.
    CheckSameEstimate(want, lw::estimate::Estimate(*c.model, all, at));
  }
}

TEST(ReadingWindow, FaultsAndAPreviousLinersReadingsAreNotUsable) {
  const lw::core::CrusherConfig& config = Data().bundle.crusher;
  const std::string sensor = config.sensors.at(0).id;
  Point p;
  p.time_s = Unix(config.installed_at) + 86400;
  p.thickness_mm = 40;
  p.loops_intact = 40;
  CHECK_TRUE(lw::estimate::UsableForWear(config, sensor, p));
  p.flags = 1 << 3;  // every loop open while loops are intact: a cut cable
  CHECK_FALSE(lw::estimate::UsableForWear(config, sensor, p));
  p.loops_intact = 0;  // every loop open, none intact: consumed, real wear
  CHECK_TRUE(lw::estimate::UsableForWear(config, sensor, p));
  p.flags = 1 << 4;  // SPI stuck
  CHECK_FALSE(lw::estimate::UsableForWear(config, sensor, p));
  p.flags = 0;
  p.time_s = Unix(config.LinerStart()) - 1;  // before this liner
  CHECK_FALSE(lw::estimate::UsableForWear(config, sensor, p));
  lw::estimate::ReadingWindow window(*Data().model);
  CHECK_FALSE(window.Add(sensor, p));
  CHECK_FALSE(window.LatestUsableTime().has_value());
  CHECK_TRUE(window.Readings().empty());
}
