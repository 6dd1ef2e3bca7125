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

using core::Option;

const core::OptionTable& Table() {
  static const core::OptionTable table{
      {
          Option::Text("broker", "URI", "tcp://host:1883 or ssl://host:8883").Required(),
          Option::Text("db", "FILE", "SQLite database (created if missing)").Required(),
          Option::Text("http", "HOST:PORT", "REST API and dashboard (default 127.0.0.1:8080; port 0 picks a free one)"),
          Option::Text("crusher-dir", "DIR", "one sub-folder per crusher with crusher.json and wear_map.vtk (or .csv)")
              .Required(),
          Option::Text("tokens", "FILE", "bearer tokens (SHA-256 hashes, read/write scopes); without it the API is open"),
          Option::Text("allowed-hosts", "LIST",
                       "comma-separated host names the API answers to (Host header), besides IP\n"
                       "addresses, localhost and --http's host; others get 421 (DNS rebinding)"),
          Option::Text("username", "U", "broker user name"),
          Option::Text("password", "P", "broker password"),
          Option::Text("tls-ca", "FILE", "CA certificate for ssl:// brokers"),
          Option::Text("client-id", "ID", "MQTT client id of the persistent session (default linerwatch-server)"),
          Option::Text("topic-root", "ROOT", "default linerwatch/v1"),
          Option::Text("web-dir", "DIR", "dashboard files served at / (default: the installed dashboard)"),
          Option::Whole("wear-interval-ms", "N", 0, kMaxWearIntervalMs, "publish global wear at most this often (default 1000)"),
          Option::Whole("batch-max", "N", 1, kMaxBatch,
                        "reading messages committed per transaction at most, a batch of records counting once (default 1000)"),
          Option::Whole("commit-delay-ms", "N", 0, kMaxCommitDelayMs,
                        "group commit: wait up to N ms for more readings before committing (default 5)"),
          Option::Text("clock-file", "PATH", "simulation: read \"now\" (unix milliseconds) from PATH"),
      },
      "",
      "",
      /*keep_other_config_keys=*/true};  // "notifications", read below
  return table;
}

std::vector<std::string> SplitList(const std::string& value) {
  std::vector<std::string> out;
  size_t start = 0;
  while (start <= value.size()) {
    const size_t comma = value.find(',', start);
    const std::string h = value.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    if (!h.empty()) out.push_back(h);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return out;
}

/// The --config file named in `args` (ParseOptions has read it).
std::string ConfigFile(const std::vector<std::string>& args) {
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "--config" && i + 1 < args.size()) return args[i + 1];
    if (args[i].rfind("--config=", 0) == 0) return args[i].substr(9);
  }
  return "";
}

}  // namespace

std::string ServerHelp() {
  return "linerwatch-server: readings over MQTT -> SQLite -> live global wear, forecasts, REST, dashboard.\n\n"
         "Usage: linerwatch-server " +
         Table().Synopsis(25, 100) + "\n\n" + Table().Help(24);
}

ServerOptions ParseServerOptions(const std::vector<std::string>& args) {
  ServerOptions o;
  const core::ParsedOptions p = core::ParseOptions(Table(), args);
  if (p.help()) {
    o.help = true;
    return o;
  }
  // The build tree's dashboard when running from a build, else the installed one.
  std::error_code ec;
  const std::string built_web_dir =
      std::filesystem::exists(std::filesystem::path(LW_WEB_DIR) / "index.html", ec) ? LW_WEB_DIR : LW_WEB_INSTALL_DIR;
  o.broker = p.Text("broker");
  o.db = p.Text("db");
  o.http = p.Text("http", o.http);
  o.crusher_dir = p.Text("crusher-dir");
  o.tokens = p.Text("tokens");
  o.username = p.Text("username");
  o.password = p.Text("password");
  o.tls_ca = p.Text("tls-ca");
  o.client_id = p.Text("client-id", o.client_id);
  o.topic_root = p.Text("topic-root", o.topic_root);
  o.web_dir = p.Text("web-dir", built_web_dir);
  o.clock_file = p.Text("clock-file");
  o.allowed_hosts = SplitList(p.Text("allowed-hosts"));
  o.wear_interval_ms = p.Whole("wear-interval-ms", o.wear_interval_ms);
  o.batch_max = p.Whole("batch-max", o.batch_max);
  o.commit_delay_ms = p.Whole("commit-delay-ms", o.commit_delay_ms);
  // The config file's objects that are not flags: only "notifications" (docs/alarms.md).
  for (const auto& [key, value] : p.other_config().items()) {
    const std::string where = "config " + ConfigFile(args);
    if (key != "notifications") throw core::ConfigFileError(where + ": unknown key '" + key + "' (see --help)");
    o.notifications = ParseNotificationConfig(value, where);
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
