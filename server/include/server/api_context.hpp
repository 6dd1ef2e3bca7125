#pragma once
/// What the REST resources (server/rest.hpp) and the HTTP front end (server/http_api.hpp) serve
/// from: the server's parts, the HTTP limits and the hosts it answers to.
#include <cstddef>
#include <cstdint>
#include <atomic>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "server/alarms.hpp"
#include "server/auth.hpp"
#include "server/campaigns.hpp"
#include "server/diagnosis_runner.hpp"
#include "server/events.hpp"
#include "server/ingest.hpp"
#include "server/live_state.hpp"
#include "server/metrics.hpp"
#include "server/registry.hpp"
#include "server/store.hpp"
#include "server/wear_service.hpp"

namespace lw::server {

/// Limits the HTTP front end enforces as bytes arrive, before anything is buffered or parsed
/// (docs/security.md). Exceeding one gets a JSON error and the connection is closed.
struct HttpLimits {
  size_t max_request_line = 8 * 1024;      ///< 414
  size_t max_head_bytes = 32 * 1024;       ///< request line + headers: 431
  size_t max_headers = 100;                ///< header fields: 431
  uint64_t max_body_bytes = 16u << 20;     ///< Content-Length or chunked (as received): 413
  int head_timeout_ms = 10'000;            ///< a request head must arrive whole within this: 408
  int idle_timeout_ms = 5'000;             ///< a connection without a request in progress is closed
  int body_timeout_ms = 60'000;            ///< a request body must arrive whole within this: 408
  int io_timeout_ms = 5'000;               ///< one read or write waits at most this
  size_t max_connections = 256;            ///< open connections in all: 503
  size_t max_connections_per_client = 32;  ///< open connections from one IP address: 503
  size_t workers = 32;                     ///< threads serving complete requests
  /// Requests from one IP address on workers at once; its further complete heads wait for one of
  /// them to finish, so an address trickling bodies leaves the other workers to other addresses.
  size_t max_requests_per_client = 8;
  size_t max_event_streams_per_client = 4;  ///< open event streams from one IP address: 503
  /// An event stream ends after this; EventSource reconnects with Last-Event-ID, missing nothing.
  int event_stream_lifetime_s = 3600;
  size_t max_requests_per_connection = 100;
};

/// Every pointer outlives the HttpApi (or rest::Resources) made from it. The resources are called
/// on the HTTP worker threads, several at once: each part named here is safe to share between them.
struct ApiContext {
  const Registry* registry = nullptr;
  LockedStore* read = nullptr;  ///< the REST reads' connection (one query at a time)
  WearService* wear = nullptr;
  const LiveState* live = nullptr;  ///< counts and latest readings (summaries never scan the store)
  Ingestor* ingestor = nullptr;
  EventBus* events = nullptr;
  DiagnosisRunner* diagnosis = nullptr;  ///< may be null (diagnosis endpoints answer 503)
  CampaignService* campaigns = nullptr;  ///< may be null (campaign endpoints answer 503)
  AlarmEngine* alarms = nullptr;         ///< may be null (alarm endpoints answer 503)
  const TokenStore* tokens = nullptr;    ///< null or disabled: open API
  ServerMetrics* metrics = nullptr;      ///< null: GET /metrics answers 503 and requests are not counted
  std::filesystem::path web_dir;         ///< dashboard files served at / (empty: none)
  /// Extra /healthz fields. Runs on an HTTP worker thread, once per GET /healthz, possibly on
  /// several workers at once: it must be safe to call concurrently.
  std::function<nlohmann::ordered_json()> health;
  /// REST-posted readings were committed (`result` as Ingestor::Ingest returned it). Runs on the
  /// HTTP worker thread that handled the POST, after the commit and before the reply; posts are
  /// handled one at a time, but it runs concurrently with whatever else commits readings (the
  /// server's MQTT loop).
  std::function<void(const IngestResult&)> after_ingest;
  /// A reline of the crusher was stored (its new liner's wear is to be computed and published). Runs
  /// on the HTTP worker thread that handled the POST, before the reply.
  std::function<void(const std::string& crusher)> after_reline;
  /// Set by the server while its wear worker's first pass runs (null: no such pass, as in tests that
  /// compute on demand): until it ends, a crusher's state is loaded and its wear computed by that
  /// pass, never on a request, and a request that needs one not there yet gets 503 "starting".
  const std::atomic<bool>* starting = nullptr;
  HttpLimits limits;
  /// Host names (besides IP addresses and localhost) the API answers to: a request whose Host is
  /// anything else is refused (DNS rebinding). From --http's host and --allowed-hosts.
  std::vector<std::string> allowed_hosts;
};

}  // namespace lw::server
