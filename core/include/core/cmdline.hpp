#pragma once
/// Command-line handling shared by the host programs: `--name value`, `--name=value`, switches, and
/// `--config FILE` (a JSON object with the same names, '_' or '-') read first so flags override it.
#include <cstdint>
#include <functional>
#include <limits>
#include <set>
#include <stdexcept>
#include <string>
#include <type_traits>
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

/// `value` as a whole number in [min, max] (decimal, optional sign, nothing else); otherwise a
/// UsageError naming --name, the value and the allowed range. Nothing is truncated: a value beyond
/// the range (or beyond 64 bits) is refused, never wrapped into it.
int64_t ParseWholeNumber(const std::string& name, const std::string& value,
                         int64_t min = std::numeric_limits<int64_t>::min(),
                         int64_t max = std::numeric_limits<int64_t>::max());
/// The same for unsigned 64-bit values (a '-' sign is refused), e.g. random seeds.
uint64_t ParseUnsignedNumber(const std::string& name, const std::string& value,
                             uint64_t min = 0, uint64_t max = std::numeric_limits<uint64_t>::max());
/// ParseWholeNumber into an integer type T, within [min, max] (default: all of T).
template <typename T>
T ParseInteger(const std::string& name, const std::string& value, T min = std::numeric_limits<T>::min(),
               T max = std::numeric_limits<T>::max()) {
  static_assert(std::is_integral_v<T>, "ParseInteger needs an integer type");
  if constexpr (std::is_unsigned_v<T>) {
    return static_cast<T>(ParseUnsignedNumber(name, value, min, max));
  } else {
    return static_cast<T>(ParseWholeNumber(name, value, min, max));
  }
}
/// `value` as a finite number; UsageError naming --name otherwise.
double ParseNumber(const std::string& name, const std::string& value);
/// "true"/"false"/"1"/"0".
bool ParseBool(const std::string& name, const std::string& value);

}  // namespace lw::core
