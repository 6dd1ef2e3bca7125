#include "gateway/options.hpp"

#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "gateway/serial_port.hpp"

namespace lw::gateway {
namespace {

std::string Normalise(std::string key) {
  for (auto& c : key) {
    if (c == '_') c = '-';
  }
  return key;
}

int64_t ToInt(const std::string& name, const std::string& value) {
  try {
    size_t used = 0;
    const long long v = std::stoll(value, &used);
    if (used != value.size()) throw std::invalid_argument("trailing");
    return v;
  } catch (const std::exception&) {
    throw UsageError("--" + name + " '" + value + "' is not a whole number");
  }
}

void Apply(Options& o, const std::string& name, const std::string& value) {
  if (name == "serial") o.serial = value;
  else if (name == "baud") o.baud = static_cast<int>(ToInt(name, value));
  else if (name == "api-mode") o.api_mode = static_cast<int>(ToInt(name, value));
  else if (name == "broker") o.broker = value;
  else if (name == "site") o.site = value;
  else if (name == "crusher") o.crusher = value;
  else if (name == "spool") o.spool = value;
  else if (name == "username") o.username = value;
  else if (name == "password") o.password = value;
  else if (name == "tls-ca") o.tls_ca = value;
  else if (name == "gateway-id") o.gateway_id = value;
  else if (name == "spool-max") o.spool_max = ToInt(name, value);
  else if (name == "stats-interval") o.stats_interval_s = static_cast<int>(ToInt(name, value));
  else if (name == "republish-after") o.republish_after_s = static_cast<int>(ToInt(name, value));
  else throw UsageError("unknown option --" + name + " (see --help)");
}

void LoadConfig(Options& o, const std::string& path) {
  std::ifstream in(path);
  if (!in) throw UsageError("--config: cannot read '" + path + "'");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw UsageError("--config '" + path + "': not valid JSON: " + e.what());
  }
  if (!j.is_object()) throw UsageError("--config '" + path + "': must hold a JSON object");
  for (const auto& [key, value] : j.items()) {
    std::string text;
    if (value.is_string()) text = value.get<std::string>();
    else if (value.is_number_integer()) text = std::to_string(value.get<long long>());
    else throw UsageError("--config '" + path + "': \"" + key + "\" must be a string or a whole number");
    Apply(o, Normalise(key), text);
  }
}

}  // namespace

std::string HelpText() {
  return R"(linerwatch-gateway: XBee coordinator serial port -> MQTT, store and forward.

Usage: linerwatch-gateway --serial PATH --broker URI --site ID --crusher ID --spool FILE [options]

  --serial PATH          coordinator serial port (or a pty / any path)
  --baud N               9600 (default), 19200, 38400, 57600, 115200, 230400, 460800, 921600
  --api-mode 1|2         the coordinator's AP setting (default 2: escaped)
  --broker URI           tcp://host:1883 or ssl://host:8883
  --site ID --crusher ID topic root linerwatch/v1/{site}/{crusher}/
  --spool FILE           SQLite spool: records stay here until the server confirms its commit
  --spool-max N          records the spool holds before it stops acking sensors (default 1000000)
  --username U --password P   broker credentials
  --tls-ca FILE          CA certificate for ssl:// brokers
  --gateway-id ID        name in status and stats (default: host name)
  --stats-interval S     seconds between .../gateway/stats messages (default 60)
  --republish-after S    republish records the server has not confirmed after S seconds (default 30)
  --config FILE          JSON object with any of the options above; flags override it
  --help                 this text
)";
}

Options ParseOptions(const std::vector<std::string>& args) {
  Options o;
  // The config file first, wherever --config appears.
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "--config") {
      if (i + 1 >= args.size()) throw UsageError("--config needs a file");
      LoadConfig(o, args[i + 1]);
    }
  }
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--help" || a == "-h") {
      o.help = true;
      return o;
    }
    if (a.rfind("--", 0) != 0) throw UsageError("unexpected argument '" + a + "'");
    std::string name = a.substr(2), value;
    const size_t eq = name.find('=');
    if (eq != std::string::npos) {
      value = name.substr(eq + 1);
      name = name.substr(0, eq);
    } else {
      if (i + 1 >= args.size()) throw UsageError("--" + name + " needs a value");
      value = args[++i];
    }
    if (name == "config") continue;
    Apply(o, name, value);
  }
  if (o.serial.empty()) throw UsageError("--serial is required");
  if (o.broker.empty()) throw UsageError("--broker is required");
  if (o.site.empty()) throw UsageError("--site is required");
  if (o.crusher.empty()) throw UsageError("--crusher is required");
  if (o.spool.empty()) throw UsageError("--spool is required");
  for (const auto* id : {&o.site, &o.crusher}) {
    if (id->find_first_of("/+# ") != std::string::npos) throw UsageError("--site/--crusher '" + *id + "' must not contain '/', '+', '#' or spaces");
  }
  if (o.api_mode != 1 && o.api_mode != 2) throw UsageError("--api-mode must be 1 or 2");
  if (!IsSupportedBaud(o.baud)) throw UsageError("--baud " + std::to_string(o.baud) + " is not a supported rate");
  if (o.broker.rfind("tcp://", 0) != 0 && o.broker.rfind("ssl://", 0) != 0 && o.broker.rfind("mqtt://", 0) != 0 &&
      o.broker.rfind("mqtts://", 0) != 0) {
    throw UsageError("--broker '" + o.broker + "' must start with tcp:// or ssl://");
  }
  if (o.spool_max < 1) throw UsageError("--spool-max must be at least 1");
  if (o.stats_interval_s < 1 || o.republish_after_s < 1) throw UsageError("--stats-interval and --republish-after must be at least 1 second");
  return o;
}

}  // namespace lw::gateway
