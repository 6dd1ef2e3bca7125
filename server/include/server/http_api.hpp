#pragma once
/// REST API (CONTRACTS §6, docs/server.md) and the dashboard's static files, on cpp-httplib.
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>

#include "server/auth.hpp"
#include "server/diagnosis_runner.hpp"
#include "server/events.hpp"
#include "server/ingest.hpp"
#include "server/registry.hpp"
#include "server/store.hpp"
#include "server/wear_service.hpp"

namespace lw::server {

struct ApiContext {
  const Registry* registry = nullptr;
  Store* read = nullptr;  ///< guarded by read_mutex
  std::mutex* read_mutex = nullptr;
  WearService* wear = nullptr;
  Ingestor* ingestor = nullptr;
  EventBus* events = nullptr;
  DiagnosisRunner* diagnosis = nullptr;  ///< may be null (diagnosis endpoints answer 503)
  const TokenStore* tokens = nullptr;    ///< null or disabled: open API
  std::filesystem::path web_dir;         ///< dashboard files served at / (empty: none)
  std::function<nlohmann::ordered_json()> health;                   ///< extra /healthz fields
  std::function<void(const IngestResult&)> after_ingest;            ///< REST-posted readings committed
};

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
