#pragma once
/// Configuration of linerwatch-gateway: command-line flags and/or a JSON file (--config FILE) with
/// the same keys (flag names without the dashes; "api-mode" and "api_mode" are both accepted).
/// Flags given on the command line win over the file.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace lw::gateway {

/// Bad input: the message names the flag or file key and the rule (one line).
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Config {
  std::string serial;  ///< serial device, pty or any readable path
  int baud = 9600;
  int api_mode = 2;    ///< XBee AP setting of the coordinator: 1 or 2
  std::string broker;  ///< tcp://host:port, ssl://host:port (mqtt:// and mqtts:// too)
  std::string site;
  std::string crusher;
  std::string spool;  ///< SQLite file
  std::string username;
  std::string password;
  std::string tls_ca;      ///< CA file for ssl:// brokers
  std::string gateway_id;  ///< defaults to "gw-" + host name
  size_t spool_max_records = 1'000'000;
  size_t window = 1;
  size_t max_batch = 64;      ///< records per reading message at most (when the server announces batches)
  size_t max_devices = 1000;  ///< device registry entries (address, sensor) at most
  double republish_after_s = 30;
  double stats_interval_s = 60;
  double reconnect_min_s = 1;
  double reconnect_max_s = 60;
  std::string clock_file;  ///< simulation: reading times come from this virtual clock file
  std::string metrics;     ///< HOST:PORT of the Prometheus /metrics endpoint; empty: none
};

enum class ParseResult { kRun, kHelp };

/// Parses argv (argv[0] is skipped). Throws ConfigError naming what was wrong.
ParseResult ParseCommandLine(const std::vector<std::string>& args, Config* config);

/// Text of --help.
std::string UsageText();

/// Baud rates the serial port accepts.
bool IsSupportedBaud(int baud);

}  // namespace lw::gateway
