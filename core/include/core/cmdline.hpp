#pragma once
/// The one command-line parser of the host programs (linerwatch-gateway, linerwatch-server,
/// linerwatch-sim, linerwatch, the bench programs).
///
/// A program describes its options once, in a table of Option rows; the table drives parsing,
/// the checks of every value and the option lines of --help:
///
///   const core::OptionTable table{{
///       core::Option::Text("serial", "PATH", "coordinator serial port").Required(),
///       core::Option::Whole("baud", "N", 1200, 921600, "serial baud rate (default 9600)"),
///       core::Option::Number("republish-after", "S", core::NumberRange::Positive(), "seconds ..."),
///       core::Option::Switch("quiet", "no progress lines")}};
///   const core::ParsedOptions o = core::ParseOptions(table, args);   // args without argv[0]
///   if (o.help()) print(table.Help());
///   const int baud = o.Integer<int>("baud", 9600);
///
/// Syntax: `--name value`, `--name=value`, switches as `--name` (or `--name=true|false`), and
/// `--config FILE`: a JSON object with the same names (spelled with '-' or '_'), read first so
/// that flags override it. `--help` or `-h` anywhere asks for help and nothing else is checked.
///
/// Every error is a UsageError whose what() is one line naming the flag (or the config file and
/// key) and the bad value: an unknown flag, a missing value, a flag given twice that takes one
/// value, a missing required flag, a number that is not one or is out of its range. Everything
/// wrong with the --config file (unreadable, not a JSON object, an unknown key, a value of the
/// wrong type or out of range) is a ConfigFileError, a kind of UsageError.
#include <cstdint>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
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

/// Something wrong with the --config file (a kind of UsageError, for programs that report a bad
/// file differently from a bad flag).
class ConfigFileError : public UsageError {
 public:
  using UsageError::UsageError;
};

/// The allowed values of a kNumber option: [min, max], either end open when asked.
struct NumberRange {
  double min = -std::numeric_limits<double>::infinity();
  double max = std::numeric_limits<double>::infinity();
  bool min_open = false;
  bool max_open = false;

  static NumberRange Any() { return {}; }
  /// (0, inf): above zero.
  static NumberRange Positive() { return {0, std::numeric_limits<double>::infinity(), true, false}; }
  bool Contains(double v) const { return (min_open ? v > min : v >= min) && (max_open ? v < max : v <= max); }
  /// "[0, 1)", "(0, 3650]".
  std::string Text() const;
};

enum class OptionType {
  kText,    ///< any string
  kWhole,   ///< a whole number in [min, max] (core::ParseWholeNumber)
  kNumber,  ///< a finite number in `range` (core::ParseNumber)
  kSwitch,  ///< no value on the command line; true/false in a config file
};

/// One row of a program's option table.
struct Option {
  std::string name;  ///< without dashes, words joined by '-': "api-mode"
  OptionType type = OptionType::kText;
  std::string value_name;                             ///< in --help and the synopsis: "--baud N" ("" for switches)
  std::string help;                                   ///< one line of --help; '\n' starts an indented continuation line
  bool required = false;                              ///< ParseOptions fails naming it when it is missing
  bool repeatable = false;                            ///< may be given several times (a config file may give a JSON array)
  int64_t min = std::numeric_limits<int64_t>::min();  ///< kWhole
  int64_t max = std::numeric_limits<int64_t>::max();  ///< kWhole
  bool whole_unsigned = false;                        ///< kWhole over all of uint64_t ([0, 2^64 - 1]) instead of min..max
  NumberRange range;                                  ///< kNumber

  static Option Text(std::string name, std::string value_name, std::string help);
  static Option Whole(std::string name, std::string value_name, int64_t min, int64_t max, std::string help);
  /// A kWhole option over all of uint64_t (random seeds).
  static Option Unsigned(std::string name, std::string value_name, std::string help);
  static Option Number(std::string name, std::string value_name, NumberRange range, std::string help);
  static Option Switch(std::string name, std::string help);
  Option Required() const;
  Option Repeatable() const;
};

/// A program's (or a subcommand's) options.
struct OptionTable {
  OptionTable() = default;
  explicit OptionTable(std::vector<Option> rows, std::string positional_name = "", std::string positional_config_key = "",
                       bool keep_other_config_keys = false)
      : options(std::move(rows)),
        positional(std::move(positional_name)),
        positional_key(std::move(positional_config_key)),
        other_config_keys(keep_other_config_keys) {}

  std::vector<Option> options;
  /// The name of the one positional argument in --help ("BUNDLE"); empty: none is accepted.
  std::string positional;
  /// The config-file key that gives the positional argument ("bundle").
  std::string positional_key;
  /// Config-file keys that are not options are kept in ParsedOptions::other_config() instead of
  /// being refused (linerwatch-sim campaign passes them to the campaign spec).
  bool other_config_keys = false;

  const Option* Find(const std::string& name) const;  ///< '_' and '-' are the same
  /// The option lines of --help, each flag `indent` spaces in and its text at `column`;
  /// `--config FILE` and `--help` last unless `builtins` is false.
  std::string Help(size_t column = 24, size_t indent = 2, bool builtins = true) const;
  /// "--serial PATH [--baud N] [--quiet] [--config FILE]": required flags bare, others in
  /// brackets, for a line whose first `indent` columns the caller fills ("usage: prog "); wrapped
  /// before column `width`, continuation lines indented by `indent` spaces.
  std::string Synopsis(size_t indent = 0, size_t width = 100) const;
};

/// The values of one command line (and its config file), all checked against the table.
class ParsedOptions {
 public:
  /// --help or -h was given: nothing else was parsed.
  bool help() const { return help_; }
  bool Has(const std::string& name) const { return values_.count(Key(name)) > 0; }
  /// The value (the last one of a repeatable option), or `fallback` when not given.
  std::string Text(const std::string& name, const std::string& fallback = "") const;
  /// Every value in order: the config file's first, then the command line's.
  std::vector<std::string> Texts(const std::string& name) const;
  int64_t Whole(const std::string& name, int64_t fallback) const;
  template <typename T>
  T Integer(const std::string& name, T fallback) const {
    static_assert(std::is_integral_v<T>, "Integer needs an integer type");
    if (!Has(name)) return fallback;
    if constexpr (std::is_unsigned_v<T>) {
      return static_cast<T>(CheckedUnsigned(name));
    } else {
      return static_cast<T>(Checked(name));
    }
  }
  double Number(const std::string& name, double fallback) const;
  bool Switch(const std::string& name) const;
  /// Where the value came from, for errors found after parsing: "--baud" or
  /// "config FILE, key 'baud'".
  std::string Where(const std::string& name) const;
  /// The positional argument (or the config file's positional_key), empty when not given.
  const std::string& positional() const { return positional_; }
  /// Config-file keys that are not options, as written (OptionTable::other_config_keys).
  const nlohmann::json& other_config() const { return other_config_; }

 private:
  friend ParsedOptions ParseOptions(const OptionTable& table, const std::vector<std::string>& args);
  struct Value {
    std::vector<std::string> texts;
    std::string where;
  };
  static std::string Key(std::string name);
  const Value& Get(const std::string& name) const;
  const Option& Spec(const std::string& name) const;
  // kWhole values (already checked against the table when parsed).
  int64_t Checked(const std::string& name) const;
  uint64_t CheckedUnsigned(const std::string& name) const;

  bool help_ = false;
  std::vector<Option> options_;
  std::map<std::string, Value> values_;
  std::string positional_;
  nlohmann::json other_config_ = nlohmann::json::object();
};

/// Parses `args` (without the program name) against `table`. Throws UsageError (see above).
ParsedOptions ParseOptions(const OptionTable& table, const std::vector<std::string>& args);

/// `value` as a whole number in [min, max] (decimal, optional sign, nothing else); otherwise a
/// UsageError naming --name, the value and the allowed range. Nothing is truncated: a value beyond
/// the range (or beyond 64 bits) is refused, never wrapped into it.
int64_t ParseWholeNumber(const std::string& name, const std::string& value, int64_t min = std::numeric_limits<int64_t>::min(),
                         int64_t max = std::numeric_limits<int64_t>::max());
/// The same for unsigned 64-bit values (a '-' sign is refused), e.g. random seeds.
uint64_t ParseUnsignedNumber(const std::string& name, const std::string& value, uint64_t min = 0,
                             uint64_t max = std::numeric_limits<uint64_t>::max());
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
/// `value` as a finite number within `range`; UsageError naming --name, the value and the range.
double ParseNumber(const std::string& name, const std::string& value, const NumberRange& range);
/// "true"/"false"/"1"/"0".
bool ParseBool(const std::string& name, const std::string& value);

}  // namespace lw::core
