#include "core/cmdline.hpp"

#include "core/json_unique.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>

namespace lw::core {
namespace {

std::string Dashes(std::string key) {
  for (auto& c : key) {
    if (c == '_') c = '-';
  }
  return key;
}

std::string NumberText(double v) {
  if (std::isinf(v)) return v < 0 ? "-inf" : "inf";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.15g", v);
  return buf;
}

/// Checks `text` as a value of `opt`, throwing a UsageError that names --opt and the value.
void CheckValue(const Option& opt, const std::string& text) {
  switch (opt.type) {
    case OptionType::kText:
      break;
    case OptionType::kWhole:
      if (opt.whole_unsigned)
        (void)ParseUnsignedNumber(opt.name, text);
      else
        (void)ParseWholeNumber(opt.name, text, opt.min, opt.max);
      break;
    case OptionType::kNumber:
      (void)ParseNumber(opt.name, text, opt.range);
      break;
    case OptionType::kSwitch:
      (void)ParseBool(opt.name, text);
      break;
  }
}

struct Collected {
  std::map<std::string, std::vector<std::string>> values;  // option name -> texts in order
  std::string positional;
};

/// The config file's values as text, checked for type; `where` prefixes every error.
void ReadConfigFile(const OptionTable& table, const std::string& path, Collected* out, nlohmann::json* other) {
  const std::string where = "config " + path;
  std::ifstream in(path);
  if (!in) throw ConfigFileError(where + ": cannot be read");
  nlohmann::json j;
  try {
    j = ParseJsonUniqueKeys(in);
  } catch (const DuplicateJsonKey& e) {
    throw ConfigFileError(where + ": " + e.what());
  } catch (const nlohmann::json::exception& e) {  // parse_error, and out_of_range for 1e999
    throw ConfigFileError(where + ": invalid JSON: " + e.what());
  }
  if (!j.is_object()) throw ConfigFileError(where + ": must be a JSON object of option names to values");
  for (const auto& [key, value] : j.items()) {
    const std::string name = Dashes(key);
    const std::string at = where + ", key '" + name + "'";
    if (!table.positional_key.empty() && name == Dashes(table.positional_key)) {
      if (!value.is_string()) throw ConfigFileError(at + ": must be a string");
      out->positional = value.get<std::string>();
      continue;
    }
    const Option* opt = table.Find(name);
    if (!opt) {
      if (table.other_config_keys) {
        (*other)[key] = value;
        continue;
      }
      throw ConfigFileError(where + ": unknown key '" + key + "' (see --help)");
    }
    std::vector<nlohmann::json> items;
    if (value.is_array() && opt->repeatable)
      items.assign(value.begin(), value.end());
    else
      items.push_back(value);
    std::vector<std::string>& texts = out->values[opt->name];
    for (const nlohmann::json& v : items) {
      std::string text;
      if (opt->type == OptionType::kSwitch) {
        if (v.is_boolean())
          text = v.get<bool>() ? "true" : "false";
        else if (v.is_string())
          text = v.get<std::string>();
        else
          throw ConfigFileError(at + ": must be true or false");
      } else if (v.is_string()) {
        text = v.get<std::string>();
      } else if (v.is_number_integer()) {
        text = v.is_number_unsigned() ? std::to_string(v.get<uint64_t>()) : std::to_string(v.get<int64_t>());
      } else if (v.is_number() && opt->type != OptionType::kWhole) {
        text = NumberText(v.get<double>());
      } else {
        throw ConfigFileError(at + ": must be " +
                              (opt->type == OptionType::kText    ? "a string"
                               : opt->type == OptionType::kWhole ? "a whole number"
                                                                 : "a number"));
      }
      try {
        CheckValue(*opt, text);
      } catch (const UsageError& e) {
        throw ConfigFileError(at + ": " + e.what());
      }
      texts.push_back(text);
    }
  }
}

}  // namespace

std::string NumberRange::Text() const {
  // An infinite end is never in the range: written open.
  return std::string(min_open || std::isinf(min) ? "(" : "[") + NumberText(min) + ", " + NumberText(max) +
         (max_open || std::isinf(max) ? ")" : "]");
}

Option Option::Text(std::string name, std::string value_name, std::string help) {
  Option o;
  o.name = std::move(name);
  o.value_name = std::move(value_name);
  o.help = std::move(help);
  return o;
}

Option Option::Whole(std::string name, std::string value_name, int64_t min, int64_t max, std::string help) {
  Option o = Text(std::move(name), std::move(value_name), std::move(help));
  o.type = OptionType::kWhole;
  o.min = min;
  o.max = max;
  return o;
}

Option Option::Unsigned(std::string name, std::string value_name, std::string help) {
  Option o = Whole(std::move(name), std::move(value_name), 0, std::numeric_limits<int64_t>::max(), std::move(help));
  o.whole_unsigned = true;
  return o;
}

Option Option::Number(std::string name, std::string value_name, NumberRange range, std::string help) {
  Option o = Text(std::move(name), std::move(value_name), std::move(help));
  o.type = OptionType::kNumber;
  o.range = range;
  return o;
}

Option Option::Switch(std::string name, std::string help) {
  Option o = Text(std::move(name), "", std::move(help));
  o.type = OptionType::kSwitch;
  return o;
}

Option Option::Required() const {
  Option o = *this;
  o.required = true;
  return o;
}

Option Option::Repeatable() const {
  Option o = *this;
  o.repeatable = true;
  return o;
}

const Option* OptionTable::Find(const std::string& name) const {
  const std::string key = Dashes(name);
  for (const Option& o : options) {
    if (o.name == key) return &o;
  }
  return nullptr;
}

std::string OptionTable::Help(size_t column, size_t indent, bool builtins) const {
  std::string s;
  const auto line = [&](const std::string& flag, const std::string& help) {
    std::string head = std::string(indent, ' ') + flag;
    head += head.size() + 1 < column ? std::string(column - head.size(), ' ') : "\n" + std::string(column, ' ');
    size_t start = 0;
    while (true) {
      const size_t nl = help.find('\n', start);
      s += head + help.substr(start, nl == std::string::npos ? std::string::npos : nl - start) + "\n";
      if (nl == std::string::npos) break;
      head = std::string(column, ' ');
      start = nl + 1;
    }
  };
  for (const Option& o : options) line("--" + o.name + (o.value_name.empty() ? "" : " " + o.value_name), o.help);
  if (builtins) {
    line("--config FILE", "JSON object with any of these options (\"name\": value); flags override it");
    line("--help", "this text");
  }
  return s;
}

std::string OptionTable::Synopsis(size_t indent, size_t width) const {
  std::vector<std::string> words;
  for (const Option& o : options) {
    const std::string flag = "--" + o.name + (o.value_name.empty() ? "" : " " + o.value_name);
    words.push_back(o.required ? flag : "[" + flag + "]");
  }
  words.push_back("[--config FILE]");
  std::string s, line;
  for (const std::string& w : words) {
    if (!line.empty() && indent + line.size() + 1 + w.size() >= width) {
      s += line + "\n" + std::string(indent, ' ');
      line.clear();
    }
    line += (line.empty() ? "" : " ") + w;
  }
  return s + line;
}

std::string ParsedOptions::Key(std::string name) {
  return Dashes(std::move(name));
}

const ParsedOptions::Value& ParsedOptions::Get(const std::string& name) const {
  const auto it = values_.find(Key(name));
  if (it == values_.end()) throw std::logic_error("option --" + name + " not given (check Has first)");
  return it->second;
}

const Option& ParsedOptions::Spec(const std::string& name) const {
  for (const Option& o : options_) {
    if (o.name == Key(name)) return o;
  }
  throw std::logic_error("no option --" + name + " in the table");
}

std::string ParsedOptions::Text(const std::string& name, const std::string& fallback) const {
  (void)Spec(name);
  return Has(name) ? Get(name).texts.back() : fallback;
}

std::vector<std::string> ParsedOptions::Texts(const std::string& name) const {
  (void)Spec(name);
  return Has(name) ? Get(name).texts : std::vector<std::string>{};
}

int64_t ParsedOptions::Checked(const std::string& name) const {
  const Option& o = Spec(name);
  if (o.type != OptionType::kWhole) throw std::logic_error("option --" + name + " is not a whole number");
  return ParseWholeNumber(o.name, Get(name).texts.back(), o.min, o.max);
}

uint64_t ParsedOptions::CheckedUnsigned(const std::string& name) const {
  const Option& o = Spec(name);
  if (o.type != OptionType::kWhole) throw std::logic_error("option --" + name + " is not a whole number");
  if (o.whole_unsigned) return ParseUnsignedNumber(o.name, Get(name).texts.back());
  return ParseUnsignedNumber(o.name, Get(name).texts.back(), static_cast<uint64_t>(std::max<int64_t>(o.min, 0)),
                             static_cast<uint64_t>(std::max<int64_t>(o.max, 0)));
}

int64_t ParsedOptions::Whole(const std::string& name, int64_t fallback) const {
  return Integer<int64_t>(name, fallback);
}

double ParsedOptions::Number(const std::string& name, double fallback) const {
  const Option& o = Spec(name);
  if (o.type != OptionType::kNumber) throw std::logic_error("option --" + name + " is not a number");
  return Has(name) ? ParseNumber(o.name, Get(name).texts.back(), o.range) : fallback;
}

bool ParsedOptions::Switch(const std::string& name) const {
  const Option& o = Spec(name);
  if (o.type != OptionType::kSwitch) throw std::logic_error("option --" + name + " is not a switch");
  return Has(name) && ParseBool(o.name, Get(name).texts.back());
}

std::string ParsedOptions::Where(const std::string& name) const {
  return Has(name) ? Get(name).where : "--" + Key(name);
}

ParsedOptions ParseOptions(const OptionTable& table, const std::vector<std::string>& args) {
  ParsedOptions parsed;
  parsed.options_ = table.options;
  for (const auto& a : args) {
    if (a == "--help" || a == "-h") {
      parsed.help_ = true;
      return parsed;
    }
  }
  // The command line first (so its errors come first), then the config file under it.
  Collected flags;
  std::string config_file;
  bool has_config = false, has_positional = false;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a.rfind("--", 0) != 0 || a.size() == 2) {
      if (table.positional.empty()) throw UsageError("unexpected argument '" + a + "' (see --help)");
      if (has_positional) throw UsageError("unexpected argument '" + a + "' (one " + table.positional + " only)");
      flags.positional = a;
      has_positional = true;
      continue;
    }
    std::string name = Dashes(a.substr(2)), value;
    const size_t eq = name.find('=');
    const bool inline_value = eq != std::string::npos;
    if (inline_value) {
      value = a.substr(2 + eq + 1);
      name = name.substr(0, eq);
    }
    const Option* opt = table.Find(name);
    if (name != "config" && !opt) throw UsageError("unknown option --" + name + " (see --help)");
    if (!inline_value) {
      if (opt && opt->type == OptionType::kSwitch) {
        value = "true";
      } else {
        if (i + 1 >= args.size()) throw UsageError("--" + name + " needs a value");
        value = args[++i];
      }
    }
    if (name == "config") {
      if (has_config) throw UsageError("--config is given twice ('" + config_file + "' and '" + value + "'); it takes one file");
      config_file = value;
      has_config = true;
      continue;
    }
    std::vector<std::string>& texts = flags.values[opt->name];
    if (!texts.empty() && !opt->repeatable) {
      throw UsageError("--" + opt->name + " is given twice ('" + texts.back() + "' and '" + value + "'); it takes one value");
    }
    CheckValue(*opt, value);
    texts.push_back(value);
  }
  Collected file;
  if (has_config) ReadConfigFile(table, config_file, &file, &parsed.other_config_);
  for (const auto& [name, texts] : file.values) {
    if (!flags.values.count(name))
      parsed.values_[name] = {texts, "config " + config_file + ", key '" + name + "'"};
    else if (table.Find(name)->repeatable)
      parsed.values_[name].texts = texts;  // the file's first
  }
  for (const auto& [name, texts] : flags.values) {
    ParsedOptions::Value& v = parsed.values_[name];
    v.texts.insert(v.texts.end(), texts.begin(), texts.end());
    v.where = "--" + name;
  }
  parsed.positional_ = has_positional ? flags.positional : file.positional;
  for (const Option& o : table.options) {
    if (o.required && !parsed.Has(o.name)) throw UsageError("--" + o.name + " is required (see --help)");
  }
  return parsed;
}

namespace {

std::string Range(const std::string& lo, const std::string& hi) {
  return "[" + lo + ", " + hi + "]";
}

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
    throw UsageError("--" + name + " " + value + " is out of range (allowed: " + Range(std::to_string(min), std::to_string(max)) +
                     ")");
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

double ParseNumber(const std::string& name, const std::string& value, const NumberRange& range) {
  const double v = ParseNumber(name, value);
  if (!range.Contains(v)) throw UsageError("--" + name + " " + value + " is out of range (allowed: " + range.Text() + ")");
  return v;
}

bool ParseBool(const std::string& name, const std::string& value) {
  if (value == "true" || value == "1") return true;
  if (value == "false" || value == "0") return false;
  throw UsageError("--" + name + " '" + value + "' must be true or false");
}

}  // namespace lw::core
