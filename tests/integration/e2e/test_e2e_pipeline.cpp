// The whole pipeline end to end, every part the production program: `linerwatch-sim run` (virtual
// boards running the real firmware, a virtual XBee network with 20 % loss and duplicates, a
// coordinator on a pty) -> `linerwatch-gateway` -> mosquitto (password, persistence) ->
// `linerwatch-server` -> SQLite and the retained global wear. While the shortened campaign runs,
// the gateway and the server are SIGKILLed and the broker is restarted, each at a random virtual
// day (seed printed on failure; LW_E2E_SEED=N repeats a run). Then every reading of the
// simulator's ledger must be stored exactly once with its time and thickness, and the retained
// global wear must equal the Eq. 9 reconstruction computed offline from the ledger.
#include <sys/stat.h>
#include <sys/wait.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <mqtt/async_client.h>
#include <nlohmann/json.hpp>

#include "core/bundle.hpp"
#include "core/reconstruction.hpp"
#include "core/time.hpp"
#include "server/store.hpp"
#include "support/mosquitto_fixture.hpp"
#include "support/pipeline_ledger.hpp"

#include <CppUTest/TestHarness.h>  // last

using nlohmann::json;

namespace {

constexpr int kDays = 25;
constexpr const char* kSite = "e2e-site";
constexpr const char* kUser = "linerwatch-e2e";
constexpr const char* kPassword = "e2e-broker-secret";

void SleepMs(int ms) {
  std::this_thread::sleep_for(std::chrono::milliseconds(ms));
}

int64_t WallMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// A program of the pipeline that the test kills and starts again with the same arguments.
struct Program {
  lw::test::ChildProcess process;
  std::vector<std::string> argv;
  std::string log;
  void Start() { process.Start(argv, log); }
};

}  // namespace

TEST_GROUP(EndToEnd){};

TEST(EndToEnd, LossDuplicatesBrokerRestartAndKilledGatewayAndServerStoreEveryReadingOnceAndWearMatchesOffline) {
  unsigned seed = std::random_device{}();
  if (const char* s = std::getenv("LW_E2E_SEED"); s && *s) seed = static_cast<unsigned>(std::stoul(s));
  const std::string seed_note = "LW_E2E_SEED=" + std::to_string(seed) + ": ";
  std::mt19937 rng(seed);

  lw::test::TempDirectory dir("lw-e2e");
  const std::string crushers = dir.File("crushers");
  ::mkdir(crushers.c_str(), 0755);
  const std::string folder = crushers + "/demo";
  LONGS_EQUAL_TEXT(0,
                   lw::test::RunCommand({LW_SIM_BIN, "campaign", "--out", folder, "--preset", "paper", "--days",
                                         std::to_string(kDays), "--no-scan", "--seed", "7"},
                                        dir.File("campaign.log")),
                   lw::test::FileTail(dir.File("campaign.log")).c_str());
  // The crusher and map as the server reads them (the folder's campaign readings are not used).
  const lw::core::Bundle crusher_folder = lw::core::LoadBundle(folder);
  const std::string crusher = crusher_folder.crusher.crusher_id;
  const std::string root = std::string("linerwatch/v1/") + kSite + "/" + crusher + "/";

  lw::test::MosquittoFixture::Options broker_options;
  broker_options.persistence = true;  // a restart keeps retained messages and persistent sessions
  broker_options.username = kUser;
  broker_options.password = kPassword;
  lw::test::MosquittoFixture broker(broker_options);
  broker.Start();

  const std::string clock = dir.File("clock");
  const std::string db = dir.File("server.sqlite");
  Program server;
  const int http_port = lw::test::FreeLoopbackPort();
  server.log = dir.File("server.log");
  server.argv = {LW_SERVER_BIN,
                 "--broker",
                 broker.uri(),
                 "--db",
                 db,
                 "--http",
                 "127.0.0.1:" + std::to_string(http_port),
                 "--crusher-dir",
                 crushers,
                 "--username",
                 kUser,
                 "--password",
                 kPassword,
                 "--clock-file",
                 clock,
                 "--wear-interval-ms",
                 "200",
                 "--web-dir",
                 ""};
  // Up to 60 s: the server builds each crusher's map model before it listens (seconds on a loaded machine).
  auto wait_for_server = [&] {
    for (int i = 0; i < 1200 && !lw::test::PortAccepts(http_port); ++i) SleepMs(50);
    CHECK_TEXT(lw::test::PortAccepts(http_port), ("server did not come up: " + lw::test::FileTail(server.log)).c_str());
  };
  server.Start();
  wait_for_server();

  Program sim;
  sim.log = dir.File("sim.log");
  const std::string tty = dir.File("tty");
  sim.argv = {LW_SIM_BIN,      "run",
              "--crusher-dir", crushers,
              "--serial-out",  tty,
              "--days",        std::to_string(kDays),
              "--loss",        "0.2",
              "--dup",         "0.05",
              "--api-mode",    "2",
              "--clock-out",   clock,
              "--ledger",      dir.File("ledger.csv"),
              "--bundle-out",  dir.File("bundle"),
              "--seed",        std::to_string(seed % 1000)};
  sim.Start();
  struct stat st {};
  // Up to 60 s: the simulator loads the crusher folder and builds its boards before the pty exists.
  for (int i = 0; i < 600 && ::lstat(tty.c_str(), &st) != 0; ++i) SleepMs(100);
  CHECK_TEXT(::lstat(tty.c_str(), &st) == 0, lw::test::FileTail(sim.log).c_str());

  Program gateway;
  gateway.log = dir.File("gateway.log");
  gateway.argv = {LW_GATEWAY_BIN,
                  "--serial",
                  tty,
                  "--api-mode",
                  "2",
                  "--broker",
                  broker.uri(),
                  "--site",
                  kSite,
                  "--crusher",
                  crusher,
                  "--spool",
                  dir.File("spool.db"),
                  "--clock-file",
                  clock,
                  "--gateway-id",
                  "gw-e2e",
                  "--username",
                  kUser,
                  "--password",
                  kPassword,
                  "--republish-after",
                  "1"};
  gateway.Start();

  // The faults, each at its own random virtual day while the campaign runs. The simulator runs a
  // virtual day in a fraction of a wall second (the whole run takes a few seconds), whatever this
  // loop does: the last fault is at least 10 days before the end (4 before), so that the loop,
  // starved on a loaded machine or sleeping in a fault's down time (up to 1 s), still acts on
  // every fault before the campaign ends.
  std::uniform_real_distribution<double> when(2.0, kDays - 10.0);
  std::vector<std::pair<double, std::string>> faults = {
      {when(rng), "kill gateway"}, {when(rng), "restart broker"}, {when(rng), "kill server"}};
  std::sort(faults.begin(), faults.end());
  std::string done;
  size_t next = 0;
  while (sim.process.Running()) {
    if (next < faults.size() && lw::test::VirtualDay(clock, crusher_folder.crusher.installed_at) >= faults[next].first) {
      const std::string& what = faults[next].second;
      if (what == "kill gateway") {
        gateway.process.Kill();
        SleepMs(static_cast<int>(rng() % 1000));
        gateway.Start();
      } else if (what == "restart broker") {
        broker.Restart();
      } else {
        server.process.Kill();
        SleepMs(static_cast<int>(rng() % 1000));
        server.Start();  // not waited for here: the campaign (and the other faults) go on meanwhile
      }
      done += what + " at day " + std::to_string(faults[next].first) + "; ";
      ++next;
    }
    SleepMs(20);
  }
  const std::string context = seed_note + done;
  LONGS_EQUAL_TEXT(0, WIFEXITED(sim.process.status()) ? WEXITSTATUS(sim.process.status()) : -1,
                   (context + lw::test::FileTail(sim.log)).c_str());
  LONGS_EQUAL_TEXT(faults.size(), next, (context + "the campaign ended before every fault happened").c_str());
  wait_for_server();

  const std::vector<lw::test::Produced> ledger = lw::test::LoadLedger(dir.File("ledger.csv"));
  CHECK_TEXT(ledger.size() > static_cast<size_t>(10 * kDays * 4),
             context.c_str());  // ten sensors, at least the 6-hourly heartbeats
  // The radio lost and duplicated packets on the way (the simulator's last progress line).
  const std::string sim_log = lw::test::FileTail(sim.log, 100000);
  const size_t last_day = sim_log.rfind("linerwatch-sim: day ");
  CHECK_TEXT(last_day != std::string::npos, sim_log.c_str());
  const std::string last_line = sim_log.substr(last_day, sim_log.find('\n', last_day) - last_day);
  CHECK_TEXT(last_line.find(" 0 lost") == std::string::npos && last_line.find(" 0 duplicated") == std::string::npos,
             last_line.c_str());

  // The gateway publishes what the sensors handed over until the server has committed it all.
  long stored = -1;
  for (const int64_t deadline = WallMs() + 60'000; WallMs() < deadline; SleepMs(200)) {
    stored = lw::test::StoredCount(http_port, crusher);
    if (stored >= static_cast<long>(ledger.size())) break;
  }
  LONGS_EQUAL_TEXT(ledger.size(), stored, (context + lw::test::FileTail(gateway.log)).c_str());
  // The server announces batches in its commit acks and the gateway heard it (docs/mqtt.md,
  // *Batches*): from then on a sensor's backlog goes several records per reading message.
  const std::string gateway_log = lw::test::FileTail(gateway.log, 1'000'000);
  CHECK_TEXT(gateway_log.find("mqtt: the server takes up to 64 records per reading message") != std::string::npos,
             lw::test::FileTail(gateway.log).c_str());

  // The retained global wear, as a client that connects now gets it (or the next one, when the
  // server has not yet published the last change), once it is made of each sensor's latest reading.
  const auto last =
      std::max_element(ledger.begin(), ledger.end(), [](const auto& a, const auto& b) { return a.time < b.time; })->time;
  std::map<std::string, std::string> latest;  // sensor -> time of its latest reading
  for (const lw::test::Produced& p : ledger) latest[p.sensor] = std::max(latest[p.sensor], lw::core::FormatIsoTime(p.time));
  auto from_latest_readings = [&latest](const json& w) {
    if (!w.is_object() || !w.contains("readings_used") || w["readings_used"].size() != latest.size()) return false;
    for (const auto& u : w["readings_used"]) {
      const auto it = latest.find(u["sensor"].get<std::string>());
      if (it == latest.end() || u["time"] != it->second) return false;
    }
    return true;
  };
  json wear;
  {
    mqtt::async_client client(broker.uri(), "lw-e2e-observer", nullptr);
    mqtt::connect_options opts;
    opts.set_clean_session(true);
    opts.set_user_name(kUser);
    opts.set_password(kPassword);
    client.start_consuming();
    client.connect(opts)->wait_for(std::chrono::seconds(60));
    client.subscribe(root + "wear", 1)->wait_for(std::chrono::seconds(60));
    // Up to 60 s: a reconstruction on a loaded machine (the server restarted meanwhile) takes seconds.
    for (const int64_t deadline = WallMs() + 60'000; WallMs() < deadline;) {
      mqtt::const_message_ptr msg;
      if (!client.try_consume_message_for(&msg, std::chrono::milliseconds(100)) || !msg) continue;
      wear = json::parse(msg->to_string(), nullptr, false);
      if (from_latest_readings(wear)) break;
    }
    client.disconnect()->wait_for(std::chrono::seconds(2));
  }
  CHECK_TEXT(from_latest_readings(wear), (context + wear.dump()).c_str());
  STRCMP_EQUAL(lw::core::FormatIsoTime(last).c_str(), wear["time"].get<std::string>().c_str());

  LONGS_EQUAL(0, gateway.process.Stop(SIGTERM));
  LONGS_EQUAL_TEXT(0, server.process.Stop(SIGTERM), lw::test::FileTail(server.log).c_str());

  // Stored exactly once: one row per ledger reading, with its time and thickness.
  {
    lw::server::Store store(db);
    const lw::test::LedgerCheck check = lw::test::CompareLedger(ledger, store.All(crusher));
    LONGS_EQUAL_TEXT(ledger.size(), check.stored, context.c_str());
    CHECK_TEXT(check.exactly_once(), (context + check.first_problem).c_str());
  }

  // The retained wear equals Eq. 9 computed offline from the ledger's readings.
  std::vector<lw::core::Reading> readings;
  for (const lw::test::Produced& p : ledger) readings.push_back({p.time, p.sensor, p.thickness_mm, 0});
  const lw::core::Reconstruction offline = lw::core::Reconstruct(crusher_folder.crusher, crusher_folder.map,
                                                                 lw::core::SensorWearAt(crusher_folder.crusher, readings, last));
  STRCMP_EQUAL(crusher_folder.map.sha256.c_str(), wear["map_sha256"].get<std::string>().c_str());
  DOUBLES_EQUAL(offline.min_thickness_mm, wear["min_thickness_mm"].get<double>(), 1e-3);
  LONGS_EQUAL(offline.rows.size(), wear["rows"].size());
  for (size_t r = 0; r < offline.rows.size(); ++r) {
    STRCMP_EQUAL(offline.rows[r].row.c_str(), wear["rows"][r]["row"].get<std::string>().c_str());
    DOUBLES_EQUAL(offline.rows[r].min_thickness_mm, wear["rows"][r]["min_thickness_mm"].get<double>(), 1e-3);
  }
  // The run's bundle (for `linerwatch diagnose`) holds the same readings.
  LONGS_EQUAL(ledger.size(), lw::core::LoadBundle(dir.File("bundle")).readings.size());
}
