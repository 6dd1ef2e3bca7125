#include "server/health.hpp"

#include <cstdint>

#include "server/metrics.hpp"

namespace lw::server {
namespace {

constexpr int64_t kMinFreeBytes = 8 << 20;  // SQLite's WAL grows to ~4 MB; docs/server.md

std::string DiskFull(const std::string& db, int64_t free) {
  return "disk full: " + std::to_string(free) + " bytes free for " + db + " (the server needs at least " +
         std::to_string(kMinFreeBytes >> 20) + " MB)";
}

}  // namespace

std::string NotWritable(const std::string& db) {
  if (OnReadOnlyFileSystem(db)) return "read-only file system: " + db + " is on a file system mounted read-only";
  if (const int64_t free = FreeBytes(db); free >= 0 && free < kMinFreeBytes) return DiskFull(db, free);
  return {};
}

nlohmann::ordered_json HealthJson(const HealthInputs& in) {
  const IngestCounters& c = in.counters;
  nlohmann::ordered_json j{{"broker", in.broker_connected ? "connected" : "disconnected"},
                           {"readings_stored", c.stored},
                           {"duplicates", c.duplicates},
                           {"rejected", c.rejected},
                           {"held", c.held},
                           {"crusher_errors", in.crusher_errors}};
  j["startup"] = {{"crushers", in.startup.crushers},
                  {"loaded", in.startup.loaded},
                  {"computed", in.startup.computed},
                  {"done", in.startup.computed >= in.startup.crushers}};
  // Batches fail (and are not acked) once the disk fills or is remounted read-only: say why
  // before the gateways' spools grow.
  if (!in.not_writable.empty()) {
    j["status"] = "degraded";
    j["reason"] = in.not_writable;
  }
  return j;
}

}  // namespace lw::server
