// The wear worker (server/wear_worker.hpp) on the server's own parts: a real SQLite file, the
// demo crusher's 20-day campaign posted through REST on loopback, the worker's own thread.
#include <chrono>
#include <cmath>
#include <regex>
#include <sstream>
#include <string>
#include <thread>

#include "core/time.hpp"
#include "server/wear_worker.hpp"
#include "unit/server/http_fixture.hpp"

#include <CppUTest/TestHarness.h>  // last: its leak-detection macros clash with std headers

using namespace lw::server;

namespace {

lw::test::CrusherFolder& Folder() {
  return lw::test::HttpFolder();
}

std::string Day(double days) {
  const auto t = Folder().bundle.crusher.installed_at +
                 std::chrono::duration_cast<lw::core::TimePoint::duration>(std::chrono::duration<double>(days * 86400.0));
  return lw::core::FormatIsoTime(t);
}

/// The server's parts on a fresh database, with a worker over them (not started).
struct Served {
  lw::test::LiveApi api{Folder().crushers, true};
  lw::test::ServerParts& p = api.parts;
  std::ostringstream log_text;
  lw::core::Logger log{log_text, "test"};
  ServerMetrics metrics{p.db_path};
  WearWorker worker{{*p.registry, *p.live, *p.wear, *p.alarms, *p.ingestor, p.events, metrics, log, p.campaigns.get()},
                    [] { return int64_t{4'000'000'000}; },
                    0};

  /// Records a setting check on the running liner at `time`; returns its opening (NaN: not known).
  double Check(const std::string& time) {
    SettingCheckRequest r;
    r.time = *lw::core::ParseIsoTime(time);
    r.css_mm = 130;
    const auto out = p.campaigns->CheckSetting(Folder().id(), r, "test");
    return out.check.opening_mm.value_or(std::nan(""));
  }
  /// The live wear's opening for the check at `time` (NaN: not known, or no such check).
  double LiveOpening(const std::string& time) {
    for (const lw::core::SettingCheck& c : p.wear->SettingChecks(Folder().id()))
      if (lw::core::FormatIsoTime(c.time) == time) return c.opening_mm;
    return std::nan("");
  }
  /// The stored opening for the check at `time` (NaN: not known).
  double StoredOpening(const std::string& time) {
    Store stored(p.db_path);
    for (const SettingCheckRecord& c : stored.SettingChecks(Folder().id()))
      if (lw::core::FormatIsoSeconds(c.time_s) == time && c.opening_mm) return *c.opening_mm;
    return std::nan("");
  }
  /// Whether the wear the worker computed last counts its setting from the check at `time`, with
  /// its opening known.
  bool CountsFrom(const std::string& time) {
    const auto st = p.wear->Latest(Folder().id());
    return st && st->setting.check && lw::core::FormatIsoTime(st->setting.check->time) == time &&
           std::isfinite(st->setting.check->opening_mm);
  }
  /// Wear recomputes the worker has finished for the crusher (its metrics' counter).
  int Runs() {
    const std::string text = metrics.Render(*p.ingestor, *p.registry, 0, 0);
    int runs = 0;
    const std::regex sample("linerwatch_wear_runs_total\\{crusher=\"" + Folder().id() + "\",result=\"(ok|error)\"\\} ([0-9]+)");
    for (auto it = std::sregex_iterator(text.begin(), text.end(), sample); it != std::sregex_iterator(); ++it)
      runs += std::stoi((*it)[2]);
    return runs;
  }
  /// Waits (at most a minute: a loaded machine) until `done` holds; false when it never did.
  template <typename Done>
  static bool Within(Done done) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::minutes(1);
    while (!done()) {
      if (std::chrono::steady_clock::now() > until) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return true;
  }
  /// Starts the worker and waits for its start-up pass.
  void Start() {
    worker.Start();
    CHECK_TRUE(Within([&] { return !worker.starting()->load(); }));
  }
};

}  // namespace

TEST_GROUP(WearWorker){};

// A check posted while the gateway was offline has no reading of its time: not known. Once those
// readings are committed, the worker estimates it before it computes the crusher's wear: the live
// wear counts from it and the database keeps it.
TEST(WearWorker, ACheckWhoseReadingsArriveLateIsEstimatedWhenTheyAreCommitted) {
  Served s;
  const std::string at = Day(15);
  CHECK_TRUE(std::isnan(s.Check(at)));
  s.Start();
  LONGS_EQUAL(200, s.api.PostReadings(Folder(), lw::test::ServerParts::kWriteToken));
  s.worker.ReadingsChanged({Folder().id()});
  // Estimated before the wear it computes next: that wear's setting counts from the check.
  const bool estimated = Served::Within([&] { return s.CountsFrom(at); });
  s.worker.Stop();  // the log is read once the worker no longer writes it
  CHECK_TEXT(estimated, s.log_text.str().c_str());
  CHECK_TRUE(std::isfinite(s.LiveOpening(at)));
  DOUBLES_EQUAL(s.LiveOpening(at), s.StoredOpening(at), 1e-9);
  CHECK_TEXT(s.log_text.str().find("setting checks estimated") != std::string::npos, s.log_text.str().c_str());
}

// The worker asks again on its own for a check still waiting: readings a gateway committed
// within a try's minute, with no commit after them, still count (no second commit is needed).
TEST(WearWorker, ACheckStillWaitingIsAskedAgainWithoutAnotherCommit) {
  Served s;
  const std::string at = Day(15);
  CHECK_TRUE(std::isnan(s.Check(at)));
  s.Start();
  const int before = s.Runs();
  s.worker.ReadingsChanged({Folder().id()});  // no reading yet: the check waits
  CHECK_TRUE(Served::Within([&] { return s.Runs() > before; }));
  CHECK_TRUE(std::isnan(s.LiveOpening(at)));
  // The readings arrive and the worker is not told: what it waits for, it asks for again, and
  // computes the crusher's wear again, its setting counted from the check.
  LONGS_EQUAL(200, s.api.PostReadings(Folder(), lw::test::ServerParts::kWriteToken));
  const bool estimated = Served::Within([&] { return s.CountsFrom(at); });
  s.worker.Stop();
  CHECK_TEXT(estimated, s.log_text.str().c_str());
  DOUBLES_EQUAL(s.LiveOpening(at), s.StoredOpening(at), 1e-9);
}
