#include "core/cmdline.hpp"

#include <charconv>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

namespace lw::core {
namespace {

std::string Normalise(std::string key) {
  for (auto& c : key) {
    if (c == '_') c = '-';
  }
  return key;
}

void ApplyConfigFile(const std::string& path, const std::function<void(const std::string&, const std::string&)>& apply) {
  std::ifstream in(path);
  if (!in) throw UsageError("--config: cannot read '" + path + "'");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw UsageError("--config '" + path + "': not valid JSON: " + e.what());
  } catch (const nlohmann::json::exception& e) {  // a number out of range (1e999) is not a parse_error
    throw UsageError("--config '" + path + "': not valid JSON: " + e.what());
  }
  if (!j.is_object()) throw UsageError("--config '" + path + "': must hold a JSON object");
  for (const auto& [key, value] : j.items()) {
    std::string text;
    if (value.is_string()) text = value.get<std::string>();
    else if (value.is_number_integer()) text = std::to_string(value.get<long long>());
    else if (value.is_number()) text = value.dump();
    else if (value.is_boolean()) text = value.get<bool>() ? "true" : "false";
    else throw UsageError("--config '" + path + "': \"" + key + "\" must be a string, a number or a boolean");
    apply(Normalise(key), text);
  }
}

}  // namespace

bool ParseCommandLine(const std::vector<std::string>& args, const std::set<std::string>& switches,
                      const std::function<void(const std::string&, const std::string&)>& apply) {
  for (const auto& a : args) {
    if (a == "--help" || a == "-h") return false;
  }
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "--config") {
      if (i + 1 >= args.size()) throw UsageError("--config needs a file");
      ApplyConfigFile(args[i + 1], apply);
    } else if (args[i].rfind("--config=", 0) == 0) {
      ApplyConfigFile(args[i].substr(9), apply);
    }
  }
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a.rfind("--", 0) != 0 || a.size() == 2) throw UsageError("unexpected argument '" + a + "'");
    std::string name = a.substr(2), value;
    const size_t eq = name.find('=');
    if (eq != std::string::npos) {
      value = name.substr(eq + 1);
      name = name.substr(0, eq);
    } else if (switches.count(name)) {
      value = "true";
    } else {
      if (i + 1 >= args.size()) throw UsageError("--" + name + " needs a value");
      value = args[++i];
    }
    if (name == "config") continue;
    apply(name, value);
  }
  return true;
}

namespace {

std::string Range(const std::string& lo, const std::string& hi) { return "[" + lo + ", " + hi + "]"; }

// Whole decimal digits with an optional sign, no spaces: what std::stoll would also take after
// leading blanks or before trailing junk is refused here.
template <typename T>
T ParseChecked(const std::string& name, const std::string& value, T min, T max) {
  const std::string allowed = "allowed: " + Range(std::to_string(min), std::to_string(max));
  const char* first = value.data();
  const char* last = value.data() + value.size();
  if (last - first > 1 && *first == '+' && first[1] != '-') ++first;  // from_chars takes no '+'
  T v{};
  const auto [end, ec] = std::from_chars(first, last, v);
  if (ec == std::errc::result_out_of_range && end == last) {
    throw UsageError("--" + name + " " + value + " is out of range (" + allowed + ")");
  }
  if (value.empty() || ec != std::errc() || end != last || first == last) {
    throw UsageError("--" + name + " '" + value + "' is not a whole number (" + allowed + ")");
  }
  if (v < min || v > max) throw UsageError("--" + name + " " + value + " is out of range (" + allowed + ")");
  return v;
}

}  // namespace

int64_t ParseWholeNumber(const std::string& name, const std::string& value, int64_t min, int64_t max) {
  return ParseChecked<int64_t>(name, value, min, max);
}

uint64_t ParseUnsignedNumber(const std::string& name, const std::string& value, uint64_t min, uint64_t max) {
  if (!value.empty() && value[0] == '-') {
    throw UsageError("--" + name + " " + value + " is out of range (allowed: " + Range(std::to_string(min), std::to_string(max)) + ")");
  }
  return ParseChecked<uint64_t>(name, value, min, max);
}

double ParseNumber(const std::string& name, const std::string& value) {
  try {
    size_t used = 0;
    const double v = std::stod(value, &used);
    if (used != value.size() || !std::isfinite(v)) throw std::invalid_argument("bad");
    return v;
  } catch (const std::exception&) {
    throw UsageError("--" + name + " '" + value + "' is not a number");
  }
}

bool ParseBool(const std::string& name, const std::string& value) {
  if (value == "true" || value == "1") return true;
  if (value == "false" || value == "0") return false;
  throw UsageError("--" + name + " '" + value + "' must be true or false");
}

}  // namespace lw::core
