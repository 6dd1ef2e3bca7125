#pragma once
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace lw::gateway {

/// A bad command line or config file; what() is the one-line reason.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Options {
  std::string serial;
  int baud = 9600;
  int api_mode = 2;
  std::string broker;
  std::string site;
  std::string crusher;
  std::string spool;
  std::string username;
  std::string password;
  std::string tls_ca;
  std::string gateway_id;
  int64_t spool_max = 1000000;
  int stats_interval_s = 60;
  int republish_after_s = 30;
  bool help = false;
};

/// Parses flags; `--config FILE` (JSON object with the same names, '-' or '_') is read first and
/// flags override it. Throws UsageError naming the option and the rule.
Options ParseOptions(const std::vector<std::string>& args);
std::string HelpText();

}  // namespace lw::gateway
