#include "gateway/config.hpp"

#include "core/cmdline.hpp"
#include "core/identifier.hpp"
#include "gateway/messages.hpp"

#include <unistd.h>

namespace lw::gateway {
namespace {

using core::NumberRange;
using core::Option;

const core::OptionTable& Table() {
  static const core::OptionTable table{{
      Option::Text("serial", "PATH", "coordinator serial port, pty or path (required)").Required(),
      Option::Whole("baud", "N", 1200, 921600, "serial baud rate (default 9600)"),
      Option::Whole("api-mode", "N", 1, 2, "XBee API mode of the coordinator, 1 or 2 (default 2)"),
      Option::Text("broker", "URI", "MQTT broker URI, tcp://host:1883 or ssl://host:8883 (required)").Required(),
      Option::Text("site", "ID", "site id, topic level (required)").Required(),
      Option::Text("crusher", "ID", "crusher id, topic level (required)").Required(),
      Option::Text("spool", "FILE", "SQLite spool file (required)").Required(),
      Option::Text("username", "U", "MQTT user name"),
      Option::Text("password", "P", "MQTT password (requires --username)"),
      Option::Text("tls-ca", "FILE", "CA certificate file for ssl:// brokers"),
      Option::Text("gateway-id", "ID", "gateway id in messages and MQTT client id (default gw-HOSTNAME)"),
      Option::Whole("spool-max-records", "N", 1, 1'000'000'000, "spool capacity in records (default 1000000)"),
      Option::Whole("window", "N", 1, static_cast<int64_t>(kMaxCommitAckSeqs),
                    "reading messages per sensor awaiting a commit ack (default 1: strict order)"),
      Option::Whole("max-batch", "N", 1, static_cast<int64_t>(mqtt::kMaxReadingBatch),
                    "records per reading message at most once the server announces batches\n(default 64; 1: never batch)"),
      Option::Whole("max-devices", "N", 1, 1'000'000,
                    "device registry entries at most; new radios beyond are not registered\n(default 1000)"),
      Option::Number("republish-after", "S", NumberRange::Positive(),
                     "seconds before an unconfirmed record is republished (default 30)"),
      Option::Number("stats-interval", "S", NumberRange::Positive(), "seconds between gateway/stats messages (default 60)"),
      Option::Number("reconnect-min", "S", NumberRange::Positive(), "first reconnect delay, seconds (default 1)"),
      Option::Number("reconnect-max", "S", NumberRange::Positive(), "longest reconnect delay, seconds (default 60)"),
      Option::Text("clock-file", "PATH", "simulation only: stamp readings with the virtual time in this file"),
      Option::Text("metrics", "HOST:PORT",
                   "serve Prometheus metrics on http://HOST:PORT/metrics (default: none; no\nauthentication: bind a loopback or "
                   "management address)"),
  }};
  return table;
}

std::string RequireUri(const std::string& uri) {
  static const char* kSchemes[] = {"tcp://", "ssl://", "mqtt://", "mqtts://", "ws://", "wss://"};
  for (const char* s : kSchemes) {
    if (uri.rfind(s, 0) == 0 && uri.size() > std::string(s).size()) return uri;
  }
  throw ConfigError("--broker: '" + uri + "' is not a broker URI (tcp://host:port or ssl://host:port)");
}

}  // namespace

bool IsSupportedBaud(int baud) {
  static constexpr int kBauds[] = {1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400, 460800, 921600};
  for (int b : kBauds) {
    if (b == baud) return true;
  }
  return false;
}

std::string UsageText() {
  return "usage: linerwatch-gateway " + Table().Synopsis(26, 100) +
         "\n"
         "Reads XBee API frames from the coordinator, spools every sensor record in SQLite, acks it to\n"
         "the sensor, publishes it on MQTT and keeps it until the server confirms it is committed.\n\n" +
         Table().Help(26);
}

ParseResult ParseCommandLine(const std::vector<std::string>& args, Config* config) {
  core::ParsedOptions o;
  try {
    o = core::ParseOptions(Table(), std::vector<std::string>(args.begin() + (args.empty() ? 0 : 1), args.end()));
  } catch (const core::UsageError& e) {
    throw ConfigError(e.what());
  }
  if (o.help()) return ParseResult::kHelp;
  Config c;
  c.serial = o.Text("serial");
  c.baud = o.Integer<int>("baud", c.baud);
  c.api_mode = o.Integer<int>("api-mode", c.api_mode);
  c.broker = o.Text("broker");
  c.site = o.Text("site");
  c.crusher = o.Text("crusher");
  c.spool = o.Text("spool");
  c.username = o.Text("username");
  c.password = o.Text("password");
  c.tls_ca = o.Text("tls-ca");
  c.gateway_id = o.Text("gateway-id");
  c.spool_max_records = o.Integer<size_t>("spool-max-records", c.spool_max_records);
  c.window = o.Integer<size_t>("window", c.window);
  c.max_batch = o.Integer<size_t>("max-batch", c.max_batch);
  c.max_devices = o.Integer<size_t>("max-devices", c.max_devices);
  c.republish_after_s = o.Number("republish-after", c.republish_after_s);
  c.stats_interval_s = o.Number("stats-interval", c.stats_interval_s);
  c.reconnect_min_s = o.Number("reconnect-min", c.reconnect_min_s);
  c.reconnect_max_s = o.Number("reconnect-max", c.reconnect_max_s);
  c.clock_file = o.Text("clock-file");
  c.metrics = o.Text("metrics");
  const std::pair<const char*, const std::string*> required[] = {
      {"serial", &c.serial}, {"broker", &c.broker}, {"site", &c.site}, {"crusher", &c.crusher}, {"spool", &c.spool}};
  for (const auto& [name, value] : required) {
    if (value->empty()) throw ConfigError(std::string("--") + name + " is required (see --help)");
  }
  if (!IsSupportedBaud(c.baud))
    throw ConfigError("--baud: " + std::to_string(c.baud) + " is not a supported rate (1200..921600, standard values)");
  RequireUri(c.broker);
  // The server and crusher.json refuse any other name, so a gateway publishing under one would
  // have every reading quarantined.
  for (const auto& [flag, value] : {std::pair{"--site", &c.site}, std::pair{"--crusher", &c.crusher}}) {
    if (!core::IsIdentifier(*value))
      throw ConfigError(std::string(flag) + ": '" + *value + "' must be " + std::string(core::kIdentifierRule) +
                        ", as crusher.json's names (it is an MQTT topic level)");
  }
  if (!c.metrics.empty()) {
    const size_t colon = c.metrics.rfind(':');
    if (colon == std::string::npos || colon == 0) throw ConfigError("--metrics: '" + c.metrics + "' must be HOST:PORT");
    try {
      (void)core::ParseWholeNumber("metrics", c.metrics.substr(colon + 1), 0, 65535);
    } catch (const core::UsageError& e) {
      throw ConfigError(e.what());
    }
  }
  if (!c.password.empty() && c.username.empty()) throw ConfigError("--password given without --username");
  if (c.reconnect_max_s < c.reconnect_min_s) throw ConfigError("--reconnect-max must not be below --reconnect-min");
  if (!c.tls_ca.empty() && access(c.tls_ca.c_str(), R_OK) != 0) throw ConfigError("--tls-ca: " + c.tls_ca + " cannot be read");
  if (c.gateway_id.empty()) {
    char host[256] = {};
    gethostname(host, sizeof host - 1);
    c.gateway_id = std::string("gw-") + (host[0] ? host : "unknown");
  }
  *config = c;
  return ParseResult::kRun;
}

}  // namespace lw::gateway
