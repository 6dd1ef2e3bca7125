// Issue 16 benchmark (gateway): recorded coordinator frames replayed as fast as they go through the
// real serial path (a pty) into the real linerwatch-gateway, its SQLite spool and a real mosquitto
// on 127.0.0.1, against the same bytes pushed through the same pty by `cat` with a bare reader on
// the other side, in one run.
//
// The frames are 0x90 receive packets carrying readings payloads, made with the protocol library
// (S sensors, R records per frame, every sensor's seqs 1, 2, 3, ...), written once to a file. Both
// runs write that file into the pty master with `cat`:
//   (a) bare: this program reads the slave until every byte has arrived;
//   (b) gateway: the gateway reads the slave, spools every record (fsynced) and acks it to its
//       sensor (0x10 frames back through the pty, read here), and publishes it; this program plays
//       the server: it subscribes to the readings and answers with commit acks, one per sensor per
//       batch as linerwatch-server does after a group commit. Run (b) is done twice per repetition,
//       interleaved: with the server-playing side announcing batches in its acks (`"batch": 64`, as
//       linerwatch-server does: the gateway then sends several records of a sensor per reading
//       message, docs/mqtt.md *Batches*) and without (the one-record form, as an older server).
// Run (b) is done when every record was acked on the radio and seen on MQTT, each exactly the set
// sent (nothing lost: counted per (sensor, seq)). After it the gateway's stats must show every
// record spooled and the spool drained by the commit acks.
//   lw_bench_gateway_replay [--frames N] [--sensors S] [--records-per-frame 1|2] [--window W] [--reps K]
//                           [--gateway-bin PATH] [--baseline-bin PATH] [--forms both|one|batch]
//                           [--broker-nodelay 0|1] [--broker-inflight N]
//   (defaults 20000, 100, 2, 1, 3, the linerwatch-gateway of this build, no baseline, both forms;
//   --baseline-bin runs another gateway build in the same forms, interleaved with this one in every
//   repetition, and prints the ratios of the two builds side by side; the bare run is repeated K
//   times around the gateway runs; the broker as packaging/mosquitto/central.conf sets it: TCP_NODELAY,
//   no in-flight limit, 100000 queued messages). Besides the rates it prints the CPU time of each party of the
//   gateway run (the gateway, mosquitto, and this process's server-playing MQTT client), so that
//   it shows which one the run waited for.
#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <map>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <ctime>
#include <vector>

#include <mqtt/async_client.h>
#include <nlohmann/json.hpp>

#include "mqtt/messages.hpp"
#include "mqtt/paho_link.hpp"
#include "protocol/frame_decoder.hpp"
#include "protocol/sensor_payload.hpp"
#include "protocol/xbee_api.hpp"
#include "support/mosquitto_fixture.hpp"
#include "support/raw_pty.hpp"
#include "../bench_stats.hpp"

extern char** environ;

namespace pr = lw::protocol;
using nlohmann::json;

namespace {

using lw::bench::Median;

using Clock = std::chrono::steady_clock;
double Seconds(Clock::duration d) {
  return std::chrono::duration<double>(d).count();
}
constexpr const char* kRoot = "linerwatch/v1/bench/c1/";

struct Options {
  size_t frames = 20000;
  uint32_t sensors = 100;
  size_t per_frame = 2;
  int window = 1;
  int reps = 3;
  bool nodelay = true;  ///< the broker's set_tcp_nodelay (as packaging/mosquitto/*.conf set it)
  /// The broker's max_inflight_messages: 0 (no limit) as packaging/mosquitto/*.conf set it;
  /// mosquitto's default is 20 QoS 1 messages awaiting a PUBACK per client.
  long broker_inflight = 0;
  std::string gateway_bin = LW_GATEWAY_BIN;
  /// Another gateway build run interleaved with gateway_bin, same runs (empty: none).
  std::string baseline_bin;
  bool one_record = true;  ///< run the one-record form (the server-playing side announces nothing)
  bool batches = true;     ///< run with batches announced
};

uint32_t SensorId(uint32_t s) {
  return 1001 + s;
}
uint64_t Address(uint32_t s) {
  return 0x0013A20040000000ull + s;
}

/// The replay file: frame f comes from sensor f % S and carries that sensor's next R seqs.
std::string MakeFrames(const Options& o, const std::string& path, size_t* records) {
  std::string bytes;
  std::vector<uint32_t> next(o.sensors, 1);
  *records = 0;
  for (size_t f = 0; f < o.frames; ++f) {
    const uint32_t s = static_cast<uint32_t>(f % o.sensors);
    pr::ReadingsHeader h;
    h.sensor_id = SensorId(s);
    h.ladder_loops = 100;
    pr::SensorRecord recs[2];
    for (size_t i = 0; i < o.per_frame; ++i) {
      const uint32_t seq = next[s]++;
      recs[i].seq = seq;
      recs[i].age_s = 0;
      recs[i].loops_intact = static_cast<uint8_t>(100 - (seq / 50) % 100);
      recs[i].thickness_dmm = static_cast<uint16_t>(recs[i].loops_intact * 10);
      recs[i].flags = seq % 4 == 0 ? 0 : pr::kFlagHeartbeat;
      recs[i].battery_mv = 3600;
      recs[i].temperature_c = 31;
      for (uint8_t l = 0; l < recs[i].loops_intact; ++l) recs[i].loop_bitmap[l / 8] |= static_cast<uint8_t>(1u << (l % 8));
    }
    uint8_t payload[pr::kMaxRfPayload];
    size_t payload_len = 0;
    if (pr::EncodeReadings(h, recs, o.per_frame, payload, sizeof payload, &payload_len) != pr::PayloadStatus::kOk) {
      throw std::runtime_error("EncodeReadings failed (records per frame too many for 100 loops?)");
    }
    const pr::ReceivePacket rx{Address(s), static_cast<uint16_t>(0x2000 + s), 0x01, payload, payload_len};
    uint8_t wire[pr::kMaxWireFrame];
    const size_t wire_len = pr::EncodeReceivePacket(pr::ApiMode::kEscaped, rx, wire, sizeof wire);
    if (wire_len == 0) throw std::runtime_error("EncodeReceivePacket failed");
    bytes.append(reinterpret_cast<const char*>(wire), wire_len);
    *records += o.per_frame;
  }
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f || std::fwrite(bytes.data(), 1, bytes.size(), f) != bytes.size() || std::fclose(f) != 0)
    throw std::runtime_error("cannot write " + path);
  return bytes;
}

/// `cat file` with its standard output on `fd` (the pty master).
/// The master is non-blocking for this process's reads; cat needs blocking writes (the same open
/// file description), so the flag is cleared for the whole run and reads below follow a poll.
pid_t SpawnCat(const std::string& file, int fd) {
  fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, fd, 1);
  std::vector<char*> argv = {const_cast<char*>("cat"), const_cast<char*>(file.c_str()), nullptr};
  pid_t pid = -1;
  if (posix_spawnp(&pid, "cat", &fa, nullptr, argv.data(), environ) != 0) throw std::runtime_error("cannot run cat");
  posix_spawn_file_actions_destroy(&fa);
  return pid;
}

void Reap(pid_t pid) {
  int status = 0;
  waitpid(pid, &status, 0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) throw std::runtime_error("cat failed");
}

/// (a) The same bytes through `cat` into a pty, read back on the slave by this process.
double BareRun(const std::string& file, size_t total_bytes) {
  lw::test::RawPty pty;
  const int slave = open(pty.slave_name().c_str(), O_RDONLY | O_NOCTTY);
  if (slave < 0) throw std::runtime_error("cannot open the pty slave");
  std::vector<char> buf(1 << 16);
  const auto t0 = Clock::now();
  const pid_t cat = SpawnCat(file, pty.master());
  size_t got = 0;
  while (got < total_bytes) {
    const ssize_t n = read(slave, buf.data(), buf.size());
    if (n <= 0) throw std::runtime_error("pty read failed");
    got += static_cast<size_t>(n);
  }
  const double s = Seconds(Clock::now() - t0);
  Reap(cat);
  close(slave);
  return s;
}

/// The server's part: records every reading, answers with commit acks grouped per sensor (what a
/// server's group commit sends), watches the gateway's status and stats.
class FakeServer {
 public:
  /// `batch`: announced in every commit ack (0: not announced, the one-record form only).
  FakeServer(const std::string& uri, uint32_t batch) : client_(uri, "lw-bench-server", nullptr), batch_(batch) {
    client_.start_consuming();
    mqtt::connect_options opts;
    opts.set_clean_session(true);
    client_.connect(opts)->wait();
    lw::mqtt::NoDelayOnTcpSockets();  // as linerwatch-server's link does after connecting
    client_.subscribe(std::string(kRoot) + "sensors/+/reading", 1)->wait();
    client_.subscribe(std::string(kRoot) + "gateway/#", 1)->wait();
    thread_ = std::thread([this] { Run(); });
  }
  ~FakeServer() {
    stop_ = true;
    thread_.join();
    try {
      client_.disconnect()->wait_for(std::chrono::seconds(2));
    } catch (const std::exception&) {
    }
  }
  size_t distinct() const { return distinct_.load(); }
  /// CPU seconds of the thread that takes the readings and publishes the acks (Paho's own
  /// threads are in the process's total).
  double thread_cpu_s() const { return thread_cpu_s_.load(); }
  size_t messages() const { return messages_.load(); }
  bool online() const { return online_.load(); }
  json last_stats() {
    std::lock_guard<std::mutex> lock(mutex_);
    return stats_;
  }
  std::set<std::pair<uint32_t, uint32_t>> seen() {
    std::lock_guard<std::mutex> lock(mutex_);
    return seen_;
  }

 private:
  void Run() {
    std::map<std::string, std::vector<uint32_t>> pending;
    while (!stop_) {
      mqtt::const_message_ptr msg;
      // Take what is there (a batch), then ack it.
      const bool got = client_.try_consume_message_for(&msg, std::chrono::milliseconds(pending.empty() ? 20 : 0));
      if (got && msg) {
        Handle(*msg, &pending);
        continue;
      }
      for (auto& [sensor, seqs] : pending) {
        for (std::string& ack : lw::mqtt::EncodeCommitAcks({sensor, seqs, "2026-01-01T00:00:00Z", batch_})) {
          client_.publish(std::string(kRoot) + "sensors/" + sensor + "/committed", std::move(ack), 1, false);
        }
      }
      pending.clear();
      timespec ts{};
      clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
      thread_cpu_s_ = static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) / 1e9;
    }
  }
  void Handle(const mqtt::message& msg, std::map<std::string, std::vector<uint32_t>>* pending) {
    const std::string topic = msg.get_topic();
    if (topic.size() > 8 && topic.compare(topic.size() - 8, 8, "/reading") == 0) {
      // As linerwatch-server: a batch is split into its records, each decoded on its own.
      std::vector<std::string> records;
      std::string error;
      if (!lw::mqtt::SplitReadingMessage(msg.to_string(), &records, &error)) return;
      if (records.empty()) records.push_back(msg.to_string());
      ++messages_;
      for (const std::string& text : records) {
        const auto r = lw::mqtt::DecodeReading(text, &error);
        if (!r) continue;
        {
          std::lock_guard<std::mutex> lock(mutex_);
          if (seen_.insert({static_cast<uint32_t>(std::stoul(r->sensor)), r->seq}).second) ++distinct_;
        }
        (*pending)[r->sensor].push_back(r->seq);
      }
      return;
    }
    const json j = json::parse(msg.to_string(), nullptr, false);
    if (j.is_discarded()) return;
    if (topic == std::string(kRoot) + "gateway/status") {
      online_ = j.value("state", "") == "online";
    } else if (topic == std::string(kRoot) + "gateway/stats") {
      std::lock_guard<std::mutex> lock(mutex_);
      stats_ = j;
    }
  }
  mqtt::async_client client_;
  uint32_t batch_ = 0;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<size_t> distinct_{0}, messages_{0};
  std::atomic<bool> online_{false};
  std::atomic<double> thread_cpu_s_{0};
  std::mutex mutex_;
  std::set<std::pair<uint32_t, uint32_t>> seen_;
  json stats_;
};

struct GatewayResult {
  double seconds = 0;              ///< first byte to every record acked on the radio and seen on MQTT
  double drain_seconds = 0;        ///< to the stats showing the spool empty
  double acked_seconds = 0;        ///< to the last radio ack (every record spooled)
  double gateway_cpu_s = 0;        ///< the gateway process's user + system CPU over the whole run
  double broker_cpu_s = 0;         ///< mosquitto's, over the whole run
  double bench_cpu_s = 0;          ///< this process's (server-playing client with Paho's threads, radio side)
  double server_thread_cpu_s = 0;  ///< of that, the server-playing thread's
  size_t radio_acked = 0, published = 0, messages = 0, spooled = 0;
  bool complete = false;
  std::string failure;
};

double CpuSeconds(pid_t pid);

double SelfCpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec) / 1e6;
}

/// (b) The same bytes through `cat` into the pty, the real gateway on the other side.
GatewayResult GatewayRun(const Options& o, const std::string& gateway_bin, const std::string& file, size_t total_records,
                         uint32_t batch) {
  GatewayResult out;
  lw::test::MosquittoFixture::Options bo;
  if (o.nodelay) bo.extra_config = "set_tcp_nodelay true\n";
  // As packaging/mosquitto/central.conf: the readings and acks of a whole site may be queued.
  bo.extra_config += "max_inflight_messages " + std::to_string(o.broker_inflight) + "\nmax_queued_messages 100000\n";
  lw::test::MosquittoFixture broker(bo);
  broker.Start();
  lw::test::TempDirectory dir("lw-bench-gw");
  lw::test::RawPty pty;
  FakeServer server(broker.uri(), batch);
  lw::test::ChildProcess gateway;
  const std::string log = dir.File("gateway.log");
  gateway.Start({gateway_bin,
                 "--serial",
                 pty.slave_name(),
                 "--baud",
                 "115200",
                 "--api-mode",
                 "2",
                 "--broker",
                 broker.uri(),
                 "--site",
                 "bench",
                 "--crusher",
                 "c1",
                 "--spool",
                 dir.File("spool.db"),
                 "--gateway-id",
                 "gw-bench",
                 "--window",
                 std::to_string(o.window),
                 "--stats-interval",
                 "0.2",
                 "--republish-after",
                 "30"},
                log);
  const auto wait_start = Clock::now();
  while (!server.online()) {
    if (Seconds(Clock::now() - wait_start) > 20) throw std::runtime_error("gateway not online: " + lw::test::FileTail(log));
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  // The radio side: every 0x10 ack the gateway writes back, decoded with the protocol library.
  std::set<std::pair<uint32_t, uint32_t>> acked;
  pr::FrameDecoder decoder(pr::ApiMode::kEscaped);
  std::vector<uint8_t> buf(1 << 16);
  const double self_cpu0 = SelfCpuSeconds(), broker_cpu0 = CpuSeconds(broker.pid()), server_cpu0 = server.thread_cpu_s();
  const auto t0 = Clock::now();
  const pid_t cat = SpawnCat(file, pty.master());
  bool cat_done = false;
  for (;;) {
    pollfd p{pty.master(), POLLIN, 0};
    ::poll(&p, 1, 5);
    if (p.revents & POLLIN) {
      const ssize_t n = read(pty.master(), buf.data(), buf.size());
      decoder.Feed(buf.data(), static_cast<size_t>(n), [&](pr::DecodeEvent ev) {
        if (ev != pr::DecodeEvent::kFrame) return;
        pr::TransmitRequest req;
        pr::Ack ack;
        if (pr::ParseTransmitRequest(decoder.frame_data(), decoder.frame_length(), &req) != pr::Status::kOk) return;
        if (pr::DecodeAck(req.payload, req.payload_len, &ack) != pr::PayloadStatus::kOk) return;
        for (uint8_t k = 0; k < ack.count; ++k) acked.insert({ack.sensor_id, ack.seqs[k]});
      });
      if (n > 0) continue;  // drain what is there before checking
    }
    if (!cat_done) {
      int status = 0;
      if (waitpid(cat, &status, WNOHANG) == cat) cat_done = true;
    }
    if (out.acked_seconds == 0 && acked.size() >= total_records) out.acked_seconds = Seconds(Clock::now() - t0);
    if (acked.size() >= total_records && server.distinct() >= total_records) break;
    if (Seconds(Clock::now() - t0) > 600 || !gateway.Running()) {
      out.failure = "stalled at " + std::to_string(acked.size()) + " acked, " + std::to_string(server.distinct()) +
                    " published: " + lw::test::FileTail(log);
      break;
    }
  }
  out.seconds = Seconds(Clock::now() - t0);
  if (!cat_done) Reap(cat);
  // Drained: the stats (every 0.2 s) show every record spooled and none left.
  for (;;) {
    const json st = server.last_stats();
    if (st.is_object() && st.value("records_spooled", 0u) >= total_records && st.value("spool_depth", 1u) == 0) {
      out.spooled = st.value("records_spooled", 0u);
      break;
    }
    if (Seconds(Clock::now() - t0) > out.seconds + 120) {
      out.failure += " spool did not drain: " + st.dump();
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  out.drain_seconds = Seconds(Clock::now() - t0);
  out.radio_acked = acked.size();
  out.published = server.distinct();
  out.messages = server.messages();
  // Nothing lost: exactly the records sent, acked on the radio and seen on MQTT.
  std::set<std::pair<uint32_t, uint32_t>> expected;
  for (uint32_t s = 0; s < o.sensors; ++s) {
    const size_t frames_of_s = o.frames / o.sensors + (s < o.frames % o.sensors ? 1 : 0);
    for (uint32_t q = 1; q <= frames_of_s * o.per_frame; ++q) expected.insert({SensorId(s), q});
  }
  out.gateway_cpu_s = CpuSeconds(gateway.pid());
  out.broker_cpu_s = CpuSeconds(broker.pid()) - broker_cpu0;
  out.bench_cpu_s = SelfCpuSeconds() - self_cpu0;
  out.server_thread_cpu_s = server.thread_cpu_s() - server_cpu0;
  out.complete = out.failure.empty() && acked == expected && server.seen() == expected && out.spooled == total_records;
  gateway.Stop(SIGTERM);
  return out;
}

/// User + system CPU seconds of a running process (/proc/PID/stat fields 14 and 15).
double CpuSeconds(pid_t pid) {
  FILE* f = std::fopen(("/proc/" + std::to_string(pid) + "/stat").c_str(), "r");
  if (!f) return -1;
  char line[2048] = {};
  const size_t n = std::fread(line, 1, sizeof line - 1, f);
  std::fclose(f);
  line[n] = 0;
  const char* p = std::strrchr(line, ')');  // the command name may hold spaces
  unsigned long utime = 0, stime = 0;
  if (!p || std::sscanf(p + 2, "%*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %lu %lu", &utime, &stime) != 2) return -1;
  return static_cast<double>(utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  const char* const kUsage =
      "usage: lw_bench_gateway_replay [--frames N] [--sensors S] [--records-per-frame 1|2] [--window W] [--reps K] "
      "[--gateway-bin PATH] [--baseline-bin PATH] [--forms both|one|batch] [--broker-nodelay 0|1] [--broker-inflight N]\n";
  if (argc == 2 && !std::strcmp(argv[1], "--help")) {
    std::fputs(kUsage, stdout);
    std::fputs(
        "Recorded coordinator frames replayed through a pty into the real linerwatch-gateway, its SQLite spool and a "
        "real mosquitto, against the same bytes through the same pty to a bare reader, interleaved in one run; prints "
        "the throughputs and their ratio (bench/gateway/RESULTS.md).\n",
        stdout);
    return 0;
  }
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    const std::string value = argv[i + 1];
    const long v = std::atol(argv[i + 1]);
    if (a == "--gateway-bin")
      o.gateway_bin = value;
    else if (a == "--baseline-bin")
      o.baseline_bin = value;
    else if (a == "--forms" && (value == "both" || value == "one" || value == "batch")) {
      o.one_record = value != "batch";
      o.batches = value != "one";
    } else if (a == "--frames" && v > 0)
      o.frames = static_cast<size_t>(v);
    else if (a == "--sensors" && v > 0)
      o.sensors = static_cast<uint32_t>(v);
    else if (a == "--records-per-frame" && (v == 1 || v == 2))
      o.per_frame = static_cast<size_t>(v);
    else if (a == "--window" && v > 0 && v <= 10000)
      o.window = static_cast<int>(v);
    else if (a == "--reps" && v > 0)
      o.reps = static_cast<int>(v);
    else if (a == "--broker-nodelay" && (v == 0 || v == 1))
      o.nodelay = v == 1;
    else if (a == "--broker-inflight" && v >= 0)
      o.broker_inflight = v;
    else {
      std::fprintf(stderr, "lw_bench_gateway_replay: bad option %s %s\n%s", a.c_str(), value.c_str(), kUsage);
      return 2;
    }
  }
  if (argc % 2 == 0) {
    std::fputs(kUsage, stderr);
    return 2;
  }
  try {
    lw::test::TempDirectory dir("lw-bench-replay");
    size_t records = 0;
    const std::string file = dir.File("frames.bin");
    const std::string bytes = MakeFrames(o, file, &records);
    std::printf("replay: %zu frames (%zu records, %u sensors, %zu per frame), %.2f MB, API mode 2\n", o.frames, records,
                o.sensors, o.per_frame, bytes.size() / 1e6);
    // Each variant (a gateway build in a form) is run once per repetition, interleaved.
    struct Variant {
      std::string label, bin;
      bool batches = false;
      std::vector<double> gw, drain, cpu, intake, broker_cpu, bench_cpu, server_cpu;
    };
    std::vector<Variant> variants;
    std::vector<std::pair<std::string, std::string>> builds;
    if (!o.baseline_bin.empty()) builds.emplace_back("baseline", o.baseline_bin);
    builds.emplace_back(o.baseline_bin.empty() ? "" : "this build", o.gateway_bin);
    for (const auto& build : builds) {
      std::printf("gateway%s%s: %s\n", build.first.empty() ? "" : " ", build.first.c_str(), build.second.c_str());
      for (int form = 0; form < 2; ++form) {
        if (form == 0 ? !o.one_record : !o.batches) continue;
        Variant v;
        v.label = std::string(form == 0 ? "one record per message" : "batches of up to 64") +
                  (build.first.empty() ? "" : ", " + build.first);
        v.bin = build.second;
        v.batches = form == 1;
        variants.push_back(std::move(v));
      }
    }
    std::vector<double> bare;
    bool all_complete = true;
    for (int r = 0; r < o.reps; ++r) {
      bare.push_back(BareRun(file, bytes.size()));
      for (Variant& s : variants) {
        const GatewayResult g =
            GatewayRun(o, s.bin, file, records, s.batches ? static_cast<uint32_t>(lw::mqtt::kMaxReadingBatch) : 0);
        s.gw.push_back(g.seconds);
        s.drain.push_back(g.drain_seconds);
        s.cpu.push_back(g.gateway_cpu_s);
        s.intake.push_back(g.acked_seconds);
        s.broker_cpu.push_back(g.broker_cpu_s);
        s.bench_cpu.push_back(g.bench_cpu_s);
        s.server_cpu.push_back(g.server_thread_cpu_s);
        all_complete = all_complete && g.complete;
        std::printf(
            "  rep %d (%s): cat -> pty -> reader %.3f s; cat -> pty -> gateway -> spool + mosquitto %.3f s (all acked on the "
            "radio at %.3f s, drained %.3f s): radio acked %zu, published %zu distinct (%zu messages), spooled %zu; CPU: "
            "gateway %.2f s, mosquitto %.2f s, bench %.2f s (server-playing thread %.2f s)%s%s\n",
            r + 1, s.label.c_str(), bare.back(), g.seconds, g.acked_seconds, g.drain_seconds, g.radio_acked, g.published,
            g.messages, g.spooled, g.gateway_cpu_s, g.broker_cpu_s, g.bench_cpu_s, g.server_thread_cpu_s,
            g.complete ? ", complete" : ", INCOMPLETE ", g.failure.c_str());
        std::fflush(stdout);
      }
    }
    bare.push_back(BareRun(file, bytes.size()));
    const double b = Median(bare);
    std::printf("bare (cat into the pty)         median %.3f s  %10.0f frames/s\n", b, o.frames / b);
    for (const Variant& s : variants) {
      const double g = Median(s.gw);
      std::printf("-- %s --\n", s.label.c_str());
      std::printf("gateway intake (spooled, fsynced, acked on the radio)  median %.3f s  %10.0f frames/s\n", Median(s.intake),
                  o.frames / Median(s.intake));
      std::printf("gateway end to end (spooled + published)   median %.3f s  %10.0f frames/s  (%.0f records/s)\n", g,
                  o.frames / g, records / g);
      std::printf("gateway, spool drained by commit acks: median %.3f s\n", Median(s.drain));
      std::printf("gateway CPU (user + system)     median %.2f s: %.0f frames per CPU-second (the capacity on an idle core)\n",
                  Median(s.cpu), o.frames / Median(s.cpu));
      std::printf("mosquitto CPU                   median %.2f s\n", Median(s.broker_cpu));
      std::printf(
          "bench CPU (server-playing client, Paho threads, radio side)  median %.2f s (server-playing thread %.2f s, "
          "%.0f %% of the end-to-end time)\n",
          Median(s.bench_cpu), Median(s.server_cpu), 100 * Median(s.server_cpu) / g);
      std::printf("ratio gateway / bare frames/s   %.3f\n", b / g);
    }
    // Side by side: the same form of the two builds, and the two forms of one build.
    for (const Variant& x : variants) {
      for (const Variant& y : variants) {
        if (&x == &y) continue;
        const bool same_build = x.bin == y.bin && x.batches && !y.batches;
        const bool same_form = x.batches == y.batches && x.bin == o.gateway_bin && y.bin != o.gateway_bin;
        if (!same_build && !same_form) continue;
        std::printf("end to end, %s / %s: %.2fx the frames/s (intake %.2fx)\n", x.label.c_str(), y.label.c_str(),
                    Median(y.gw) / Median(x.gw), Median(y.intake) / Median(x.intake));
      }
    }
    std::printf("nothing lost (every record acked on the radio, published, spooled): %s\n", all_complete ? "yes" : "NO");
    return all_complete ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lw_bench_gateway_replay: %s\n", e.what());
    return 1;
  }
}
