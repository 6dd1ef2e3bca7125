// End to end through real processes: simulated sensors write coordinator frames into a pty, the
// real linerwatch-gateway reads it, a real mosquitto on a free loopback port carries the messages,
// and the test plays the server (subscribes to readings, publishes commit acks). Mid-stream the
// broker is killed or stopped and restarted (with and without persistence), or the gateway is
// killed with SIGKILL and restarted on the same spool. Every record must arrive, each sensor's
// records first seen in seq order, and the gateway's spool must drain to zero.
#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <termios.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <chrono>
#include <deque>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <mqtt/async_client.h>
#include <nlohmann/json.hpp>

#include "protocol/frame_decoder.hpp"
#include "protocol/sensor_payload.hpp"
#include "protocol/xbee_api.hpp"
#include "support/mosquitto_fixture.hpp"
#include "support/raw_pty.hpp"

// CppUTest last: its new/delete macros break standard headers included after it.
#include <CppUTest/TestHarness.h>

namespace pr = lw::protocol;
using nlohmann::json;

namespace {

int64_t NowMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
void SleepMs(int ms) {
  std::this_thread::sleep_for(std::chrono::milliseconds(ms));
}

constexpr const char* kRoot = "linerwatch/v1/s1/c1/";
constexpr int kSensors = 3;
constexpr uint32_t kRecordsPerSensor = 40;
constexpr int64_t kProducePeriodMs = 40;
constexpr int64_t kRetransmitMs = 300;

// Sensors in the manner of the firmware: a queue of unacked records, the oldest two sent per frame,
// sent again after a timeout until the gateway's ack names them.
class SensorSite {
 public:
  SensorSite() {
    for (int i = 0; i < kSensors; ++i) {
      sensors_.push_back(
          Sensor{1001u + static_cast<uint32_t>(i), 0x0013A20040000000ull + static_cast<uint64_t>(i) * 0x1111, 0, {}, false, 0});
    }
  }
  const std::string& slave_name() const { return pty_.slave_name(); }

  void Tick(int64_t now) {
    ReadAcks();
    for (Sensor& s : sensors_) {
      if (s.produced < kRecordsPerSensor && now >= start_ms_ + static_cast<int64_t>(s.produced) * kProducePeriodMs) {
        s.queue.push_back(++s.produced);
      }
      if (!s.queue.empty() && (!s.awaiting || now - s.last_send_ms >= kRetransmitMs)) Send(s, now);
    }
  }
  void Begin(int64_t now) { start_ms_ = now; }
  bool AllProducedAndAcked() const {
    for (const Sensor& s : sensors_) {
      if (s.produced < kRecordsPerSensor || !s.queue.empty()) return false;
    }
    return true;
  }
  size_t acks() const { return acks_; }

 private:
  struct Sensor {
    uint32_t id;
    uint64_t address;
    uint32_t produced;
    std::deque<uint32_t> queue;
    bool awaiting;
    int64_t last_send_ms;
  };

  void Send(Sensor& s, int64_t now) {
    pr::ReadingsHeader h;
    h.sensor_id = s.id;
    h.ladder_loops = 100;
    pr::SensorRecord recs[2];
    const size_t n = std::min<size_t>(2, s.queue.size());
    for (size_t i = 0; i < n; ++i) {
      recs[i].seq = s.queue[i];
      recs[i].thickness_dmm = static_cast<uint16_t>(1000 - s.queue[i]);
      recs[i].loops_intact = static_cast<uint8_t>(100 - s.queue[i] / 10);
      recs[i].battery_mv = 3600;
      recs[i].flags = (s.queue[i] % 5 == 0) ? pr::kFlagHeartbeat : 0;
    }
    uint8_t payload[pr::kMaxRfPayload];
    size_t payload_len = 0;
    if (pr::EncodeReadings(h, recs, n, payload, sizeof payload, &payload_len) != pr::PayloadStatus::kOk) {
      throw std::runtime_error("EncodeReadings failed");
    }
    const pr::ReceivePacket rx{s.address, static_cast<uint16_t>(0x2000 + s.id), 0x01, payload, payload_len};
    uint8_t wire[pr::kMaxWireFrame];
    const size_t wire_len = pr::EncodeReceivePacket(pr::ApiMode::kEscaped, rx, wire, sizeof wire);
    const ssize_t written = write(pty_.master(), wire, wire_len);
    (void)written;  // a full pty buffer loses the frame: the sensor retransmits, as over radio
    s.awaiting = true;
    s.last_send_ms = now;
  }

  void ReadAcks() {
    uint8_t buf[1024];
    for (;;) {
      const ssize_t n = read(pty_.master(), buf, sizeof buf);
      if (n <= 0) return;
      for (ssize_t i = 0; i < n; ++i) {
        if (decoder_.Feed(buf[i]) != pr::DecodeEvent::kFrame) continue;
        pr::TransmitRequest req;
        pr::Ack ack;
        if (pr::ParseTransmitRequest(decoder_.frame_data(), decoder_.frame_length(), &req) != pr::Status::kOk) continue;
        if (pr::DecodeAck(req.payload, req.payload_len, &ack) != pr::PayloadStatus::kOk) continue;
        ++acks_;
        for (Sensor& s : sensors_) {
          if (s.id != ack.sensor_id || s.address != req.dest64) continue;
          for (uint8_t k = 0; k < ack.count; ++k) {
            for (auto it = s.queue.begin(); it != s.queue.end(); ++it) {
              if (*it == ack.seqs[k]) {
                s.queue.erase(it);
                break;
              }
            }
          }
          s.awaiting = false;
        }
      }
    }
  }

  lw::test::RawPty pty_;  // the coordinator's serial line
  std::vector<Sensor> sensors_;
  pr::FrameDecoder decoder_{pr::ApiMode::kEscaped};
  int64_t start_ms_ = 0;
  size_t acks_ = 0;
};

// The server's part: subscribe to readings, publish a commit ack for each (again for redeliveries),
// watch the gateway's status and stats. Its own thread; reconnects whenever the broker is back.
class TestServer {
 public:
  TestServer(const std::string& uri, std::string ca_file, std::string username, std::string password)
      : client_(uri, "lw-it-server", nullptr),
        ca_file_(std::move(ca_file)),
        username_(std::move(username)),
        password_(std::move(password)) {
    client_.start_consuming();
    thread_ = std::thread([this] { Run(); });
  }
  ~TestServer() {
    stop_ = true;
    thread_.join();
    // Destroying a Paho client while an operation is in flight crashes its C library (a connect:
    // eclipse-paho/paho.mqtt.c#220; seen here as heap corruption on a loaded CI machine): every
    // connect has ended (Run), and the disconnect is waited out to its end too.
    try {
      if (client_.is_connected()) WaitOut(client_.disconnect());
    } catch (const std::exception&) {
    }
  }

  struct View {
    std::map<std::string, std::vector<uint32_t>> arrivals;  // every reading, in arrival order
    std::vector<std::string> statuses;                      // gateway/status states in order
    int64_t last_spool_depth = -1;
    int64_t last_stats_ms = 0;
  };
  View Snapshot() {
    std::lock_guard<std::mutex> lock(mutex_);
    return view_;
  }

 private:
  void Run() {
    while (!stop_) {
      if (!client_.is_connected()) {
        try {
          mqtt::connect_options opts;
          opts.set_clean_session(true);
          opts.set_connect_timeout(1);
          if (!ca_file_.empty()) {
            mqtt::ssl_options ssl;
            ssl.set_trust_store(ca_file_);
            opts.set_ssl(ssl);
          }
          if (!username_.empty()) {
            opts.set_user_name(username_);
            opts.set_password(password_);
          }
          // Each attempt waited out to its end (the connect timeout bounds it; a failure throws):
          // a second connect while one is in flight, or the destructor during one, is what crashes
          // Paho. The same for the subscriptions (a clean session needs them on every connect).
          WaitOut(client_.connect(opts));
          WaitOut(client_.subscribe(std::string(kRoot) + "sensors/+/reading", 1));
          WaitOut(client_.subscribe(std::string(kRoot) + "gateway/#", 1));
        } catch (const std::exception&) {
          SleepMs(100);
          continue;
        }
      }
      mqtt::const_message_ptr msg;
      if (!client_.try_consume_message_for(&msg, std::chrono::milliseconds(50)) || !msg) continue;
      Handle(*msg);
    }
  }

  // Waits until the operation has ended (success, or failure: then wait_for throws). Paho ends every
  // operation (connect and operation timeouts); a minute is a bound only a broken client reaches.
  static void WaitOut(const mqtt::token_ptr& tok) {
    const int64_t until = NowMs() + 60'000;
    while (!tok->wait_for(std::chrono::milliseconds(200))) {
      if (NowMs() > until) throw std::runtime_error("an MQTT operation did not end within a minute");
    }
  }

  void Handle(const mqtt::message& msg) {
    const std::string topic = msg.get_topic();
    json j = json::parse(msg.to_string(), nullptr, false);
    if (j.is_discarded()) return;
    std::lock_guard<std::mutex> lock(mutex_);
    if (topic.size() > 8 && topic.compare(topic.size() - 8, 8, "/reading") == 0) {
      const std::string sensor = j.value("sensor", "");
      const uint32_t seq = j.value("seq", 0u);
      view_.arrivals[sensor].push_back(seq);
      const json ack = {{"sensor", sensor}, {"seqs", {seq}}, {"time", "2026-01-01T00:00:00Z"}};
      try {
        client_.publish(std::string(kRoot) + "sensors/" + sensor + "/committed", ack.dump(), 1, false);
      } catch (const std::exception&) {
        // Lost commit ack: the gateway republishes and we ack again.
      }
    } else if (topic == std::string(kRoot) + "gateway/status") {
      view_.statuses.push_back(j.value("state", ""));
    } else if (topic == std::string(kRoot) + "gateway/stats") {
      view_.last_spool_depth = j.value("spool_depth", -1);
      view_.last_stats_ms = NowMs();
    }
  }

  mqtt::async_client client_;
  std::string ca_file_;
  std::string username_;
  std::string password_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::mutex mutex_;
  View view_;
};

enum class Disruption { kNone, kKillBroker, kStopBroker, kKillGateway };

struct Outcome {
  TestServer::View view;
  bool disrupted_mid_stream = false;
  std::string failure;
  std::string shutdown_failure;  // SIGTERM must end the gateway cleanly with exit status 0
};

size_t Distinct(const TestServer::View& v) {
  size_t n = 0;
  for (const auto& [sensor, seqs] : v.arrivals) n += std::set<uint32_t>(seqs.begin(), seqs.end()).size();
  return n;
}

// The gateway under test: this build's, or the command in LW_GATEWAY_UNDER_TEST (words split on
// spaces; the arm64 build runs its gateway through qemu-user this way).
std::vector<std::string> GatewayCommand() {
  const char* under_test = std::getenv("LW_GATEWAY_UNDER_TEST");
  if (!under_test || !*under_test) return {LW_GATEWAY_BIN};
  std::vector<std::string> words;
  std::istringstream in(under_test);
  for (std::string w; in >> w;) words.push_back(w);
  return words;
}

Outcome RunScenario(bool persistence, Disruption disruption, bool tls_and_login = false) {
  lw::test::MosquittoFixture::Options broker_options;
  broker_options.persistence = persistence;
  if (tls_and_login) {
    broker_options.tls = true;
    broker_options.username = "gw-user";
    broker_options.password = "s3cret pass";
  }
  lw::test::MosquittoFixture broker(broker_options);
  broker.Start();
  lw::test::TempDirectory dir("lw-gateway-it");
  SensorSite site;
  TestServer server(broker.uri(), tls_and_login ? broker.ca_file() : "", broker_options.username, broker_options.password);
  lw::test::ChildProcess gateway;
  std::vector<std::string> args = GatewayCommand();
  args.insert(args.end(), {"--serial",
                           site.slave_name(),
                           "--baud",
                           "115200",
                           "--api-mode",
                           "2",
                           "--broker",
                           broker.uri(),
                           "--site",
                           "s1",
                           "--crusher",
                           "c1",
                           "--spool",
                           dir.File("spool.db"),
                           "--gateway-id",
                           "gw-it",
                           "--republish-after",
                           "1.5",
                           "--stats-interval",
                           "0.3",
                           "--reconnect-min",
                           "0.1",
                           "--reconnect-max",
                           "0.5"});
  if (tls_and_login) {
    args.insert(args.end(),
                {"--tls-ca", broker.ca_file(), "--username", broker_options.username, "--password", broker_options.password});
  }
  const std::string gateway_log = dir.File("gateway.log");
  gateway.Start(args, gateway_log);

  const size_t total = static_cast<size_t>(kSensors) * kRecordsPerSensor;
  Outcome out;
  const int64_t start = NowMs();
  site.Begin(start);
  int64_t disrupted_at = -1;
  bool restored = disruption == Disruption::kNone;
  // A bound only a real failure reaches: the stream takes a few seconds, more on a loaded machine
  // (every record goes through an fsynced spool commit, and a disruption adds a restart).
  const int64_t deadline = start + 120'000;
  for (;;) {
    const int64_t now = NowMs();
    site.Tick(now);
    const TestServer::View v = server.Snapshot();
    const size_t delivered = Distinct(v);
    if (disrupted_at < 0 && disruption != Disruption::kNone && delivered >= total / 3) {
      out.disrupted_mid_stream = delivered < total;
      disrupted_at = now;
      if (disruption == Disruption::kKillBroker) broker.Kill();
      if (disruption == Disruption::kStopBroker) broker.Stop();
      if (disruption == Disruption::kKillGateway) gateway.Kill();
    }
    if (!restored && disrupted_at >= 0 && now - disrupted_at >= 1000) {
      if (disruption == Disruption::kKillGateway) {
        gateway.Start(args, gateway_log);
      } else {
        broker.Start();
      }
      restored = true;
    }
    if (restored && delivered == total && site.AllProducedAndAcked() && v.last_spool_depth == 0 && v.last_stats_ms > now - 200) {
      out.view = v;
      break;
    }
    if (now > deadline) {
      out.view = v;
      out.failure = "timed out: " + std::to_string(delivered) + "/" + std::to_string(total) + " delivered, last spool depth " +
                    std::to_string(v.last_spool_depth) +
                    (site.AllProducedAndAcked() ? "" : ", sensors still hold unacked records") + "\n--- gateway log ---\n" +
                    lw::test::FileTail(gateway_log) + "\n--- mosquitto log ---\n" + lw::test::FileTail(broker.log_file());
      break;
    }
    if (!gateway.Running() && restored) {
      out.view = v;
      out.failure = "gateway exited: " + lw::test::FileTail(gateway_log);
      break;
    }
    SleepMs(5);
  }
  const int status = gateway.Stop(SIGTERM);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    out.shutdown_failure = "gateway did not exit cleanly on SIGTERM (wait status " + std::to_string(status) + "):\n" +
                           lw::test::FileTail(gateway_log);
  }
  if (std::getenv("LW_IT_VERBOSE")) {
    std::fprintf(stderr, "\n[scenario took %lld ms, disruption at +%lld ms]\n%s\n", static_cast<long long>(NowMs() - start),
                 static_cast<long long>(disrupted_at < 0 ? -1 : disrupted_at - start),
                 lw::test::FileTail(gateway_log, 6000).c_str());
  }
  return out;
}

// Every record of every sensor arrived, and each sensor's records were first seen in seq order.
void CheckComplete(const Outcome& out) {
  CHECK_TRUE_TEXT(out.failure.empty(), out.failure.c_str());
  CHECK_TRUE_TEXT(out.shutdown_failure.empty(), out.shutdown_failure.c_str());
  LONGS_EQUAL(kSensors, out.view.arrivals.size());
  for (const auto& [sensor, seqs] : out.view.arrivals) {
    std::vector<uint32_t> first_seen;
    std::set<uint32_t> seen;
    for (uint32_t s : seqs) {
      if (seen.insert(s).second) first_seen.push_back(s);
    }
    LONGS_EQUAL(kRecordsPerSensor, first_seen.size());
    for (size_t i = 0; i < first_seen.size(); ++i) {
      if (first_seen[i] != i + 1) {
        FAIL(("sensor " + sensor + ": record " + std::to_string(first_seen[i]) + " first seen at position " +
              std::to_string(i + 1))
                 .c_str());
      }
    }
  }
}

}  // namespace

TEST_GROUP(GatewayEndToEnd){};

TEST(GatewayEndToEnd, UndisturbedStreamArrivesCompleteAndInOrder) {
  const Outcome out = RunScenario(false, Disruption::kNone);
  CheckComplete(out);
  CHECK_TRUE(!out.view.statuses.empty() && out.view.statuses.back() == "online");
}

TEST(GatewayEndToEnd, BrokerKilledAndRestartedWithoutPersistence) {
  const Outcome out = RunScenario(false, Disruption::kKillBroker);
  CHECK_TRUE(out.disrupted_mid_stream);
  CheckComplete(out);
  // The new broker knew nothing: the retained "online" seen after the restart is the gateway's
  // republication on reconnect.
  size_t online = 0;
  for (const std::string& state : out.view.statuses) online += state == "online";
  CHECK_TEXT(online >= 2, ("statuses seen: " + std::to_string(out.view.statuses.size())).c_str());
}

TEST(GatewayEndToEnd, BrokerStoppedAndRestartedWithPersistence) {
  const Outcome out = RunScenario(true, Disruption::kStopBroker);
  CHECK_TRUE(out.disrupted_mid_stream);
  CheckComplete(out);
}

TEST(GatewayEndToEnd, GatewayKilledWithSigkillAndRestartedOnItsSpool) {
  const Outcome out = RunScenario(false, Disruption::kKillGateway);
  CHECK_TRUE(out.disrupted_mid_stream);
  CheckComplete(out);
  // The last will announced the death; the restarted gateway announced itself again.
  const auto& st = out.view.statuses;
  bool offline_then_online = false;
  for (size_t i = 0; i + 1 < st.size(); ++i) {
    if (st[i] == "offline" && st.back() == "online") offline_then_online = true;
  }
  CHECK_TRUE(offline_then_online);
}

TEST(GatewayEndToEnd, TlsWithLoginAndBrokerKilledMidStream) {
  const Outcome out = RunScenario(false, Disruption::kKillBroker, /*tls_and_login=*/true);
  CHECK_TRUE(out.disrupted_mid_stream);
  CheckComplete(out);
}
