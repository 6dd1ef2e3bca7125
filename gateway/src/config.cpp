#include "gateway/config.hpp"

#include "core/cmdline.hpp"
#include "gateway/messages.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <unistd.h>

namespace lw::gateway {
namespace {

using nlohmann::json;

enum class Kind { kString, kInt, kSeconds };

struct Option {
  const char* name;
  Kind kind;
  const char* help;
  int64_t min = 0, max = 0;  ///< kInt: the allowed range
};

constexpr Option kOptions[] = {
    {"serial", Kind::kString, "coordinator serial port, pty or path (required)"},
    {"baud", Kind::kInt, "serial baud rate (default 9600)", 1200, 921600},
    {"api-mode", Kind::kInt, "XBee API mode of the coordinator, 1 or 2 (default 2)", 1, 2},
    {"broker", Kind::kString, "MQTT broker URI, tcp://host:1883 or ssl://host:8883 (required)"},
    {"site", Kind::kString, "site id, topic level (required)"},
    {"crusher", Kind::kString, "crusher id, topic level (required)"},
    {"spool", Kind::kString, "SQLite spool file (required)"},
    {"username", Kind::kString, "MQTT user name"},
    {"password", Kind::kString, "MQTT password (requires --username)"},
    {"tls-ca", Kind::kString, "CA certificate file for ssl:// brokers"},
    {"gateway-id", Kind::kString, "gateway id in messages and MQTT client id (default gw-HOSTNAME)"},
    {"spool-max-records", Kind::kInt, "spool capacity in records (default 1000000)", 1, 1'000'000'000},
    {"window", Kind::kInt, "records per sensor awaiting a commit ack (default 1: strict order)", 1, static_cast<int64_t>(kMaxCommitAckSeqs)},
    {"max-devices", Kind::kInt, "device registry entries at most; new radios beyond are not registered (default 1000)", 1, 1'000'000},
    {"republish-after", Kind::kSeconds, "seconds before an unconfirmed record is republished (default 30)"},
    {"stats-interval", Kind::kSeconds, "seconds between gateway/stats messages (default 60)"},
    {"reconnect-min", Kind::kSeconds, "first reconnect delay, seconds (default 1)"},
    {"reconnect-max", Kind::kSeconds, "longest reconnect delay, seconds (default 60)"},
    {"clock-file", Kind::kString, "simulation only: stamp readings with the virtual time in this file"},
};

const Option* FindOption(std::string name) {
  for (char& c : name) {
    if (c == '_') c = '-';
  }
  for (const Option& o : kOptions) {
    if (name == o.name) return &o;
  }
  return nullptr;
}

void Assign(Config* c, const std::string& name, const std::string& text, const std::string& where) {
  const Option* opt = FindOption(name);
  if (!opt) throw ConfigError(where + ": unknown option '" + name + "' (see --help)");
  int64_t integer = 0;
  double seconds = 0;
  if (opt->kind == Kind::kInt) {
    try {
      integer = core::ParseWholeNumber(opt->name, text, opt->min, opt->max);  // never truncated into range
    } catch (const core::UsageError& e) {
      throw ConfigError(where.rfind("--", 0) == 0 ? std::string(e.what()) : where + ": " + e.what());
    }
  } else if (opt->kind == Kind::kSeconds) {
    size_t used = 0;
    try {
      seconds = std::stod(text, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != text.size() || !std::isfinite(seconds) || seconds <= 0) {
      throw ConfigError(where + ": '" + opt->name + "' must be a positive number of seconds, got '" + text + "'");
    }
  }
  const std::string n = opt->name;
  if (n == "serial") c->serial = text;
  else if (n == "baud") c->baud = static_cast<int>(integer);
  else if (n == "api-mode") c->api_mode = static_cast<int>(integer);
  else if (n == "broker") c->broker = text;
  else if (n == "site") c->site = text;
  else if (n == "crusher") c->crusher = text;
  else if (n == "spool") c->spool = text;
  else if (n == "username") c->username = text;
  else if (n == "password") c->password = text;
  else if (n == "tls-ca") c->tls_ca = text;
  else if (n == "gateway-id") c->gateway_id = text;
  else if (n == "spool-max-records") c->spool_max_records = static_cast<size_t>(integer);
  else if (n == "window") c->window = static_cast<size_t>(integer);
  else if (n == "max-devices") c->max_devices = static_cast<size_t>(integer);
  else if (n == "republish-after") c->republish_after_s = seconds;
  else if (n == "stats-interval") c->stats_interval_s = seconds;
  else if (n == "reconnect-min") c->reconnect_min_s = seconds;
  else if (n == "reconnect-max") c->reconnect_max_s = seconds;
  else if (n == "clock-file") c->clock_file = text;
}

void LoadFile(const std::string& path, std::map<std::string, std::string>* values) {
  std::ifstream in(path);
  if (!in) throw ConfigError("config " + path + ": cannot be read");
  std::stringstream text;
  text << in.rdbuf();
  json j;
  try {
    j = json::parse(text.str());
  } catch (const json::parse_error& e) {
    throw ConfigError("config " + path + ": invalid JSON: " + e.what());
  } catch (const json::exception& e) {  // a number out of range (1e999) is not a parse_error
    throw ConfigError("config " + path + ": invalid JSON: " + e.what());
  }
  if (!j.is_object()) throw ConfigError("config " + path + ": must be a JSON object of option names to values");
  for (const auto& [key, value] : j.items()) {
    const std::string where = "config " + path + ", key '" + key + "'";
    const Option* opt = FindOption(key);
    if (!opt) throw ConfigError("config " + path + ": unknown key '" + key + "' (see --help)");
    std::string v;
    if (value.is_string()) {
      if (opt->kind != Kind::kString) throw ConfigError(where + ": must be a number");
      v = value.get<std::string>();
    } else if (value.is_number_integer() && opt->kind != Kind::kString) {
      v = std::to_string(value.get<long long>());
    } else if (value.is_number() && opt->kind == Kind::kSeconds) {
      std::ostringstream os;
      os << value.get<double>();
      v = os.str();
    } else {
      throw ConfigError(where + ": must be " + (opt->kind == Kind::kString ? "a string" : "a number"));
    }
    (*values)[opt->name] = v;
  }
}

std::string RequireUri(const std::string& uri) {
  static const char* kSchemes[] = {"tcp://", "ssl://", "mqtt://", "mqtts://", "ws://", "wss://"};
  for (const char* s : kSchemes) {
    if (uri.rfind(s, 0) == 0 && uri.size() > std::string(s).size()) return uri;
  }
  throw ConfigError("--broker: '" + uri + "' is not a broker URI (tcp://host:port or ssl://host:port)");
}

bool IsTopicLevel(const std::string& s) {
  if (s.empty()) return false;
  for (char c : s) {
    if (c == '/' || c == '+' || c == '#' || c == '\0') return false;
  }
  return true;
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
  std::string s =
      "usage: linerwatch-gateway --serial PATH [--baud N] [--api-mode 1|2] --broker URI --site ID\n"
      "                          --crusher ID --spool FILE [--username U --password P] [--tls-ca FILE]\n"
      "                          [--gateway-id ID] [--config FILE] [options]\n"
      "Reads XBee API frames from the coordinator, spools every sensor record in SQLite, acks it to\n"
      "the sensor, publishes it on MQTT and keeps it until the server confirms it is committed.\n\n"
      "  --config FILE           JSON object with the same keys (flags override it)\n"
      "  --help                  this text\n";
  for (const Option& o : kOptions) {
    std::string flag = std::string("  --") + o.name;
    flag += o.kind == Kind::kString ? " S" : " N";
    if (flag.size() < 26) flag.resize(26, ' ');
    s += flag + o.help + "\n";
  }
  return s;
}

ParseResult ParseCommandLine(const std::vector<std::string>& args, Config* config) {
  std::map<std::string, std::string> flags;
  std::string config_file;
  for (size_t i = 1; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--help" || a == "-h") return ParseResult::kHelp;
    if (a.rfind("--", 0) != 0) throw ConfigError("unexpected argument '" + a + "' (options start with --; see --help)");
    std::string name = a.substr(2);
    std::string value;
    const size_t eq = name.find('=');
    if (eq != std::string::npos) {
      value = name.substr(eq + 1);
      name = name.substr(0, eq);
    } else {
      if (i + 1 >= args.size()) throw ConfigError("--" + name + " needs a value");
      value = args[++i];
    }
    if (name == "config") {
      config_file = value;
      continue;
    }
    const Option* opt = FindOption(name);
    if (!opt || name.find('_') != std::string::npos) throw ConfigError("unknown option --" + name + " (see --help)");
    flags[opt->name] = value;
  }
  Config c;
  std::map<std::string, std::string> merged;
  if (!config_file.empty()) LoadFile(config_file, &merged);
  for (const auto& [k, v] : flags) merged[k] = v;
  for (const auto& [k, v] : merged) {
    Assign(&c, k, v, flags.count(k) ? "--" + k : "config " + config_file + ", key '" + k + "'");
  }
  const std::pair<const char*, const std::string*> required[] = {
      {"serial", &c.serial}, {"broker", &c.broker}, {"site", &c.site}, {"crusher", &c.crusher}, {"spool", &c.spool}};
  for (const auto& [name, value] : required) {
    if (value->empty()) throw ConfigError(std::string("--") + name + " is required (see --help)");
  }
  if (!IsSupportedBaud(c.baud)) throw ConfigError("--baud: " + std::to_string(c.baud) + " is not a supported rate (1200..921600, standard values)");
  if (c.api_mode != 1 && c.api_mode != 2) throw ConfigError("--api-mode: must be 1 or 2, got " + std::to_string(c.api_mode));
  RequireUri(c.broker);
  if (!IsTopicLevel(c.site)) throw ConfigError("--site: '" + c.site + "' must be a non-empty MQTT topic level without '/', '+' or '#'");
  if (!IsTopicLevel(c.crusher)) throw ConfigError("--crusher: '" + c.crusher + "' must be a non-empty MQTT topic level without '/', '+' or '#'");
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
