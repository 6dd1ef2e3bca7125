// linerwatch-sim run end to end: a generated 20-day campaign through the real firmware on virtual
// boards, 20 % radio loss and duplicates, into the real linerwatch-gateway (virtual clock file)
// and a real mosquitto on 127.0.0.1; the test plays the server (subscribes to readings, publishes
// `committed` acks). Every reading of the simulator's ledger must arrive at least once with its
// exact time and thickness, and the run's bundle must load as a campaign bundle.
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <mqtt/async_client.h>
#include <nlohmann/json.hpp>

#include "core/bundle.hpp"
#include "support/mosquitto_fixture.hpp"

// CppUTest last: its new/delete macros break standard headers included after it.
#include <CppUTest/TestHarness.h>

using nlohmann::json;

namespace {

constexpr const char* kRoot = "linerwatch/v1/s1/sim-62-75/";

void SleepMs(int ms) {
  std::this_thread::sleep_for(std::chrono::milliseconds(ms));
}

// The server's part: every reading is noted (sensor, seq) -> (time, thickness) and acked.
class TestServer {
 public:
  explicit TestServer(const std::string& uri) : client_(uri, "lw-it-sim-server", nullptr) {
    client_.start_consuming();
    mqtt::connect_options opts;
    opts.set_clean_session(true);
    // Up to 60 s each, returning at the answer: a subscribe before the connect is done throws.
    client_.connect(opts)->wait_for(std::chrono::seconds(60));
    client_.subscribe(std::string(kRoot) + "sensors/+/reading", 1)->wait_for(std::chrono::seconds(60));
    thread_ = std::thread([this] { Run(); });
  }
  ~TestServer() {
    stop_ = true;
    thread_.join();
    try {
      client_.disconnect()->wait_for(std::chrono::seconds(2));
    } catch (const std::exception&) {
    }
  }
  std::map<std::pair<std::string, uint32_t>, std::pair<std::string, double>> Readings() {
    std::lock_guard<std::mutex> lock(mutex_);
    return readings_;
  }

 private:
  void Run() {
    while (!stop_) {
      mqtt::const_message_ptr msg;
      if (!client_.try_consume_message_for(&msg, std::chrono::milliseconds(50)) || !msg) continue;
      const json j = json::parse(msg->to_string(), nullptr, false);
      if (j.is_discarded()) continue;
      const std::string sensor = j.value("sensor", "");
      const uint32_t seq = j.value("seq", 0u);
      {
        std::lock_guard<std::mutex> lock(mutex_);
        readings_.emplace(std::make_pair(sensor, seq), std::make_pair(j.value("time", ""), j.value("thickness_mm", -1.0)));
      }
      const json ack = {{"sensor", sensor}, {"seqs", {seq}}, {"time", j.value("time", "")}};
      try {
        client_.publish(std::string(kRoot) + "sensors/" + sensor + "/committed", ack.dump(), 1, false);
      } catch (const std::exception&) {
      }
    }
  }
  mqtt::async_client client_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::mutex mutex_;
  std::map<std::pair<std::string, uint32_t>, std::pair<std::string, double>> readings_;
};

struct LedgerRow {
  std::string sensor;
  uint32_t seq;
  std::string time;
  double thickness_mm;
};

std::vector<LedgerRow> ReadLedger(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  CHECK_EQUAL(std::string("sensor_id,seq,time,thickness_mm"), line);
  std::vector<LedgerRow> rows;
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::string f[4];
    for (auto& x : f) std::getline(ss, x, ',');
    rows.push_back({f[0], static_cast<uint32_t>(std::stoul(f[1])), f[2], std::stod(f[3])});
  }
  return rows;
}

// One run: a generated campaign of `days` through linerwatch-sim run (`sim_extra` added to its
// flags) into the real gateway; checks that every ledger reading reached the test server with its
// exact time and thickness, and returns the ledger (the logs stay in `dir`).
std::vector<LedgerRow> RunSite(lw::test::TempDirectory& dir, const std::string& days, const std::vector<std::string>& sim_extra) {
  const std::string crushers = dir.File("crushers");
  ::mkdir(crushers.c_str(), 0755);
  LONGS_EQUAL(0, lw::test::RunCommand(
                     {LW_SIM_BIN, "campaign", "--out", crushers + "/sim-62-75", "--days", days, "--no-scan", "--seed", "3"},
                     dir.File("campaign.log")));
  lw::test::MosquittoFixture broker;
  broker.Start();
  TestServer server(broker.uri());

  lw::test::ChildProcess sim;
  std::vector<std::string> sim_args{LW_SIM_BIN,      "run",
                                    "--crusher-dir", crushers,
                                    "--serial-out",  dir.File("tty"),
                                    "--days",        days,
                                    "--api-mode",    "2",
                                    "--clock-out",   dir.File("clock"),
                                    "--ledger",      dir.File("ledger.csv"),
                                    "--bundle-out",  dir.File("bundle"),
                                    "--seed",        "3"};
  sim_args.insert(sim_args.end(), sim_extra.begin(), sim_extra.end());
  sim.Start(sim_args, dir.File("sim.log"));
  struct stat st {};
  // Up to 60 s: the simulator loads the crusher folder and builds its boards before the pty exists.
  for (int i = 0; i < 600 && ::lstat(dir.File("tty").c_str(), &st) != 0; ++i) SleepMs(100);
  CHECK_TEXT(::lstat(dir.File("tty").c_str(), &st) == 0, lw::test::FileTail(dir.File("sim.log")).c_str());

  lw::test::ChildProcess gateway;
  gateway.Start({LW_GATEWAY_BIN, "--serial", dir.File("tty"), "--api-mode", "2", "--broker", broker.uri(), "--site", "s1",
                 "--crusher", "sim-62-75", "--spool", dir.File("spool.db"), "--clock-file", dir.File("clock"), "--gateway-id",
                 "gw-it-sim", "--republish-after", "1"},
                dir.File("gateway.log"));
  const int sim_exit = sim.Wait(std::chrono::seconds(80));
  CHECK_EQUAL_TEXT(0, sim_exit, lw::test::FileTail(dir.File("sim.log")).c_str());

  const std::vector<LedgerRow> ledger = ReadLedger(dir.File("ledger.csv"));
  // The gateway publishes one unconfirmed record per sensor at a time: let it finish (up to 120 s,
  // each record an fsynced spool commit, slow on a loaded machine; a lost record still fails below).
  std::map<std::pair<std::string, uint32_t>, std::pair<std::string, double>> got;
  for (int i = 0; i < 1200; ++i) {
    got = server.Readings();
    if (got.size() >= ledger.size()) break;
    SleepMs(100);
  }
  size_t missing = 0, wrong = 0;
  std::string first_problem;
  for (const LedgerRow& r : ledger) {
    auto it = got.find({r.sensor, r.seq});
    if (it == got.end()) {
      if (missing++ == 0 && first_problem.empty()) first_problem = "missing " + r.sensor + "/" + std::to_string(r.seq);
      continue;
    }
    if (it->second.first != r.time || it->second.second != r.thickness_mm) {
      if (wrong++ == 0 && first_problem.empty()) {
        first_problem = r.sensor + "/" + std::to_string(r.seq) + ": ledger " + r.time + " " + std::to_string(r.thickness_mm) +
                        ", server " + it->second.first + " " + std::to_string(it->second.second);
      }
    }
  }
  CHECK_EQUAL_TEXT(0u, missing, first_problem.c_str());
  CHECK_EQUAL_TEXT(0u, wrong, first_problem.c_str());
  CHECK_EQUAL(ledger.size(), got.size());  // nothing the sensors did not produce
  gateway.Stop(SIGTERM);
  return ledger;
}

}  // namespace

TEST_GROUP(SimRun){};

TEST(SimRun, EveryLedgerReadingReachesTheServerWithItsTimeAndThicknessThrough20PercentLoss) {
  lw::test::TempDirectory dir("lw-it-sim");
  const std::vector<LedgerRow> ledger = RunSite(dir, "20", {"--loss", "0.2", "--dup", "0.05"});
  CHECK(ledger.size() > 10 * 20 * 4);  // ten sensors, 20 days, at least the 6-hourly heartbeats

  // The simulator's log shows the radio lost and duplicated packets on the way.
  const std::string log = lw::test::FileTail(dir.File("sim.log"), 100000);
  const size_t last_day = log.rfind("day 20.0/20.0");
  CHECK_TEXT(last_day != std::string::npos, log.c_str());
  const std::string last_line = log.substr(last_day, log.find('\n', last_day) - last_day);
  CHECK_TEXT(last_line.find(" 0 lost") == std::string::npos && last_line.find(" 0 duplicated") == std::string::npos,
             last_line.c_str());

  // The run's bundle is a campaign bundle with one line per ledger reading.
  const lw::core::Bundle bundle = lw::core::LoadBundle(dir.File("bundle"));
  CHECK_EQUAL(ledger.size(), bundle.readings.size());
  CHECK_EQUAL(10u, bundle.crusher.sensors.size());
  CHECK(!bundle.operations.empty());
}

// The radio as it is: every virtual radio answers NP 49 with EE=1 (APS security and a smaller
// link) and refuses any frame above 49 bytes. The firmware and the gateway size their frames to
// it, so every reading still arrives and no frame was refused.
TEST(SimRun, EveryReadingArrivesWhenTheRadiosCarry49Bytes) {
  lw::test::TempDirectory dir("lw-it-sim-np");
  const std::vector<LedgerRow> ledger = RunSite(dir, "8", {"--loss", "0.1", "--radio-np", "49", "--radio-ee", "1"});
  CHECK(ledger.size() > 10 * 8 * 4);
  const std::string sim_log = lw::test::FileTail(dir.File("sim.log"), 100000);
  CHECK_TEXT(sim_log.find("frames refused as too large: 0 from boards, 0 acks") != std::string::npos, sim_log.c_str());
  const std::string gateway_log = lw::test::FileTail(dir.File("gateway.log"), 100000);
  CHECK_TEXT(gateway_log.find("coordinator NP 49, EE 1: RF payloads of at most 49 bytes") != std::string::npos,
             gateway_log.c_str());
}
