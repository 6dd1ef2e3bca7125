// The per-crusher state kept as readings are committed (server/live_state.hpp) gives what a full
// recompute from every stored reading gives: wear and forecast JSON, the sensors' latest readings
// and counts, after ingest in any order, after a restart (rebuilt from the store) and after more
// readings on top of the rebuilt state; and it holds far fewer readings than the store.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>

#include "server/ingest.hpp"
#include "server/live_state.hpp"
#include "server/wear_service.hpp"
#include "unit/server/server_fixture.hpp"

#include <CppUTest/TestHarness.h>  // last: its leak-detection macros clash with std headers

using namespace lw::server;
using nlohmann::json;

namespace {

/// 120 days (the forecast's window is the last 48: most readings fall out of it), the laser scan on
/// day 30 (the sensors' wear at its date comes from readings outside the window).
lw::test::CrusherFolder& Folder() {
  static lw::test::CrusherFolder f(120, 5, 30);
  return f;
}
int64_t Now() {
  return lw::test::LatestReadingS(Folder().bundle) + 3600;
}

constexpr int kFractional = 300;

/// The campaign's readings plus what the state must get right: cut-cable readings (stored, not
/// used for wear) newer than everything else, a second reading at a sensor's latest time that is
/// thinner, one at the scan's date; in a shuffled order (late readings).
std::vector<Incoming> Messages() {
  auto out = lw::test::Messages(Folder().bundle);
  const auto& b = Folder().bundle;
  // A third sensor dies on day 60: stale (no row scale) both ways, from its readings before then.
  const std::string dead = b.crusher.sensors.at(2).id;
  const lw::core::TimePoint died = lw::core::AddDays(b.crusher.installed_at, 60);
  std::erase_if(out, [&](const Incoming& m) {
    return m.sensor == dead && lw::core::ParseIsoTime(json::parse(m.payload)["time"].get<std::string>()).value() > died;
  });
  // A sensor of the lowest row sticks 18 days before the end: it keeps reporting its value while
  // its row mates wear on (stuck, no row scale, both ways).
  const std::string stuck = b.crusher.sensors.at(7).id;
  const lw::core::TimePoint froze = lw::core::AddDays(b.readings.back().time, -18);
  double frozen = -1;
  for (const auto& r : b.readings)
    if (r.sensor_id == stuck && r.time <= froze) frozen = r.thickness_mm;
  // Another sticks on day 6, before the scan (day 30) and long before the window (the last 48 days):
  // stuck both ways, judged from when it froze (the record lows before the window: from the window
  // alone its share of its mates' wear would be under 5 mm), and its frozen value at the scan's date
  // is left out of the scan's scales both ways (core::ScanSensorWear).
  const std::string early = b.crusher.sensors.at(8).id;
  const lw::core::TimePoint froze_early = lw::core::AddDays(b.crusher.installed_at, 6);
  double frozen_early = -1;
  for (const auto& r : b.readings)
    if (r.sensor_id == early && r.time <= froze_early) frozen_early = r.thickness_mm;
  // A middle-row sensor holds its day-12 value too, but one of its loops reads intact again on day
  // 66, before the window: judged from day 66 (its share of its mates' wear since is under 5 mm),
  // not stuck both ways; judged from day 12 it would be (the live state keeps that reading).
  const std::string held = b.crusher.sensors.at(3).id;
  const lw::core::TimePoint held_from = lw::core::AddDays(b.crusher.installed_at, 12);
  const lw::core::TimePoint intact_again = lw::core::AddDays(b.crusher.installed_at, 66);
  double held_mm = -1;
  for (const auto& r : b.readings)
    if (r.sensor_id == held && r.time <= held_from) held_mm = r.thickness_mm;
  bool reread = false;
  for (Incoming& m : out) {
    json j = json::parse(m.payload);
    const lw::core::TimePoint t = lw::core::ParseIsoTime(j["time"].get<std::string>()).value();
    if (m.sensor == held && t > held_from) {
      const bool up = !reread && t >= intact_again;
      reread = reread || up;
      j["thickness_mm"] = held_mm + (up ? 1 : 0);
      j["loops_intact"] = static_cast<int>(held_mm) + (up ? 1 : 0);
      m.payload = j.dump();
      continue;
    }
    const bool is_stuck = m.sensor == stuck && t > froze, is_early = m.sensor == early && t > froze_early;
    if (!is_stuck && !is_early) continue;
    const double mm = is_stuck ? frozen : frozen_early;
    j["thickness_mm"] = mm;
    j["loops_intact"] = static_cast<int>(mm);
    m.payload = j.dump();
  }
  const auto add = [&](const std::string& sensor, int64_t seq, int64_t time_s, double mm, int loops, int flags) {
    const json j = {{"sensor", sensor},
                    {"seq", seq},
                    {"time", lw::core::FormatIsoTime(lw::core::TimePoint(std::chrono::seconds(time_s)))},
                    {"thickness_mm", mm},
                    {"loops_intact", loops},
                    {"flags", flags},
                    {"battery_mv", 3300}};
    out.push_back({"site1", b.crusher.crusher_id, sensor,
                   "linerwatch/v1/site1/" + b.crusher.crusher_id + "/sensors/" + sensor + "/reading", j.dump()});
  };
  const int64_t last = b.readings.back().time.time_since_epoch().count();
  const std::string s0 = b.crusher.sensors.at(0).id, s1 = b.crusher.sensors.at(1).id;
  add(s0, 900001, last + 60, 0, 40, 8);     // all open with loops intact: a cut cable
  add(s1, 900002, last + 120, 55, 55, 16);  // SPI stuck
  int64_t s1_last = 0;
  double s1_mm = 0;
  for (const auto& r : b.readings) {
    if (r.sensor_id == s1 && r.time.time_since_epoch().count() >= s1_last) {
      s1_last = r.time.time_since_epoch().count();
      s1_mm = r.thickness_mm;
    }
  }
  add(s1, 900003, s1_last, s1_mm - 1, static_cast<int>(s1_mm - 1), 0);  // thinner at the same time
  const int64_t scan_s = b.scans.at(0).date.time_since_epoch().count();
  add(s0, 900004, scan_s, 90, 90, 0);  // at the scan's date exactly
  // 300 readings on day 10 a minute apart, each a little thinner, all within one loop below the
  // sensor's reading then (odd input: sensors report whole loops): the state keeps at most one point
  // per loop of the days before the window, not one per reading (CheckEqualsFullRecompute).
  const int64_t day10 = lw::core::AddDays(b.crusher.installed_at, 10).time_since_epoch().count();
  double s0_day10 = 0;
  for (const auto& r : b.readings)
    if (r.sensor_id == s0 && r.time.time_since_epoch().count() <= day10) s0_day10 = r.thickness_mm;
  for (int k = 0; k < kFractional; ++k)
    add(s0, 910000 + k, day10 + 60 * k, s0_day10 - 0.001 - 0.003 * k, static_cast<int>(s0_day10) - 1, 0);
  std::mt19937 rng(3);
  // Mostly in order (as a gateway delivers), with every 7th message moved to a random place.
  for (size_t i = 0; i < out.size(); i += 7) std::swap(out[i], out[rng() % out.size()]);
  return out;
}

/// Everything the live state serves equals the full recompute from `store`.
void CheckEqualsFullRecompute(const Crusher& c, const LiveState& live, Store& store, bool expect_pruned) {
  const auto all = store.All(Folder().id());
  const auto inputs = live.WearInputs(Folder().id());
  if (expect_pruned) CHECK_TEXT(inputs.size() * 2 < all.size(), "the state holds the forecast window, not every reading");
  const CrusherState full = ComputeCrusherState(c, all), incremental = ComputeCrusherState(c, inputs);
  CHECK_TRUE(full.has_wear);
  CHECK(full.scan != nullptr);
  CHECK(WearJson(full, true) == WearJson(incremental, true));
  if (expect_pruned) {
    // Before the window (the last 48 days and a day): record lows (at most one per loop), an
    // anchor per scan and a reading above the lowest, per sensor.
    const int64_t window_from = Now() - 50 * 86400;
    std::map<std::string, size_t> before;
    for (const auto& r : inputs)
      if (r.time_s < window_from) ++before[r.sensor];
    for (const auto& [sensor, n] : before)
      CHECK_TEXT(n <= static_cast<size_t>(c.config.thickness_new_mm) + 4, (sensor + ": " + std::to_string(n)).c_str());
  }
  if (expect_pruned) {  // all readings in: the sensor dead since day 60 is stale, the frozen ones stuck
    CHECK_TEXT(full.stale == std::vector<std::string>{c.config.sensors.at(2).id},
               WearJson(full, false)["sensors_stale"].dump().c_str());
    CHECK_TEXT(full.stuck == (std::vector<std::string>{c.config.sensors.at(7).id, c.config.sensors.at(8).id}),
               WearJson(full, false)["sensors_stuck"].dump().c_str());
    // The one frozen before the scan sets no scale there; the one frozen after it does.
    std::vector<std::string> at_scan;
    for (const auto& w : full.scan->wear_at_scan) at_scan.push_back(w.sensor_id);
    CHECK(std::find(at_scan.begin(), at_scan.end(), c.config.sensors.at(8).id) == at_scan.end());
    CHECK(std::find(at_scan.begin(), at_scan.end(), c.config.sensors.at(7).id) != at_scan.end());
  }
  CHECK(ForecastJson(full) == ForecastJson(incremental));
  CHECK(live.LatestUsableTime(Folder().id()) == full.time.time_since_epoch().count());
  LONGS_EQUAL(store.CountReadings(Folder().id()), live.CountReadings(Folder().id()));
  const auto a = store.LatestPerSensor(Folder().id()), b = live.LatestPerSensor(Folder().id());
  LONGS_EQUAL(a.size(), b.size());
  for (size_t i = 0; i < a.size() && i < b.size(); ++i) {
    STRCMP_EQUAL(a[i].latest.sensor.c_str(), b[i].latest.sensor.c_str());
    LONGS_EQUAL(a[i].count, b[i].count);
    LONGS_EQUAL(a[i].latest.seq, b[i].latest.seq);
    LONGS_EQUAL(a[i].latest.time_s, b[i].latest.time_s);
    DOUBLES_EQUAL(a[i].latest.thickness_mm, b[i].latest.thickness_mm, 0);
    LONGS_EQUAL(a[i].latest.flags, b[i].latest.flags);
    LONGS_EQUAL(a[i].latest.loops_intact, b[i].latest.loops_intact);
    LONGS_EQUAL(a[i].latest.battery_mv, b[i].latest.battery_mv);
    LONGS_EQUAL(a[i].latest.received_s, b[i].latest.received_s);
  }
}

}  // namespace

TEST_GROUP(LiveState){};

TEST(LiveState, EqualsAFullRecomputeAfterIngestAfterARestartAndAfterMore) {
  lw::test::TempDirectory dir{"lw-live"};
  std::vector<std::string> errors;
  const auto registry = Registry::Load(Folder().crushers, &errors);
  const Crusher& c = *registry->Find(Folder().id());
  const auto messages = Messages();
  const size_t half = messages.size() / 2;
  {
    Store store(dir.File("db.sqlite"));
    LiveState live(*registry);
    live.Rebuild(store);  // an empty database
    LONGS_EQUAL(0, live.CountReadings(Folder().id()));
    CHECK_FALSE(live.LatestUsableTime(Folder().id()));
    CHECK_TRUE(live.WearInputs(Folder().id()).empty());
    Ingestor ingestor(
        store, *registry, [] { return Now(); }, &live);
    for (size_t i = 0; i < half; i += 97) {
      ingestor.Ingest({messages.begin() + static_cast<std::ptrdiff_t>(i),
                       messages.begin() + static_cast<std::ptrdiff_t>(std::min(half, i + 97))});
    }
    // Redelivered: duplicates change nothing.
    ingestor.Ingest({messages.begin(), messages.begin() + 50});
    CheckEqualsFullRecompute(c, live, store, false);
  }
  // Restart: rebuilt once from the store, then kept up to date by the rest of the campaign.
  Store store(dir.File("db.sqlite"));
  LiveState live(*registry);
  live.Rebuild(store);
  CheckEqualsFullRecompute(c, live, store, false);
  Ingestor ingestor(
      store, *registry, [] { return Now(); }, &live);
  for (size_t i = half; i < messages.size(); i += 211) {
    ingestor.Ingest({messages.begin() + static_cast<std::ptrdiff_t>(i),
                     messages.begin() + static_cast<std::ptrdiff_t>(std::min(messages.size(), i + 211))});
  }
  CheckEqualsFullRecompute(c, live, store, true);
  LiveState rebuilt(*registry);
  rebuilt.Rebuild(store);
  CheckEqualsFullRecompute(c, rebuilt, store, true);
}

// The service computes from the state: what it serves after ingest is the full recompute.
TEST(LiveState, WearServiceServesTheFullRecompute) {
  lw::test::TempDirectory dir{"lw-live"};
  std::vector<std::string> errors;
  const auto registry = Registry::Load(Folder().crushers, &errors);
  Store store(dir.File("db.sqlite"));
  LiveState live(*registry);
  live.Rebuild(store);
  Ingestor ingestor(
      store, *registry, [] { return Now(); }, &live);
  WearService wear(*registry, live);
  CHECK_FALSE(wear.Get(Folder().id())->has_wear);
  ingestor.Ingest(Messages());
  wear.MarkChanged(Folder().id());
  const Crusher& c = *registry->Find(Folder().id());
  const CrusherState full = ComputeCrusherState(c, store.All(Folder().id()));
  CHECK(WearJson(full, false) == WearJson(*wear.Get(Folder().id()), false));
  CHECK(ForecastJson(full) == ForecastJson(*wear.Latest(Folder().id())));
  CHECK(wear.Get("no-such-crusher") == nullptr);
}

// Loaded lazily (as the server does: it answers while the states load): readings committed before
// the crusher's first use are read from the database, those after it are added, none twice.
TEST(LiveState, ALazyLoadCountsEveryCommitOnce) {
  lw::test::TempDirectory dir{"lw-live"};
  std::vector<std::string> errors;
  const auto registry = Registry::Load(Folder().crushers, &errors);
  const Crusher& c = *registry->Find(Folder().id());
  const auto messages = Messages();
  const size_t third = messages.size() / 3;
  {
    Store store(dir.File("db.sqlite"));
    Ingestor ingestor(store, *registry, [] { return Now(); });
    ingestor.Ingest({messages.begin(), messages.begin() + static_cast<std::ptrdiff_t>(third)});
  }
  Store store(dir.File("db.sqlite"));
  LiveState live(*registry);
  live.LoadLazily(std::make_unique<Store>(dir.File("db.sqlite")));
  Ingestor ingestor(
      store, *registry, [] { return Now(); }, &live);
  // Committed before the crusher was first asked for: not added, read at its load.
  ingestor.Ingest(
      {messages.begin() + static_cast<std::ptrdiff_t>(third), messages.begin() + static_cast<std::ptrdiff_t>(2 * third)});
  LONGS_EQUAL(store.CountReadings(Folder().id()), live.CountReadings(Folder().id()));
  ingestor.Ingest({messages.begin() + static_cast<std::ptrdiff_t>(2 * third), messages.end()});
  CheckEqualsFullRecompute(c, live, store, true);
}

// A reline: the new liner's sensors keep their ids (and continue their seqs), and the operator moves
// installed_at to its installation and restarts. The previous liner's readings (ending half a day
// before, in the day of clock slack) stay in the database and its history (counts, latest per
// sensor) but are no part of this liner's live state:
// wear and forecast equal those of the new liner's readings alone, at the restart, after ingest and
// after another restart. A sensor silent since the reline is neither stale nor worn to its old value.
TEST(LiveState, AfterARelineThePreviousLinersReadingsAreHistoryOnly) {
  static lw::test::CrusherFolder f(15, 11, 10);  // the new liner: 15 days, a scan on day 10
  lw::test::TempDirectory dir{"lw-live"};
  const lw::core::TimePoint installed = f.bundle.crusher.installed_at;
  const double back = 15.5;  // days: the previous liner's 15 days end half a day before the reline
  // The previous liner's folder: the same crusher installed `back` days earlier.
  const std::string previous = dir.File("previous");
  std::filesystem::copy(f.crushers, previous, std::filesystem::copy_options::recursive);
  json cj = json::parse(std::ifstream(previous + "/demo/crusher.json"));
  cj["installed_at"] = lw::core::FormatIsoTime(lw::core::AddDays(installed, -back));
  std::ofstream(previous + "/demo/crusher.json") << cj.dump(2);
  // Each liner's readings as messages: the previous one's shifted back and 60 mm thinner (a liner
  // near its end), the new one's seqs continuing after it.
  const std::string silent = f.bundle.crusher.sensors.at(4).id;  // not heard since the reline
  auto liner = [&](double shift_days, int64_t seq_from) {
    auto out = lw::test::Messages(f.bundle);
    std::erase_if(out, [&](const Incoming& m) { return shift_days == 0 && m.sensor == silent; });
    for (Incoming& m : out) {
      json j = json::parse(m.payload);
      const auto t = lw::core::ParseIsoTime(j["time"].get<std::string>()).value();
      j["time"] = lw::core::FormatIsoTime(lw::core::AddDays(t, shift_days));
      j["seq"] = j["seq"].get<int64_t>() + seq_from;
      if (shift_days != 0) {
        j["thickness_mm"] = j["thickness_mm"].get<double>() - 60;
        j["loops_intact"] = j["loops_intact"].get<int>() - 60;
      }
      m.payload = j.dump();
    }
    return out;
  };
  const int64_t end = lw::test::LatestReadingS(f.bundle) + 3600;
  std::vector<std::string> errors;
  const auto old_registry = Registry::Load(previous, &errors);
  const auto registry = Registry::Load(f.crushers, &errors);
  const Crusher& c = *registry->Find(f.id());
  Store store(dir.File("db.sqlite"));
  {
    Ingestor ingestor(store, *old_registry, [&] { return end - static_cast<int64_t>(back * 86400); });
    const auto messages = liner(-back, 0);
    LONGS_EQUAL(messages.size(), ingestor.Ingest(messages).stored);
  }
  const int64_t history = store.CountReadings(f.id());
  auto check = [&](const LiveState& live) {
    std::vector<StoredReading> mine = store.All(f.id());  // the new liner's: seqs from 100000
    std::erase_if(mine, [&](const StoredReading& r) { return r.seq < 100000; });
    const auto inputs = live.WearInputs(f.id());
    for (const auto& r : inputs) CHECK_TRUE(r.seq >= 100000);
    const CrusherState own = ComputeCrusherState(c, mine), full = ComputeCrusherState(c, store.All(f.id())),
                       incremental = ComputeCrusherState(c, inputs);
    CHECK(WearJson(own, true) == WearJson(full, true));
    CHECK(WearJson(own, true) == WearJson(incremental, true));
    CHECK(ForecastJson(own) == ForecastJson(full));
    CHECK(ForecastJson(own) == ForecastJson(incremental));
    CHECK_TRUE(full.stale.empty());
    LONGS_EQUAL(store.CountReadings(f.id()), live.CountReadings(f.id()));  // the history is kept
    if (mine.empty())
      CHECK_FALSE(live.LatestUsableTime(f.id()));
    else
      CHECK(live.LatestUsableTime(f.id()) == own.time.time_since_epoch().count());
  };
  LiveState live(*registry);
  live.Rebuild(store);  // the restart with the new installed_at
  CHECK_TRUE(live.WearInputs(f.id()).empty());
  CHECK_FALSE(ComputeCrusherState(c, store.All(f.id())).has_wear);
  check(live);
  Ingestor ingestor(
      store, *registry, [&] { return end; }, &live);
  ingestor.Ingest(liner(0, 100000));
  CHECK_TRUE(store.CountReadings(f.id()) > history);
  check(live);
  LiveState rebuilt(*registry);
  rebuilt.Rebuild(store);
  check(rebuilt);
}
