#pragma once
/// The server's /healthz fields (ApiContext::health) and the database check they report: ingest
/// counters, the broker, the wear worker's start-up pass, and why the database takes no writes.
#include <cstddef>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "server/ingest.hpp"

namespace lw::server {

/// Why the database's file system takes no writes now: mounted read-only, or full (less than the
/// 8 MB SQLite's WAL needs); empty when it takes them. Both are states an operator fixes without
/// touching the database (a remount, space).
std::string NotWritable(const std::string& db);

/// The wear worker's first pass (every crusher loaded, then computed): until it ends the crusher
/// list says "pending" for crushers it has not reached.
struct StartupProgress {
  size_t crushers = 0;  ///< in the registry
  size_t loaded = 0;    ///< crushers whose state the pass has loaded
  size_t computed = 0;  ///< crushers whose wear it has computed (or failed to: the error is logged)
};

/// What the server knows of itself for /healthz.
struct HealthInputs {
  IngestCounters counters;
  bool broker_connected = false;
  std::vector<std::string> crusher_errors;  ///< crusher folders skipped at start-up
  StartupProgress startup;
  std::string not_writable;  ///< NotWritable(db): non-empty makes the status "degraded"
};

/// The /healthz fields of a server taking readings, added to the REST resource's own. "status" is
/// set only when degraded (the resource's is "ok" otherwise).
nlohmann::ordered_json HealthJson(const HealthInputs& in);

}  // namespace lw::server
