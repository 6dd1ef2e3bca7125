#pragma once
/// Command-line handling shared by the host programs: `--name value`, `--name=value`, switches, and
/// `--config FILE` (a JSON object with the same names, '_' or '-') read first so flags override it.
#include <cstdint>
#include <functional>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace lw::core {

/// A bad command line or config file; what() is the one-line reason.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Calls `apply(name, value)` for every key of the --config file (strings, numbers and booleans
/// are passed as text) and then for every flag in order. `switches` take no value on the command
/// line (they get "true"). Returns false when --help or -h was given (nothing else is applied).
/// Throws UsageError on a missing value, a stray argument or an unreadable/invalid config file.
bool ParseCommandLine(const std::vector<std::string>& args, const std::set<std::string>& switches,
                      const std::function<void(const std::string& name, const std::string& value)>& apply);

/// `value` as a whole number; UsageError naming --name otherwise.
int64_t ParseWholeNumber(const std::string& name, const std::string& value);
/// `value` as a finite number; UsageError naming --name otherwise.
double ParseNumber(const std::string& name, const std::string& value);
/// "true"/"false"/"1"/"0".
bool ParseBool(const std::string& name, const std::string& value);

}  // namespace lw::core
