#include "core/cmdline.hpp"
#include "server/server.hpp"

#include <filesystem>

#ifndef LW_WEB_DIR
#define LW_WEB_DIR ""
#endif
#ifndef LW_WEB_INSTALL_DIR
#define LW_WEB_INSTALL_DIR ""
#endif

namespace lw::server {
namespace {
constexpr int64_t kMaxWearIntervalMs = 86'400'000;  // a day
constexpr int64_t kMaxBatch = 1'000'000;
constexpr int64_t kMaxCommitDelayMs = 1000;
}  // namespace

std::string ServerHelp() {
  return R"(linerwatch-server: readings over MQTT -> SQLite -> live global wear, forecasts, REST, dashboard.

Usage: linerwatch-server --broker URI --db FILE --http HOST:PORT --crusher-dir DIR [options]

  --broker URI          tcp://host:1883 or ssl://host:8883
  --db FILE             SQLite database (created if missing)
  --http HOST:PORT      REST API and dashboard (default 127.0.0.1:8080; port 0 picks a free one)
  --crusher-dir DIR     one sub-folder per crusher with crusher.json and wear_map.vtk (or .csv)
  --tokens FILE         bearer tokens (SHA-256 hashes, read/write scopes); without it the API is open
  --allowed-hosts LIST  comma-separated host names the API answers to (Host header), besides IP
                        addresses, localhost and --http's host; others get 421 (DNS rebinding)
  --username U --password P   broker credentials
  --tls-ca FILE         CA certificate for ssl:// brokers
  --client-id ID        MQTT client id of the persistent session (default linerwatch-server)
  --topic-root ROOT     default linerwatch/v1
  --web-dir DIR         dashboard files served at / (default: the installed dashboard)
  --wear-interval-ms N  publish global wear at most this often (default 1000)
  --batch-max N         readings committed per transaction at most (default 1000)
  --commit-delay-ms N   group commit: wait up to N ms for more readings before committing (default 5)
  --clock-file PATH     simulation: read "now" (unix milliseconds) from PATH
  --config FILE         JSON object with any of the options above; flags override it
  --help                this text
)";
}

ServerOptions ParseServerOptions(const std::vector<std::string>& args) {
  ServerOptions o;
  // The build tree's dashboard when running from a build, else the installed one.
  std::error_code ec;
  o.web_dir = std::filesystem::exists(std::filesystem::path(LW_WEB_DIR) / "index.html", ec) ? LW_WEB_DIR : LW_WEB_INSTALL_DIR;
  const bool go = core::ParseCommandLine(args, {}, [&o](const std::string& name, const std::string& value) {
    if (name == "broker") o.broker = value;
    else if (name == "db") o.db = value;
    else if (name == "http") o.http = value;
    else if (name == "crusher-dir") o.crusher_dir = value;
    else if (name == "tokens") o.tokens = value;
    else if (name == "username") o.username = value;
    else if (name == "password") o.password = value;
    else if (name == "tls-ca") o.tls_ca = value;
    else if (name == "client-id") o.client_id = value;
    else if (name == "topic-root") o.topic_root = value;
    else if (name == "web-dir") o.web_dir = value;
    else if (name == "clock-file") o.clock_file = value;
    else if (name == "allowed-hosts") {
      o.allowed_hosts.clear();
      size_t start = 0;
      while (start <= value.size()) {
        const size_t comma = value.find(',', start);
        const std::string h = value.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
        if (!h.empty()) o.allowed_hosts.push_back(h);
        if (comma == std::string::npos) break;
        start = comma + 1;
      }
    }
    else if (name == "wear-interval-ms") o.wear_interval_ms = core::ParseWholeNumber(name, value, 0, kMaxWearIntervalMs);
    else if (name == "batch-max") o.batch_max = core::ParseWholeNumber(name, value, 1, kMaxBatch);
    else if (name == "commit-delay-ms") o.commit_delay_ms = core::ParseWholeNumber(name, value, 0, kMaxCommitDelayMs);
    else throw core::UsageError("unknown option --" + name + " (see --help)");
  });
  if (!go) {
    o.help = true;
    return o;
  }
  if (o.broker.empty()) throw core::UsageError("--broker is required");
  if (o.db.empty()) throw core::UsageError("--db is required");
  if (o.crusher_dir.empty()) throw core::UsageError("--crusher-dir is required");
  if (o.broker.rfind("tcp://", 0) != 0 && o.broker.rfind("ssl://", 0) != 0 && o.broker.rfind("mqtt://", 0) != 0 &&
      o.broker.rfind("mqtts://", 0) != 0) {
    throw core::UsageError("--broker '" + o.broker + "' must start with tcp:// or ssl://");
  }
  const size_t colon = o.http.rfind(':');
  if (colon == std::string::npos || colon == 0) throw core::UsageError("--http '" + o.http + "' must be HOST:PORT");
  (void)core::ParseWholeNumber("http", o.http.substr(colon + 1), 0, 65535);  // the port
  if (o.client_id.empty() || o.topic_root.empty()) throw core::UsageError("--client-id and --topic-root must not be empty");
  return o;
}

}  // namespace lw::server
