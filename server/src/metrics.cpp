#include "server/metrics.hpp"

#include <sys/statvfs.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <vector>

#include "server/rest.hpp"

namespace lw::server {
namespace {

using core::prometheus::Labels;
using core::prometheus::Type;
using core::prometheus::Writer;

int64_t NowS() {
  return std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

/// True when `path` matches `path_template` segment by segment ({name}: any one non-empty segment).
bool Matches(std::string_view path_template, std::string_view path) {
  size_t t = 0, p = 0;
  while (t < path_template.size() && p < path.size()) {
    if (path_template[t] == '{') {
      const size_t close = path_template.find('}', t);
      const size_t slash = path.find('/', p);
      const size_t end = slash == std::string_view::npos ? path.size() : slash;
      if (close == std::string_view::npos || end == p) return false;
      t = close + 1;
      p = end;
    } else if (path_template[t++] != path[p++]) {
      return false;
    }
  }
  return t == path_template.size() && p == path.size();
}

int64_t FileBytes(const std::string& path) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  return ec ? 0 : static_cast<int64_t>(size);
}

}  // namespace

int64_t FreeBytes(const std::string& path) {
  std::filesystem::path dir = std::filesystem::path(path).parent_path();
  if (dir.empty()) dir = ".";
  struct statvfs v {};
  if (::statvfs(dir.c_str(), &v) != 0) return -1;
  return static_cast<int64_t>(v.f_bavail) * static_cast<int64_t>(v.f_frsize);
}

bool OnReadOnlyFileSystem(const std::string& path) {
  std::filesystem::path dir = std::filesystem::path(path).parent_path();
  if (dir.empty()) dir = ".";
  struct statvfs v {};
  return ::statvfs(dir.c_str(), &v) == 0 && (v.f_flag & ST_RDONLY) != 0;
}

std::string RouteLabel(std::string_view path) {
  for (const rest::Route& route : rest::Resources::Routes()) {
    if (Matches(route.path, path)) return route.path;
  }
  if (path == "/") return "/";
  if (path.rfind("/assets/", 0) == 0) return "/assets";
  return "other";
}

ServerMetrics::ServerMetrics(std::string db)
    : db_(std::move(db)),
      // Measured time to commit: radio, gateway spool, broker and server; hours when a gateway was cut off.
      ingest_lag_({1, 5, 15, 60, 300, 900, 3600, 14400, 86400}),
      wear_seconds_({0.01, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30}),
      start_s_(NowS()) {}

void ServerMetrics::CountHttp(std::string_view method, std::string_view path, int status) {
  std::string route = RouteLabel(path);
  // Methods outside HTTP's usual set are one label value, so a client cannot grow the series.
  static const std::set<std::string_view> kMethods = {"GET", "HEAD", "POST", "PUT", "DELETE", "PATCH", "OPTIONS"};
  const std::string m = kMethods.count(method) ? std::string(method) : "other";
  std::lock_guard<std::mutex> lock(mutex_);
  ++http_[{m, std::move(route), status}];
}

void ServerMetrics::CountAcked(uint64_t seqs) {
  acked_ += seqs;
}

void ServerMetrics::ObserveCommitted(const IngestResult& result, int64_t now_s) {
  for (const StoredReading& r : result.new_readings)
    ingest_lag_.Observe(static_cast<double>(std::max<int64_t>(0, now_s - r.time_s)));
}

void ServerMetrics::WearChanged(const std::string& crusher, int64_t now_ms) {
  std::lock_guard<std::mutex> lock(mutex_);
  WearState& w = wear_[crusher];
  if (w.changed_since_ms == 0) w.changed_since_ms = now_ms;
}

void ServerMetrics::WearTaken(const std::string& crusher) {
  std::lock_guard<std::mutex> lock(mutex_);
  WearState& w = wear_[crusher];
  if (w.taken_since_ms == 0 || (w.changed_since_ms != 0 && w.changed_since_ms < w.taken_since_ms))
    w.taken_since_ms = w.changed_since_ms;
  w.changed_since_ms = 0;
}

void ServerMetrics::WearDone(const std::string& crusher, bool ok, double seconds, int64_t now_ms) {
  wear_seconds_.Observe(seconds);
  std::lock_guard<std::mutex> lock(mutex_);
  WearState& w = wear_[crusher];
  if (ok) {
    ++w.ok;
    w.last_success_ms = now_ms;
    w.taken_since_ms = 0;
  } else {
    ++w.failed;  // still behind: the lag keeps growing until a recompute succeeds
  }
}

void ServerMetrics::RenderIngest(Writer& w, const Ingestor& ingestor) const {
  const IngestCounters c = ingestor.Counters();
  w.Counter("linerwatch_readings_ingested_total", "Reading records validated by the ingest (MQTT and REST), whatever the outcome",
            static_cast<double>(c.stored + c.duplicates + c.conflicts + c.rejected + c.held));
  w.Counter("linerwatch_readings_stored_total", "Readings committed to the database for the first time",
            static_cast<double>(c.stored));
  w.Counter("linerwatch_readings_duplicates_total", "Readings already stored (a republication): committed before, acked again",
            static_cast<double>(c.duplicates));
  w.Counter("linerwatch_readings_conflicts_total",
            "Readings whose (sensor, seq) was stored before with another time or thickness: quarantined",
            static_cast<double>(c.conflicts));
  w.Family("linerwatch_readings_rejected_total", "Readings that failed validation (quarantined), by reason class",
           Type::kCounter);
  for (const char* reason : kRejectionReasons) {
    const auto it = c.rejected_by_reason.find(reason);
    w.Sample({{"reason", reason}}, it == c.rejected_by_reason.end() ? 0.0 : static_cast<double>(it->second));
  }
  w.Family("linerwatch_readings_held_total",
           "Readings neither stored nor quarantined nor acknowledged, kept by their gateway until they can be stored, by "
           "reason class",
           Type::kCounter);
  for (const char* reason : kHeldReasons) {
    const auto it = c.held_by_reason.find(reason);
    w.Sample({{"reason", reason}}, it == c.held_by_reason.end() ? 0.0 : static_cast<double>(it->second));
  }
  w.Counter("linerwatch_ingest_commits_total", "Ingest transactions (one per MQTT batch or REST post)",
            static_cast<double>(c.batches));
  w.Counter("linerwatch_readings_acked_total", "Sequence numbers sent to gateways in commit acks",
            static_cast<double>(acked_.load()));
  w.Counter("linerwatch_commit_acks_dropped_total",
            "Commit acks dropped while the broker would not take them (their gateways republish those readings)",
            static_cast<double>(acks_dropped_.load()));
  w.Family(
      "linerwatch_ingest_lag_seconds",
      "Commit time minus the reading's measured time, per newly stored reading (the ingest clock: the simulator's when it runs)",
      Type::kHistogram);
  w.HistogramSample({}, ingest_lag_.Snapshot());
  w.Gauge("linerwatch_broker_connected", "1 while the server is connected to the MQTT broker", broker_connected_ ? 1 : 0);
}

void ServerMetrics::RenderWear(Writer& w, const Registry& registry, int64_t now_ms) const {
  std::map<std::string, WearState> wear;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    wear = wear_;
  }
  std::vector<std::string> crushers;
  for (const Crusher* c : registry.All()) crushers.push_back(c->config.crusher_id);
  w.Family("linerwatch_wear_runs_total", "Wear recomputes of the wear worker, by crusher and result", Type::kCounter);
  for (const std::string& c : crushers) {
    const WearState s = wear.count(c) ? wear.at(c) : WearState{};
    w.Sample({{"crusher", c}, {"result", "ok"}}, static_cast<double>(s.ok));
    w.Sample({{"crusher", c}, {"result", "error"}}, static_cast<double>(s.failed));
  }
  w.Family("linerwatch_wear_duration_seconds", "Duration of one wear recompute of the wear worker", Type::kHistogram);
  w.HistogramSample({}, wear_seconds_.Snapshot());
  w.Family("linerwatch_wear_last_success_timestamp_seconds",
           "Unix time of the crusher's last successful wear recompute (0: none yet)", Type::kGauge);
  for (const std::string& c : crushers)
    w.Sample({{"crusher", c}}, wear.count(c) ? static_cast<double>(wear.at(c).last_success_ms) / 1000 : 0);
  w.Family("linerwatch_wear_lag_seconds",
           "How long the crusher's oldest committed reading has waited for a successful wear recompute (0: up to date)",
           Type::kGauge);
  for (const std::string& c : crushers) {
    int64_t since = 0;
    if (const auto it = wear.find(c); it != wear.end()) {
      for (int64_t t : {it->second.changed_since_ms, it->second.taken_since_ms}) {
        if (t != 0 && (since == 0 || t < since)) since = t;
      }
    }
    w.Sample({{"crusher", c}}, since == 0 ? 0 : static_cast<double>(std::max<int64_t>(0, now_ms - since)) / 1000);
  }
}

void ServerMetrics::RenderHttpAndStore(Writer& w, int sse_clients) const {
  w.Family("linerwatch_http_requests_total", "HTTP requests answered, by method, route (path template) and status code",
           Type::kCounter);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [key, n] : http_) {
      w.Sample({{"method", std::get<0>(key)}, {"route", std::get<1>(key)}, {"code", std::to_string(std::get<2>(key))}},
               static_cast<double>(n));
    }
  }
  w.Gauge("linerwatch_sse_clients", "Open Server-Sent Events streams (GET .../events)", sse_clients);
  w.Gauge("linerwatch_store_bytes", "Size of the SQLite database with its -wal and -shm files",
          static_cast<double>(FileBytes(db_) + FileBytes(db_ + "-wal") + FileBytes(db_ + "-shm")));
  w.Gauge("linerwatch_store_free_bytes", "Bytes still free to the server on the database's file system (-1: unknown)",
          static_cast<double>(FreeBytes(db_)));
}

void ServerMetrics::CountNotification(const std::string& channel, bool ok) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++notifications_[{channel, ok}];
}

void ServerMetrics::RenderNotifications(Writer& w) const {
  w.Family("linerwatch_notifications_sent_total",
           "Delivery attempts of alarm notifications, by channel and result (ok: the receiver took it; error: retried later)",
           Type::kCounter);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const char* channel : {"webhook", "email"}) {
      for (const bool ok : {true, false}) {
        const auto it = notifications_.find({channel, ok});
        w.Sample({{"channel", channel}, {"result", ok ? "ok" : "error"}},
                 it == notifications_.end() ? 0.0 : static_cast<double>(it->second));
      }
    }
  }
  w.Gauge("linerwatch_notifications_pending", "Alarm notifications queued and not yet taken by their receiver",
          static_cast<double>(notifications_pending_.load()));
}

std::string ServerMetrics::Render(const Ingestor& ingestor, const Registry& registry, int sse_clients, int64_t now_ms) const {
  Writer w;
  w.Family("linerwatch_build_info", "The server's version (the value is always 1)", Type::kGauge);
  w.Sample({{"program", "linerwatch-server"}, {"version", LW_VERSION}}, 1);
  w.Gauge("process_start_time_seconds", "Unix time the server started", static_cast<double>(start_s_));
  RenderIngest(w, ingestor);
  RenderWear(w, registry, now_ms);
  RenderHttpAndStore(w, sse_clients);
  RenderNotifications(w);
  return w.Take();
}

}  // namespace lw::server
