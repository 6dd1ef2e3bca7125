#pragma once
/// REST API (docs/server.md) and the dashboard's static files, on cpp-httplib.
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "server/auth.hpp"
#include "server/diagnosis_runner.hpp"
#include "server/events.hpp"
#include "server/ingest.hpp"
#include "server/registry.hpp"
#include "server/store.hpp"
#include "server/wear_service.hpp"

namespace lw::server {

/// Limits the HTTP front end enforces as bytes arrive, before anything is buffered or parsed
/// (docs/security.md). Exceeding one gets a JSON error and the connection is closed.
struct HttpLimits {
  size_t max_request_line = 8 * 1024;     ///< 414
  size_t max_head_bytes = 32 * 1024;      ///< request line + headers: 431
  size_t max_headers = 100;               ///< header fields: 431
  uint64_t max_body_bytes = 16u << 20;    ///< Content-Length or chunked (as received): 413
  int head_timeout_ms = 10'000;           ///< a request head must arrive whole within this: 408
  int idle_timeout_ms = 5'000;            ///< a connection without a request in progress is closed
  int body_timeout_ms = 60'000;           ///< a request body must arrive whole within this: 408
  int io_timeout_ms = 5'000;              ///< one read or write waits at most this
  size_t max_connections = 256;           ///< open connections in all: 503
  size_t max_connections_per_client = 32; ///< open connections from one IP address: 503
  size_t workers = 32;                    ///< threads serving complete requests
  size_t max_requests_per_connection = 100;
};

struct ApiContext {
  const Registry* registry = nullptr;
  Store* read = nullptr;  ///< guarded by read_mutex
  std::mutex* read_mutex = nullptr;
  WearService* wear = nullptr;
  const LiveState* live = nullptr;  ///< counts and latest readings (summaries never scan the store)
  Ingestor* ingestor = nullptr;
  EventBus* events = nullptr;
  DiagnosisRunner* diagnosis = nullptr;  ///< may be null (diagnosis endpoints answer 503)
  const TokenStore* tokens = nullptr;    ///< null or disabled: open API
  std::filesystem::path web_dir;         ///< dashboard files served at / (empty: none)
  std::function<nlohmann::ordered_json()> health;                   ///< extra /healthz fields
  std::function<void(const IngestResult&)> after_ingest;            ///< REST-posted readings committed
  HttpLimits limits;
  /// Host names (besides IP addresses and localhost) the API answers to: a request whose Host is
  /// anything else is refused (DNS rebinding). From --http's host and --allowed-hosts.
  std::vector<std::string> allowed_hosts;
};

/// True when `host` (a Host header: name or address, optional :port) is an IP address literal,
/// localhost, or one of `allowed` (case-insensitive).
bool HostAllowed(const std::string& host, const std::vector<std::string>& allowed);

class HttpApi {
 public:
  explicit HttpApi(ApiContext context);
  ~HttpApi();
  HttpApi(const HttpApi&) = delete;
  HttpApi& operator=(const HttpApi&) = delete;

  /// Binds host:port (port 0: any free port). Throws std::runtime_error when it cannot.
  int Bind(const std::string& host, int port);
  /// Serves on a background thread until Stop().
  void Start();
  void Stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lw::server
