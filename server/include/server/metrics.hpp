#pragma once
/// The server's `GET /metrics` (Prometheus text format 0.0.4; docs/server.md, *Metrics*). The
/// counts its parts already keep are read from them at each scrape (Ingestor::Counters(), the
/// same the /healthz JSON shows; the open event streams); ServerMetrics holds only what nothing
/// else counts: HTTP requests, commit acks, ingest lag, the wear worker's runs, the broker state.
/// Every method is safe to call from any thread.
#include <atomic>
#include <cstdint>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <string_view>
#include <tuple>

#include "core/prometheus.hpp"
#include "server/ingest.hpp"
#include "server/registry.hpp"

namespace lw::server {

/// Bytes an unprivileged writer may still use on the file system of `path`'s folder; -1 when unknown.
int64_t FreeBytes(const std::string& path);
/// True when the file system holding `path` (its folder) is mounted read-only (statvfs ST_RDONLY).
bool OnReadOnlyFileSystem(const std::string& path);

/// The route label of an HTTP request: the API route's path template it matches (`/api/v1/crushers/{crusher}/wear`),
/// `/` or `/assets` for the dashboard, `other` for anything else: a bounded set, whatever the paths asked.
std::string RouteLabel(std::string_view path);

class ServerMetrics {
 public:
  /// `db`: the database file whose size (with its -wal and -shm files) and free space are reported.
  explicit ServerMetrics(std::string db);

  /// One HTTP request answered with `status` (the HTTP front end calls it for every request).
  void CountHttp(std::string_view method, std::string_view path, int status);
  /// Seqs sent to gateways in commit acks.
  void CountAcked(uint64_t seqs);
  /// Commit acks dropped because the broker would not take them (mqtt::Outbox::dropped(), a total).
  void SetAcksDropped(uint64_t total) { acks_dropped_ = total; }
  /// Readings newly committed at `now_s` (the ingest clock): each one's lag, now minus its
  /// measured time, goes into the ingest lag histogram.
  void ObserveCommitted(const IngestResult& result, int64_t now_s);
  void SetBrokerConnected(bool connected) { broker_connected_ = connected; }
  bool broker_connected() const { return broker_connected_; }

  /// The wear worker: `crusher` has new readings (at wall time `now_ms`); the worker took it
  /// for a recompute; the recompute ended (`ok` false: it threw) after `seconds`.
  void WearChanged(const std::string& crusher, int64_t now_ms);
  void WearTaken(const std::string& crusher);
  void WearDone(const std::string& crusher, bool ok, double seconds, int64_t now_ms);

  /// Notifications (server/notify.hpp): one delivery attempt on `channel` ("webhook", "email"),
  /// taken (`ok`) or not; and how many wait for delivery.
  void CountNotification(const std::string& channel, bool ok);
  void SetNotificationsPending(int64_t pending) { notifications_pending_ = pending; }

  /// The exposition text: these counts with `ingestor`'s, the open event streams and the store's size.
  std::string Render(const Ingestor& ingestor, const Registry& registry, int sse_clients, int64_t now_ms) const;

 private:
  void RenderIngest(core::prometheus::Writer& w, const Ingestor& ingestor) const;
  void RenderWear(core::prometheus::Writer& w, const Registry& registry, int64_t now_ms) const;
  void RenderHttpAndStore(core::prometheus::Writer& w, int sse_clients) const;
  void RenderNotifications(core::prometheus::Writer& w) const;

  std::string db_;
  std::atomic<uint64_t> acked_{0};
  std::atomic<uint64_t> acks_dropped_{0};
  std::atomic<bool> broker_connected_{false};
  std::atomic<int64_t> notifications_pending_{0};
  core::prometheus::Histogram ingest_lag_;
  core::prometheus::Histogram wear_seconds_;
  const int64_t start_s_;

  mutable std::mutex mutex_;                                            // guards everything below
  std::map<std::tuple<std::string, std::string, int>, uint64_t> http_;  ///< (method, route, status) -> requests
  struct WearState {
    int64_t changed_since_ms = 0;  ///< oldest change not taken by the worker yet (0: none)
    int64_t taken_since_ms = 0;    ///< oldest change in the recompute under way (0: none)
    int64_t last_success_ms = 0;
    uint64_t ok = 0, failed = 0;
  };
  std::map<std::string, WearState> wear_;
  std::map<std::pair<std::string, bool>, uint64_t> notifications_;  ///< (channel, ok) -> attempts
};

}  // namespace lw::server
