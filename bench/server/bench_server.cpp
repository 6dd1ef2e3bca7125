// The REST API at fleet scale (docs/performance.md, *Server REST at fleet scale*; figures and their
// history in bench/server/RESULTS.md). Builds a database of N readings (default 10,000,000: 100
// crushers x 10 sensors, one reading per sensor per hour) through the server's own Store::Commit,
// starts the real linerwatch-server on it, and prints in one run p50/p99 of
//   a one-day readings query, the crusher list, a crusher's detail, its sensors, wear and forecast,
// over one kept-alive connection and over a new connection per request, each against the same
// data fetched directly from SQLite (its own connection, statements prepared once):
//   readings   index: the cheapest query for the answer (the JSON's columns, through the
//              readings_by_sensor_time index); rows: every column, payload included, with the
//              server's earlier SQL (the cursor as an OR), printed beside it;
//   list       what the list is computed from: each sensor's latest reading, through the index;
//   crusher    each sensor's reading count (an index range count);
//   sensors    each sensor's latest reading and count;
//   wear       each sensor's latest reading (the wear's inputs);
//   forecast   each sensor's fit window of readings (the forecast's inputs), through the index.
// Also the startup time on that database (process start -> HTTP answers, -> every crusher's wear
// computed), the first requests after HTTP answers, and the crusher list while readings are posted.
//   lw_bench_server [--readings N] [--crushers C] [--requests R] [--db FILE]   (--help: every option)
#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "core/bundle.hpp"
#include "core/cmdline.hpp"
#include "core/time.hpp"
#include "server/store.hpp"
#include "sim/campaign.hpp"
#include "support/mosquitto_fixture.hpp"

#include <httplib.h>  // after Eigen (through core/): its macros would clash
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sqlite3.h>
#include <sys/socket.h>
#include <unistd.h>

namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

double Ms(Clock::duration d) {
  return std::chrono::duration<double, std::milli>(d).count();
}

struct Stats {
  double p50 = 0, p99 = 0;
};
Stats Percentiles(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  Stats s;
  s.p50 = v[v.size() / 2];
  s.p99 = v[static_cast<size_t>(std::ceil(0.99 * static_cast<double>(v.size()))) - 1];
  return s;
}

struct Fleet {
  std::vector<std::string> crushers;
  std::vector<std::string> sensors;   ///< the same sensor ids on every crusher
  std::vector<double> thickness_new;  ///< per sensor
  int64_t installed_s = 0;
  int64_t per_sensor = 0;  ///< readings per sensor, one per hour from installed + 1 h
  double thickness_min = 0;
};

/// crushers/cNNN/{crusher.json, wear_map.vtk}: the simulator's crusher and map under 100 ids.
Fleet MakeCrusherDir(const std::string& dir, int n, const std::string& installed_at) {
  lw::sim::CampaignSpec spec;
  spec.days = 2;
  spec.installed_at = installed_at;
  spec.write_scan = false;
  const std::string proto = dir + "/proto";
  lw::sim::GenerateCampaign(spec, 1).WriteBundle(proto);
  const lw::core::CrusherConfig c = lw::core::LoadCrusherConfig(proto + "/crusher.json");
  std::ifstream in(proto + "/crusher.json");
  json cj = json::parse(in);
  Fleet f;
  for (int k = 0; k < n; ++k) {
    char id[16];
    std::snprintf(id, sizeof id, "c%03d", k);
    const std::string folder = dir + "/crushers/" + id;
    std::filesystem::create_directories(folder);
    cj["crusher_id"] = id;
    cj["site"] = "bench";
    std::ofstream(folder + "/crusher.json") << cj.dump(2);
    std::filesystem::copy_file(proto + "/wear_map.vtk", folder + "/wear_map.vtk");
    f.crushers.push_back(id);
  }
  for (const auto& s : c.sensors) {
    f.sensors.push_back(s.id);
    f.thickness_new.push_back(s.thickness_new_mm);
  }
  f.installed_s = c.installed_at.time_since_epoch().count();
  f.thickness_min = c.thickness_min_mm;
  return f;
}

/// The database, through the server's own store code (Store::Commit, 100,000 readings per
/// transaction, in key order: the bulk path a backfill would take).
void BuildDatabase(const std::string& db, const Fleet& f) {
  lw::server::Store store(db);
  std::vector<std::string> iso(static_cast<size_t>(f.per_sensor));
  for (int64_t k = 0; k < f.per_sensor; ++k) {
    iso[static_cast<size_t>(k)] =
        lw::core::FormatIsoTime(lw::core::TimePoint(std::chrono::seconds(f.installed_s + 3600 * (k + 1))));
  }
  const int64_t received =
      std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  std::vector<lw::server::StoredReading> batch;
  batch.reserve(100000);
  const auto t0 = Clock::now();
  int64_t done = 0;
  const int64_t total = static_cast<int64_t>(f.crushers.size() * f.sensors.size()) * f.per_sensor;
  for (const std::string& crusher : f.crushers) {
    for (size_t s = 0; s < f.sensors.size(); ++s) {
      // Wears from new to 5 mm above the minimum over the campaign, whole millimetres as the ladder reads.
      const double span = f.thickness_new[s] - f.thickness_min - 5;
      for (int64_t k = 0; k < f.per_sensor; ++k) {
        lw::server::StoredReading r;
        r.crusher = crusher;
        r.sensor = f.sensors[s];
        r.seq = k + 1;
        r.time_s = f.installed_s + 3600 * (k + 1);
        r.thickness_mm = std::floor(f.thickness_new[s] - span * static_cast<double>(k) / static_cast<double>(f.per_sensor) *
                                                             (0.9 + 0.02 * static_cast<double>(s)));
        r.loops_intact = static_cast<int64_t>(r.thickness_mm);
        r.battery_mv = 3500;
        r.received_s = received;
        char payload[256];
        std::snprintf(payload, sizeof payload,
                      "{\"sensor\":\"%s\",\"seq\":%lld,\"time\":\"%s\",\"thickness_mm\":%g,\"loops_intact\":%lld,\"flags\":0,"
                      "\"battery_mv\":3500}",
                      r.sensor.c_str(), static_cast<long long>(r.seq), iso[static_cast<size_t>(k)].c_str(), r.thickness_mm,
                      static_cast<long long>(r.loops_intact));
        r.payload = payload;
        batch.push_back(std::move(r));
        if (batch.size() == 100000) {
          store.Commit(batch, {});
          done += static_cast<int64_t>(batch.size());
          batch.clear();
          std::fprintf(stderr, "\rbuilding the database: %lld of %lld readings (%.0f s)", static_cast<long long>(done),
                       static_cast<long long>(total), Ms(Clock::now() - t0) / 1000);
        }
      }
    }
  }
  if (!batch.empty()) store.Commit(batch, {});
  std::fprintf(stderr, "\nbuilt in %.1f s\n", Ms(Clock::now() - t0) / 1000);
}

/// A read-only SQLite connection of its own: the direct baseline.
class Direct {
 public:
  explicit Direct(const std::string& path) {
    if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK)
      throw std::runtime_error("cannot open " + path);
  }
  ~Direct() {
    for (auto& [sql, st] : cache_) sqlite3_finalize(st);
    sqlite3_close(db_);
  }
  /// Runs `sql` with the bound values, reads every column of every row; returns the row count.
  int Run(const char* sql, const std::vector<std::string>& text, const std::vector<int64_t>& ints) {
    sqlite3_stmt*& st = cache_[sql];
    if (!st && sqlite3_prepare_v2(db_, sql, -1, &st, nullptr) != SQLITE_OK) throw std::runtime_error(sqlite3_errmsg(db_));
    sqlite3_reset(st);
    int i = 1;
    for (const auto& t : text) sqlite3_bind_text(st, i++, t.c_str(), static_cast<int>(t.size()), SQLITE_TRANSIENT);
    for (const int64_t v : ints) sqlite3_bind_int64(st, i++, v);
    int rows = 0;
    volatile int64_t sink = 0;
    while (sqlite3_step(st) == SQLITE_ROW) {
      ++rows;
      for (int c = 0; c < sqlite3_column_count(st); ++c) {
        if (sqlite3_column_type(st, c) == SQLITE_TEXT)
          sink = sink + sqlite3_column_bytes(st, c);
        else
          sink = sink + sqlite3_column_int64(st, c);
      }
    }
    sqlite3_reset(st);
    return rows;
  }
  Direct(const Direct&) = delete;
  Direct& operator=(const Direct&) = delete;

 private:
  sqlite3* db_ = nullptr;
  std::map<const char*, sqlite3_stmt*> cache_;
};

/// The socket floor: a thread of this process that answers every request head on a kept-alive
/// loopback connection with the same fixed response (head and a body of the one-day answer's size,
/// one send, TCP_NODELAY), parsing and computing nothing. What a request costs below any HTTP server:
/// the system calls, loopback TCP and the wake-up of the thread on each side.
class EchoServer {
 public:
  explicit EchoServer(size_t body_bytes) {
    const std::string body(body_bytes, 'x');
    response_ = "HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nContent-Length: " + std::to_string(body.size()) +
                "\r\nKeep-Alive: timeout=5, max=100000\r\n\r\n" + body;
    listener_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof a;
    if (listener_ < 0 || ::bind(listener_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || ::listen(listener_, 8) != 0 ||
        ::getsockname(listener_, reinterpret_cast<sockaddr*>(&a), &len) != 0)
      throw std::runtime_error("echo server: cannot listen on loopback");
    port_ = ntohs(a.sin_port);
    thread_ = std::thread([this] { Run(); });
  }
  ~EchoServer() {  // after its clients closed their connections
    ::shutdown(listener_, SHUT_RDWR);
    ::close(listener_);
    thread_.join();
    for (auto& t : served_) t.join();
  }
  EchoServer(const EchoServer&) = delete;
  EchoServer& operator=(const EchoServer&) = delete;
  int port() const { return port_; }

 private:
  void Run() {
    while (true) {
      const int fd = ::accept(listener_, nullptr, nullptr);
      if (fd < 0) return;                               // closed
      served_.emplace_back([this, fd] { Serve(fd); });  // a thread per connection, as a worker waits on it
    }
  }
  void Serve(int fd) const {
    const int one = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    std::string got;
    char buf[4096];
    for (ssize_t n; (n = ::recv(fd, buf, sizeof buf, 0)) > 0;) {
      got.append(buf, static_cast<size_t>(n));
      for (size_t end; (end = got.find("\r\n\r\n")) != std::string::npos;) {
        got.erase(0, end + 4);
        if (::send(fd, response_.data(), response_.size(), MSG_NOSIGNAL) < 0) break;
      }
    }
    ::close(fd);
  }
  std::string response_;
  int listener_ = -1;
  int port_ = 0;
  std::thread thread_;
  std::vector<std::thread> served_;  ///< Run's alone until it returns
};

/// A kept-alive client with nothing of an HTTP client: writes a request head, reads until the
/// response's Content-Length bytes have arrived.
class RawClient {
 public:
  explicit RawClient(int port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(static_cast<uint16_t>(port));
    if (fd_ < 0 || ::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0)
      throw std::runtime_error("raw client: cannot connect");
    const int one = 1;
    ::setsockopt(fd_, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  }
  ~RawClient() { ::close(fd_); }
  RawClient(const RawClient&) = delete;
  RawClient& operator=(const RawClient&) = delete;
  /// One request; false when the connection failed.
  bool Get(const std::string& head) {
    if (::send(fd_, head.data(), head.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(head.size())) return false;
    std::string got;
    char buf[16384];
    size_t want = std::string::npos;
    while (want == std::string::npos || got.size() < want) {
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n <= 0) return false;
      got.append(buf, static_cast<size_t>(n));
      const size_t end = got.find("\r\n\r\n");
      if (want == std::string::npos && end != std::string::npos) {
        const size_t at = got.find("Content-Length: ");
        if (at == std::string::npos || at > end) return false;
        want = end + 4 + std::stoul(got.substr(at + 16));
      }
    }
    return true;
  }

 private:
  int fd_ = -1;
};

// One day of one sensor, two ways. The cheapest a user could ask for the readings JSON: its columns
// only, through the time index (battery_mv and received from the row: the index does not hold them).
const char* kDayIndexSql =
    "SELECT seq, time, thickness_mm, loops_intact, flags, battery_mv, received FROM readings"
    " WHERE crusher=?1 AND sensor=?2 AND time>=?3 AND time<=?4 ORDER BY time, seq LIMIT ?5";
// Every column, payload included, with the SQL the server ran before (its cursor bound as an OR):
// SQLite started that range at the cursor's time (INT64_MIN on a first page), not at `from`.
const char* kDayRowsSql =
    "SELECT crusher, sensor, seq, time, thickness_mm, loops_intact, flags, battery_mv, received, payload FROM readings"
    " WHERE crusher=?1 AND sensor=?2 AND time>=?3 AND time<=?4 AND (time>?5 OR (time=?5 AND seq>?6)) ORDER BY time, seq LIMIT ?7";
const char* kCountSql = "SELECT COUNT(*) FROM readings WHERE crusher=?1 AND sensor=?2";
const char* kLatestSql =
    "SELECT time, thickness_mm, flags, loops_intact FROM readings WHERE crusher=?1 AND sensor=?2"
    " ORDER BY time DESC, seq DESC LIMIT 1";
const char* kWindowSql =
    "SELECT time, thickness_mm, flags, loops_intact FROM readings WHERE crusher=?1 AND sensor=?2"
    " AND time>=?3 ORDER BY time, seq";

/// CPU time (ns, from each thread's /proc schedstat) and context switches of every thread of a process.
struct ThreadTotals {
  double cpu_ns = 0;
  double switches = 0;
};
ThreadTotals ProcessTotals(int pid) {
  ThreadTotals t;
  const std::string base = "/proc/" + std::to_string(pid) + "/task";
  std::error_code ec;
  for (const auto& task : std::filesystem::directory_iterator(base, ec)) {
    std::ifstream stat(task.path() / "schedstat");
    double on_cpu = 0;
    if (stat >> on_cpu) t.cpu_ns += on_cpu;
    std::ifstream status(task.path() / "status");
    for (std::string line; std::getline(status, line);) {
      if (line.rfind("voluntary_ctxt_switches:", 0) == 0 || line.rfind("nonvoluntary_ctxt_switches:", 0) == 0)
        t.switches += std::stod(line.substr(line.find(':') + 1));
    }
  }
  return t;
}

std::string Iso(int64_t s) {
  return lw::core::FormatIsoTime(lw::core::TimePoint(std::chrono::seconds(s)));
}

const lw::core::OptionTable& Table() {
  using lw::core::Option;
  static const lw::core::OptionTable table{{
      Option::Whole("readings", "N", 10, 1'000'000'000,
                    "readings in the database (default 10000000; crushers x 10 sensors x N/(10 C), hourly)"),
      Option::Whole("crushers", "C", 1, 10'000, "crusher folders (default 100; the simulator's crusher and map)"),
      Option::Whole("requests", "R", 10, 1'000'000, "requests per query (default 200; the crusher list R/4)"),
      Option::Text("perf", "FILE",
                   "perf record -e cpu-clock --call-graph dwarf attached to the server during the\n"
                   "one-day readings loop (FILE: perf's output)"),
      Option::Text("server", "BIN", "the linerwatch-server binary to measure (default: this build's)"),
      Option::Text("db", "FILE",
                   "the database file, kept; reused when it exists (the same --readings and\n"
                   "--crushers, built on the same day)"),
  }};
  return table;
}

}  // namespace

int main(int argc, char** argv) {
  long long n = 10'000'000;
  int n_crushers = 100, requests = 200;
  std::string db_arg, perf, server_bin = LW_SERVER_BIN;
  try {
    const lw::core::ParsedOptions p = lw::core::ParseOptions(Table(), std::vector<std::string>(argv + 1, argv + argc));
    if (p.help()) {
      std::printf(
          "lw_bench_server: the REST API on a fleet-sized database against SQLite alone, p50/p99 and their\n"
          "ratios from one run (docs/performance.md, *Server REST at fleet scale*).\n\nusage: lw_bench_server %s\n\n%s",
          Table().Synopsis(24, 100).c_str(), Table().Help(28).c_str());
      return 0;
    }
    n = p.Integer<long long>("readings", n);
    n_crushers = p.Integer<int>("crushers", n_crushers);
    requests = p.Integer<int>("requests", requests);
    db_arg = p.Text("db");
    server_bin = p.Text("server", server_bin);
    perf = p.Text("perf");
  } catch (const lw::core::UsageError& e) {
    std::fprintf(stderr, "lw_bench_server: %s\n", e.what());
    return 2;
  }
  if (n < n_crushers * 10LL) {
    std::fprintf(stderr, "lw_bench_server: --readings must be at least 10 per crusher (--crushers %d)\n", n_crushers);
    return 2;
  }
  lw::test::TempDirectory dir("lw-bench-server");
  // Installed so that the hourly readings end an hour ago (posted readings must not be in the future).
  const long long per_sensor = n / (static_cast<long long>(n_crushers) * 10);
  const int64_t now_s =
      std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  const int64_t installed_s =
      (now_s - 3600 * (per_sensor + 1)) / 86400 * 86400;  // midnight: the same for runs on one day (--db reuse)
  Fleet fleet = MakeCrusherDir(dir.path(), n_crushers, Iso(installed_s));
  fleet.per_sensor = n / static_cast<long long>(fleet.crushers.size() * fleet.sensors.size());
  const long long total = fleet.per_sensor * static_cast<long long>(fleet.crushers.size() * fleet.sensors.size());
  const std::string db = db_arg.empty() ? dir.File("server.sqlite") : db_arg;
  if (!std::filesystem::exists(db)) {
    BuildDatabase(db, fleet);
  } else {
    std::fprintf(stderr, "reusing %s (built by an earlier run with the same --readings and --crushers)\n", db.c_str());
  }
  const int64_t end_s = fleet.installed_s + 3600 * fleet.per_sensor;
  std::printf("database   %lld readings: %zu crushers x %zu sensors x %lld (hourly, %.0f days), %.2f GB\n", total,
              fleet.crushers.size(), fleet.sensors.size(), static_cast<long long>(fleet.per_sensor),
              static_cast<double>(fleet.per_sensor) / 24.0, static_cast<double>(std::filesystem::file_size(db)) / 1e9);

  lw::test::MosquittoFixture broker({.persistence = false, .tls = false, .username = "", .password = "", .extra_config = ""});
  broker.Start();
  const int port = lw::test::FreeLoopbackPort();
  lw::test::ChildProcess server;
  const auto t_start = Clock::now();
  server.Start({server_bin, "--broker", broker.uri(), "--db", db, "--http", "127.0.0.1:" + std::to_string(port), "--crusher-dir",
                dir.File("crushers"), "--client-id", "bench-server", "--web-dir", ""},
               dir.File("server.log"));
  double t_http = -1, t_ready = -1;
  std::vector<std::tuple<std::string, double, int>> first_ms;  // (path, ms, status) right after HTTP answered
  while (Ms(Clock::now() - t_start) < 600'000) {
    if (!server.Running()) {
      std::fprintf(stderr, "the server exited:\n%s\n", lw::test::FileTail(dir.File("server.log")).c_str());
      return 1;
    }
    httplib::Client probe("127.0.0.1", port);
    probe.set_connection_timeout(1, 0);
    probe.set_read_timeout(60, 0);
    if (t_http < 0) {
      if (auto r = probe.Get("/healthz"); r && r->status == 200) {
        t_http = Ms(Clock::now() - t_start);
        // The first requests a user would make once the server answers: nothing should be loaded or
        // computed for them on the request path (the later ones are timed below).
        for (const std::string& path :
             {std::string("/api/v1/crushers"), "/api/v1/crushers/" + fleet.crushers.back() + "/wear",
              "/api/v1/crushers/" + fleet.crushers.back() + "/sensors/" + fleet.sensors[0] +
                  "/readings?from=" + Iso(fleet.installed_s) + "&to=" + Iso(fleet.installed_s + 86399)}) {
          const auto t0 = Clock::now();
          auto first = probe.Get(path);
          first_ms.emplace_back(path, Ms(Clock::now() - t0), first ? first->status : -1);
        }
      }
    } else if (auto r = probe.Get("/api/v1/crushers"); r && r->status == 200) {
      const json list = json::parse(r->body)["crushers"];
      if (std::all_of(list.begin(), list.end(), [](const json& c) { return !c["min_thickness_mm"].is_null(); })) {
        t_ready = Ms(Clock::now() - t_start);
        break;
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  std::string rebuild = "?", cpu = "?";
  for (int tries = 0; tries < 100 && cpu == "?"; ++tries) {  // the worker logs its line as it finishes
    std::ifstream log(dir.File("server.log"));
    for (std::string line; std::getline(log, line);) {
      size_t at = line.find("per-crusher state loaded in ");
      if (at != std::string::npos) rebuild = line.substr(at + 28);
      at = line.find("(process CPU since start: ");
      if (at != std::string::npos) cpu = line.substr(at + 26, line.size() - at - 27);
    }
    if (cpu == "?") std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  double load[1] = {0};
  getloadavg(load, 1);
  std::printf(
      "startup    HTTP answering after %.2f s, every crusher's wear and forecast computed after %.2f s, target < 10 s\n"
      "           (per-crusher state from the database: %s; the server's CPU time to that point: %s;\n"
      "            load average %.1f on %u cores)\n",
      t_http / 1000, t_ready / 1000, rebuild.c_str(), cpu.c_str(), load[0], std::thread::hardware_concurrency());
  for (const auto& [path, ms, status] : first_ms)
    std::printf("first      %8.2f ms  GET %s (status %d), as soon as /healthz answered\n", ms, path.c_str(), status);
  if (t_ready < 0) return 1;

  // The same random picks for every way of asking.
  std::mt19937_64 rng(16);
  struct Pick {
    std::string crusher, sensor;
    int64_t from_s;
  };
  std::vector<Pick> picks;
  for (int i = 0; i < requests; ++i) {
    const int64_t day = static_cast<int64_t>(rng() % static_cast<uint64_t>(std::max<int64_t>(1, fleet.per_sensor / 24)));
    picks.push_back({fleet.crushers[rng() % fleet.crushers.size()], fleet.sensors[rng() % fleet.sensors.size()],
                     fleet.installed_s + day * 86400});
  }
  const double t_last_days = static_cast<double>(end_s - fleet.installed_s) / 86400.0;
  const int64_t window_s = end_s - static_cast<int64_t>(std::max(21.0, 0.4 * t_last_days) * 86400.0);

  Direct direct(db);
  struct Kind {
    const char* name;
    std::function<std::string(const Pick&)> path;
    std::function<int(const Pick&)> sqlite;
    std::function<int(const Pick&)> rows;  ///< a second baseline (printed beside), or empty
  };
  int day_rows = 0;
  const auto each_sensor = [&](const char* sql, const Pick& p, std::vector<int64_t> ints) {
    int rows = 0;
    for (const auto& s : fleet.sensors) rows += direct.Run(sql, {p.crusher, s}, ints);
    return rows;
  };
  const std::vector<Kind> kinds = {
      {"one-day readings",
       [](const Pick& p) {
         return "/api/v1/crushers/" + p.crusher + "/sensors/" + p.sensor + "/readings?from=" + Iso(p.from_s) +
                "&to=" + Iso(p.from_s + 86399);
       },
       [&](const Pick& p) {
         return day_rows = direct.Run(kDayIndexSql, {p.crusher, p.sensor}, {p.from_s, p.from_s + 86399, 501});
       },
       [&](const Pick& p) {
         return direct.Run(kDayRowsSql, {p.crusher, p.sensor}, {p.from_s, p.from_s + 86399, INT64_MIN, INT64_MIN, 501});
       }},
      {"crusher list",
       [](const Pick&) { return std::string("/api/v1/crushers"); },
       [&](const Pick&) {
         int rows = 0;
         for (const auto& c : fleet.crushers)
           for (const auto& s : fleet.sensors) rows += direct.Run(kLatestSql, {c, s}, {});
         return rows;
       },
       {}},
      {"crusher",
       [](const Pick& p) { return "/api/v1/crushers/" + p.crusher; },
       [&](const Pick& p) { return each_sensor(kCountSql, p, {}); },
       {}},
      {"sensors",
       [](const Pick& p) { return "/api/v1/crushers/" + p.crusher + "/sensors"; },
       [&](const Pick& p) { return each_sensor(kLatestSql, p, {}) + each_sensor(kCountSql, p, {}); },
       {}},
      {"wear (with faces)",
       [](const Pick& p) { return "/api/v1/crushers/" + p.crusher + "/wear"; },
       [&](const Pick& p) { return each_sensor(kLatestSql, p, {}); },
       {}},
      {"forecast",
       [](const Pick& p) { return "/api/v1/crushers/" + p.crusher + "/forecast"; },
       [&](const Pick& p) { return each_sensor(kWindowSql, p, {window_s}); },
       {}},
  };
  std::printf("%-17s %15s %15s | %15s %12s %12s | %15s %12s\n", "", "SQLite: index", "SQLite: rows", "kept-alive", "/ index",
              "/ rows", "new connection", "/ index");
  std::printf("%-17s %15s %15s | %15s %12s %12s | %15s %12s\n", "query", "p50 / p99 ms", "p50 / p99 ms", "p50 / p99 ms",
              "p50 / p99", "p50 / p99", "p50 / p99 ms", "p50 / p99");
  httplib::Client kept("127.0.0.1", port);
  kept.set_keep_alive(true);
  kept.set_read_timeout(60, 0);
  size_t body_bytes = 0;
  // The floor under the one-day query, interleaved with it: the same exchange against a thread that
  // answers without HTTP (EchoServer), from a raw socket and from the bench's own httplib client.
  std::optional<EchoServer> echo;
  if (auto r = kept.Get(kinds.front().path(picks.front())); r && r->status == 200) echo.emplace(r->body.size());
  if (!echo) {
    std::fprintf(stderr, "GET %s failed\n", kinds.front().path(picks.front()).c_str());
    return 1;
  }
  RawClient raw(echo->port());
  httplib::Client echo_client("127.0.0.1", echo->port());
  echo_client.set_keep_alive(true);
  std::vector<double> t_raw, t_echo;
  for (const Kind& k : kinds) {
    // Interleaved: each pick asked of SQLite (each baseline), over the kept-alive connection and over
    // a new one in turn.
    std::vector<double> t_sql, t_rows, t_kept, t_new;
    const int reps = std::string(k.name) == "crusher list" ? std::max(10, requests / 4) : requests;
    // CPU samples of the server's threads only (this machine's virtual CPU has no hardware counters).
    lw::test::ChildProcess profiler;
    if (!perf.empty() && &k == &kinds.front()) {
      profiler.Start(
          {"perf", "record", "-e", "cpu-clock", "--call-graph", "dwarf", "-p", std::to_string(server.pid()), "-o", perf},
          dir.File("perf.log"));
      std::this_thread::sleep_for(std::chrono::seconds(2));  // attached before the first request
    }
    bool failed = false;
    for (int i = 0; i < reps && !failed; ++i) {
      const Pick& p = picks[static_cast<size_t>(i)];
      const std::string path = k.path(p);
      const auto timed = [](std::vector<double>& into, const std::function<void()>& run) {
        const auto t0 = Clock::now();
        run();
        into.push_back(Ms(Clock::now() - t0));
      };
      std::vector<std::function<void()>> ways = {
          [&] { timed(t_sql, [&] { k.sqlite(p); }); },
          [&] {
            if (k.rows) timed(t_rows, [&] { k.rows(p); });
          },
          [&] {
            std::optional<httplib::Result> r;
            timed(t_kept, [&] { r.emplace(kept.Get(path)); });
            if (!*r || (*r)->status != 200) {
              std::fprintf(stderr, "GET %s: %s\n", path.c_str(), *r ? (*r)->body.c_str() : "no response");
              failed = true;
              return;
            }
            body_bytes = (*r)->body.size();
          },
          [&] {
            std::optional<httplib::Result> r;
            timed(t_new, [&] {
              httplib::Client fresh("127.0.0.1", port);
              fresh.set_read_timeout(60, 0);
              r.emplace(fresh.Get(path));
            });
            if (!*r || (*r)->status != 200) failed = true;
          },
      };
      if (&k == &kinds.front()) {
        const std::string head = "GET " + path + " HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(echo->port()) +
                                 "\r\nAccept: */*\r\nUser-Agent: cpp-httplib/0.11.4\r\n\r\n";
        ways.push_back([&, head] { timed(t_raw, [&] { failed = failed || !raw.Get(head); }); });
        ways.push_back([&] {
          timed(t_echo, [&] {
            auto r = echo_client.Get(path);
            failed = failed || !r || r->status != 200;
          });
        });
      }
      // The order rotates pick by pick: whichever way runs right after a long SQLite query finds
      // the server's threads asleep (a wake-up on a loaded machine), and no way always pays it.
      for (size_t w = 0; w < ways.size(); ++w) ways[(w + static_cast<size_t>(i)) % ways.size()]();
    }
    if (failed) return 1;
    if (!perf.empty() && &k == &kinds.front()) profiler.Stop(SIGINT, std::chrono::seconds(60));
    const Stats s = Percentiles(t_sql), a = Percentiles(t_kept), b = Percentiles(t_new);
    char rows[64] = "", rows_ratio[64] = "";
    if (!t_rows.empty()) {
      const Stats w = Percentiles(t_rows);
      std::snprintf(rows, sizeof rows, "%6.3f / %6.3f", w.p50, w.p99);
      std::snprintf(rows_ratio, sizeof rows_ratio, "%5.2f / %5.2f", a.p50 / w.p50, a.p99 / w.p99);
    }
    std::printf(
        "%-17s %6.3f / %6.3f %15s | %6.3f / %6.3f %5.1f / %5.1f %12s | %6.3f / %6.3f %5.1f / %5.1f  (%d requests, %zu bytes)\n",
        k.name, s.p50, s.p99, rows, a.p50, a.p99, a.p50 / s.p50, a.p99 / s.p99, rows_ratio, b.p50, b.p99, b.p50 / s.p50,
        b.p99 / s.p99, reps, body_bytes);
    if (&k == &kinds.front()) {
      const Stats r = Percentiles(t_raw), e = Percentiles(t_echo);
      std::printf("%-17s %33s | %6.3f / %6.3f %5.1f / %5.1f   (socket floor: a thread answering a fixed %zu-byte response,\n",
                  "  floor: socket", "", r.p50, r.p99, r.p50 / s.p50, r.p99 / s.p99, body_bytes);
      std::printf(
          "%-17s %33s | %6.3f / %6.3f %5.1f / %5.1f   no HTTP; from a raw socket, then from this bench's httplib client)\n",
          "  floor: +client", "", e.p50, e.p99, e.p50 / s.p50, e.p99 / s.p99);
    }
  }
  {
    // The one-day query back to back on the kept-alive connection (a script paging readings): the
    // server's CPU time and task switches per request, which move less with the machine's load than
    // its latency does.
    std::vector<double> t;
    const ThreadTotals before = ProcessTotals(server.pid());
    for (int i = 0; i < requests; ++i) {
      const std::string path = kinds.front().path(picks[static_cast<size_t>(i)]);
      const auto t0 = Clock::now();
      auto r = kept.Get(path);
      t.push_back(Ms(Clock::now() - t0));
      if (!r || r->status != 200) return 1;
    }
    const ThreadTotals after = ProcessTotals(server.pid());
    const Stats s = Percentiles(t);
    std::printf(
        "%-19s %17s | %7.3f / %7.3f   (one-day, back to back: the server's CPU %.0f us and %.1f task switches a request)\n",
        "one-day, in a row", "", s.p50, s.p99, (after.cpu_ns - before.cpu_ns) / 1e3 / requests,
        (after.switches - before.switches) / requests);
  }
  {
    std::vector<double> t;
    for (int i = 0; i < requests; ++i) {
      const auto t0 = Clock::now();
      auto r = kept.Get("/healthz");
      t.push_back(Ms(Clock::now() - t0));
      if (!r) return 1;
    }
    const Stats s = Percentiles(t);
    std::printf("%-19s %17s | %7.3f / %7.3f   (no stall: a delayed-ACK wait would be ~40 ms)\n", "/healthz", "", s.p50, s.p99);
  }
  std::printf("one-day query: %d readings per answer\n", day_rows);

  // The list while readings are posted to every crusher (each post commits and makes its crusher's
  // wear stale: the wear worker recomputes them while the list is asked for).
  {
    std::atomic<bool> stop{false};
    std::atomic<long> posted{0};
    std::thread writer([&] {
      httplib::Client w("127.0.0.1", port);
      w.set_keep_alive(true);
      int64_t seq = fleet.per_sensor + 1;
      while (!stop) {
        for (const auto& c : fleet.crushers) {
          json body = {{"readings", json::array()}};
          for (size_t s = 0; s < fleet.sensors.size(); ++s) {
            body["readings"].push_back({{"sensor", fleet.sensors[s]},
                                        {"seq", seq},
                                        {"time", Iso(end_s + 60 * (seq - fleet.per_sensor))},
                                        {"thickness_mm", fleet.thickness_min + 5},
                                        {"loops_intact", 35},
                                        {"flags", 0},
                                        {"battery_mv", 3500}});
          }
          if (auto r = w.Post("/api/v1/crushers/" + c + "/readings", body.dump(), "application/json"); r && r->status == 200)
            ++posted;
          if (stop) break;
        }
        ++seq;
      }
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    std::vector<double> t;
    for (int i = 0; i < std::max(10, requests / 4); ++i) {
      const auto t0 = Clock::now();
      auto r = kept.Get("/api/v1/crushers");
      t.push_back(Ms(Clock::now() - t0));
      if (!r || r->status != 200) return 1;
    }
    stop = true;
    writer.join();
    const Stats s = Percentiles(t);
    std::printf("%-19s %17s | %7.3f / %7.3f   (while %ld posts of 10 readings were committed; target < 50 ms)\n",
                "list under ingest", "", s.p50, s.p99, posted.load());
  }
  server.Stop(SIGTERM);
  return 0;
}
