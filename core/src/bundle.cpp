#include "core/bundle.hpp"

#include "core/identifier.hpp"
#include "core/json_unique.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>

namespace lw::core {
namespace {

using nlohmann::json;

std::string Trim(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  size_t i = 0;
  while (i < s.size() && std::isspace(static_cast<unsigned char>(s[i]))) ++i;
  return s.substr(i);
}

std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> out;
  std::string cell;
  bool quoted = false;
  for (char c : line) {
    if (c == '"') {
      quoted = !quoted;
    } else if (c == ',' && !quoted) {
      out.push_back(Trim(cell));
      cell.clear();
    } else if (c != '\r') {
      cell += c;
    }
  }
  out.push_back(Trim(cell));
  return out;
}

/// A value in a message: as short as it reads ("120", "119.5", "1e+308").
std::string Number(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.10g", v);
  return b;
}

double ParseNumber(const std::string& text, const std::string& file, size_t line, const std::string& column) {
  // Decimal notation only: strtod also reads hex ("0x10" as 16), "inf" and "nan", none of which a
  // sensor or a spreadsheet export means as a number.
  if (text.find_first_not_of("+-.0123456789eE") != std::string::npos)
    throw InputError(file, line, column + " '" + text + "' is not a number (decimal notation only, e.g. 119 or 1.2e2)");
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end == text.c_str() || *end != '\0')
    throw InputError(file, line, column + " '" + text + "' is not a number");
  if (!std::isfinite(v)) throw InputError(file, line, column + " '" + text + "' is not finite");
  return v;
}

TimePoint ParseTime(const std::string& text, const std::string& file, size_t line, const std::string& column) {
  const auto t = ParseIsoTime(text);
  if (!t) throw InputError(file, line, column + " '" + text + "' is not an ISO-8601 time (e.g. 2026-03-01T12:00:00Z)");
  // Absurd dates are input errors, not data.
  const auto y = static_cast<int>(std::chrono::year_month_day{std::chrono::floor<std::chrono::days>(*t)}.year());
  if (y < 1990 || y > 2200) throw InputError(file, line, column + " '" + text + "' is outside 1990-2200");
  return *t;
}

// Reads a CSV file with a header; calls row(cells, line) for each data row.
template <typename F>
void ReadCsv(const std::filesystem::path& path, const std::vector<std::string>& required, F row,
             std::map<std::string, size_t>* columns) {
  const std::string file = path.filename().string();
  std::ifstream in(path);
  if (!in) throw InputError(file, 0, "cannot open '" + path.string() + "'");
  std::string line;
  if (!std::getline(in, line)) throw InputError(file, 1, "empty file: a header line is required");
  if (line.size() >= 3 && static_cast<unsigned char>(line[0]) == 0xEF) line = line.substr(3);  // UTF-8 BOM
  const auto header = SplitCsv(line);
  columns->clear();
  for (size_t i = 0; i < header.size(); ++i) (*columns)[header[i]] = i;
  for (const auto& r : required) {
    if (!columns->count(r)) {
      std::string need;
      for (const auto& q : required) need += (need.empty() ? "" : ",") + q;
      throw InputError(file, 1, "header lacks column '" + r + "' (required: " + need + ")");
    }
  }
  size_t lineno = 1;
  while (std::getline(in, line)) {
    ++lineno;
    if (Trim(line).empty()) continue;
    const auto cells = SplitCsv(line);
    if (cells.size() < header.size()) {
      throw InputError(file, lineno,
                       "has " + std::to_string(cells.size()) + " columns, the header has " + std::to_string(header.size()));
    }
    row(cells, lineno);
  }
}

template <typename T>
T Get(const json& j, const char* key, const std::string& where, const std::string& file) {
  if (!j.contains(key)) throw InputError(file, 0, where + " lacks \"" + key + "\"");
  try {
    return j.at(key).get<T>();
  } catch (const json::exception&) {
    throw InputError(file, 0, where + " \"" + key + "\" has the wrong type");
  }
}

/// crusher.json's "thinnest_area": every key optional, each out-of-range value refused by its name.
ThinnestAreaConfig ParseThinnestArea(const json& j, double thickness_new_mm, const std::string& file) {
  if (!j.is_object()) throw InputError(file, 0, "\"thinnest_area\" must be an object");
  ThinnestAreaConfig t;
  const std::string where = "thinnest_area";
  if (j.contains("band_half_width_mm")) {
    t.band_half_width_mm = Get<double>(j, "band_half_width_mm", where, file);
    if (!(t.band_half_width_mm > 0) || t.band_half_width_mm > thickness_new_mm)
      throw InputError(file, 0, "thinnest_area.band_half_width_mm must be in (0, thickness_new_mm]");
  }
  if (j.contains("patches_m")) {
    t.patches_m = Get<std::vector<double>>(j, "patches_m", where, file);
    if (t.patches_m.empty() || t.patches_m.size() > 16)
      throw InputError(file, 0, "thinnest_area.patches_m must list 1-16 patch sizes");
    for (size_t k = 0; k < t.patches_m.size(); ++k) {
      if (!(t.patches_m[k] >= 0.01 && t.patches_m[k] <= 10.0))
        throw InputError(file, 0, "thinnest_area.patches_m values must be in [0.01, 10] m");
      if (k > 0 && !(t.patches_m[k] > t.patches_m[k - 1]))
        throw InputError(file, 0, "thinnest_area.patches_m must be increasing (smallest first)");
    }
  }
  if (j.contains("sensor_reach_m")) {
    t.sensor_reach_m = Get<double>(j, "sensor_reach_m", where, file);
    if (!(t.sensor_reach_m >= 0 && t.sensor_reach_m <= 10.0))
      throw InputError(file, 0, "thinnest_area.sensor_reach_m must be in [0, 10] m");
  }
  return t;
}

/// crusher.json's "setting": every key optional, an unknown key or an out-of-range value refused by its name.
SettingConfig ParseSetting(const json& j, const std::string& file) {
  if (!j.is_object()) throw InputError(file, 0, "\"setting\" must be an object");
  SettingConfig out;
  const std::string where = "setting";
  for (const auto& [key, value] : j.items())
    if (key != "css_mm" && key != "ring_height_m")
      throw InputError(file, 0, "setting." + key + " is not a setting key (they are css_mm, ring_height_m)");
  if (j.contains("css_mm")) {
    out.css_mm = Get<double>(j, "css_mm", where, file);
    if (!(*out.css_mm > 0 && *out.css_mm <= 1000)) throw InputError(file, 0, "setting.css_mm must be in (0, 1000] mm");
  }
  if (j.contains("ring_height_m")) {
    out.ring_height_m = Get<double>(j, "ring_height_m", where, file);
    if (!(out.ring_height_m >= 0.01 && out.ring_height_m <= 2.0))
      throw InputError(file, 0, "setting.ring_height_m must be in [0.01, 2] m");
  }
  return out;
}

/// One rule object of "alarms" over `rule`: only the keys of its spec, each checked by its name.
AlarmRule ParseAlarmRule(const json& j, const AlarmRuleSpec& spec, AlarmRule rule, const std::string& file) {
  const std::string where = std::string("alarms.") + spec.name;
  if (!j.is_object()) throw InputError(file, 0, where + " must be an object");
  for (const auto& [key, value] : j.items()) {
    const bool known = key == "enabled" || key == "severity" || (spec.threshold_key && key == spec.threshold_key) ||
                       (spec.hysteresis_key && key == spec.hysteresis_key);
    if (!known) {
      std::string keys = "enabled, severity";
      for (const char* k : {spec.threshold_key, spec.hysteresis_key})
        if (k) keys += std::string(", ") + k;
      throw InputError(file, 0, where + "." + key + " is not a setting of this rule (it has " + keys + ")");
    }
  }
  if (j.contains("enabled")) rule.enabled = Get<bool>(j, "enabled", where, file);
  if (j.contains("severity")) {
    rule.severity = Get<std::string>(j, "severity", where, file);
    if (rule.severity != "info" && rule.severity != "warning" && rule.severity != "critical")
      throw InputError(file, 0, where + ".severity '" + rule.severity + "' must be info, warning or critical");
  }
  const auto number = [&](const char* key, double* out) {
    if (!key || !j.contains(key)) return;
    *out = Get<double>(j, key, where, file);
    if (!(*out >= 0 && *out <= spec.max))
      throw InputError(file, 0, where + "." + key + " must be in [0, " + Number(spec.max) + "]");
  };
  number(spec.threshold_key, &rule.threshold);
  number(spec.hysteresis_key, &rule.hysteresis);
  // These two clear below their threshold (threshold - hysteresis): below zero, never.
  const std::string name = spec.name;
  if ((name == "sensor_silent" || name == "rejected_rate" || name == "setting_open") && rule.hysteresis > rule.threshold)
    throw InputError(file, 0, where + "." + spec.hysteresis_key + " must be at most " + spec.threshold_key);
  return rule;
}

}  // namespace

const std::vector<AlarmRuleSpec>& AlarmRuleSpecs() {
  static const std::vector<AlarmRuleSpec> specs = {
      {"thinnest_area", "below_mm", "hysteresis_mm", 10, 2, "warning", kMaxThicknessMm},
      {"reline_due", "within_days", "hysteresis_days", 30, 2, "warning", 3650},
      {"overdue", nullptr, "hysteresis_mm", 0, 2, "critical", 100},
      {"sensor_silent", "hours", "hysteresis_hours", 24, 12, "warning", 8760},
      {"battery_low", "below_mv", "hysteresis_mv", 3300, 100, "warning", 10000},
      {"gateway_offline", "minutes", nullptr, 10, 0, "critical", 10080},
      {"unsupported", nullptr, nullptr, 0, 0, "info", 0},
      {"rejected_rate", "per_hour", "hysteresis_per_hour", 10, 5, "warning", 1e6},
      {"setting_open", "above_mm", "hysteresis_mm", 20, 2, "warning", kMaxThicknessMm, false},
  };
  return specs;
}

const AlarmRule& AlarmConfig::Rule(const std::string& name) const {
  const auto& specs = AlarmRuleSpecs();
  for (size_t k = 0; k < specs.size() && k < rules.size(); ++k)
    if (name == specs[k].name) return rules[k];
  throw std::out_of_range("no alarm rule '" + name + "'");
}

AlarmConfig DefaultAlarmConfig(const CrusherConfig& config) {
  AlarmConfig out;
  for (const AlarmRuleSpec& s : AlarmRuleSpecs())
    out.rules.push_back({s.enabled_by_default, s.severity, s.threshold, s.hysteresis});
  out.rules.front().threshold = config.thickness_min_mm + AlarmRuleSpecs().front().threshold;
  return out;
}

AlarmConfig ParseAlarmConfig(const json& alarms, const AlarmConfig& base, const std::string& file) {
  if (!alarms.is_object()) throw InputError(file, 0, "\"alarms\" must be an object");
  const auto& specs = AlarmRuleSpecs();
  AlarmConfig out = base;
  for (const auto& [name, rule] : alarms.items()) {
    size_t k = 0;
    while (k < specs.size() && name != specs[k].name) ++k;
    if (k == specs.size()) {
      std::string names;
      for (const AlarmRuleSpec& s : specs) names += (names.empty() ? "" : ", ") + std::string(s.name);
      throw InputError(file, 0, "alarms." + name + " is not an alarm rule (the rules: " + names + ")");
    }
    out.rules[k] = ParseAlarmRule(rule, specs[k], out.rules[k], file);
  }
  return out;
}

nlohmann::ordered_json AlarmConfigJson(const AlarmConfig& config) {
  nlohmann::ordered_json out = nlohmann::ordered_json::object();
  const auto& specs = AlarmRuleSpecs();
  for (size_t k = 0; k < specs.size() && k < config.rules.size(); ++k) {
    const AlarmRule& r = config.rules[k];
    nlohmann::ordered_json j{{"enabled", r.enabled}, {"severity", r.severity}};
    if (specs[k].threshold_key) j[specs[k].threshold_key] = r.threshold;
    if (specs[k].hysteresis_key) j[specs[k].hysteresis_key] = r.hysteresis;
    out[specs[k].name] = std::move(j);
  }
  return out;
}

void CheckIdentifier(const std::string& id, const std::string& what, const std::string& file) {
  if (!IsIdentifier(id)) {
    throw InputError(file, 0, what + " '" + id + "' must be " + std::string(kIdentifierRule) + " (it is an MQTT topic level)");
  }
}

const SensorInfo* CrusherConfig::FindSensor(const std::string& id) const {
  for (const auto& s : sensors) {
    if (s.id == id) return &s;
  }
  return nullptr;
}

int CrusherConfig::RowIndex(const std::string& name) const {
  for (size_t i = 0; i < rows.size(); ++i) {
    if (rows[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

TimePoint CrusherConfig::LinerStart() const {
  return installed_at - std::chrono::days(1);
}

std::string ReadingThicknessError(const SensorInfo& sensor, double thickness_mm) {
  const double max = sensor.thickness_new_mm + kReadingSlackMm;
  if (std::isfinite(thickness_mm) && thickness_mm >= 0 && thickness_mm <= max) return "";
  return Number(thickness_mm) + " is outside [0, " + Number(max) + "] (sensor '" + sensor.id + "': its thickness_new_mm " +
         Number(sensor.thickness_new_mm) + " + " + Number(kReadingSlackMm) + " mm)";
}

bool CrusherConfig::OfThisLiner(const std::string& sensor_id, TimePoint t, double thickness_mm) const {
  if (t >= installed_at) return true;
  if (t < LinerStart()) return false;
  const SensorInfo* s = FindSensor(sensor_id);
  return thickness_mm >= (s ? s->thickness_new_mm : thickness_new_mm) - kSlackWearMm;
}

void ParseSensors(const nlohmann::json& sensors, const std::string& file, CrusherConfig* config) {
  if (!sensors.is_array()) throw InputError(file, 0, "\"sensors\" array is required");
  CrusherConfig& c = *config;
  c.sensors.clear();
  for (const auto& s : sensors) {
    if (!s.is_object()) throw InputError(file, 0, "each sensor must be a JSON object");
    SensorInfo si;
    if (s.contains("id") && s["id"].is_number_integer())
      si.id = std::to_string(s["id"].get<long long>());
    else
      si.id = Get<std::string>(s, "id", "a sensor", file);
    CheckIdentifier(si.id, "sensor id", file);
    const std::string where = "sensor '" + si.id + "'";
    si.row = Get<std::string>(s, "row", where, file);
    si.z_m = Get<double>(s, "z_m", where, file);
    si.theta_deg = Get<double>(s, "theta_deg", where, file);
    si.thickness_new_mm = s.contains("thickness_new_mm") ? Get<double>(s, "thickness_new_mm", where, file) : c.thickness_new_mm;
    if (s.contains("address")) {
      const std::string a = Get<std::string>(s, "address", where, file);
      try {
        size_t used = 0;
        si.address = std::stoull(a, &used, 16);
        if (used != a.size()) throw std::invalid_argument("hex");
      } catch (const std::exception&) {
        throw InputError(file, 0, where + " address '" + a + "' is not a 64-bit hex number");
      }
    }
    if (c.RowIndex(si.row) < 0) throw InputError(file, 0, where + " names row '" + si.row + "' that is not in concave.rows");
    if (c.FindSensor(si.id)) throw InputError(file, 0, where + " is listed twice");
    if (!(si.thickness_new_mm > 0) || si.thickness_new_mm > kMaxThicknessMm) {
      throw InputError(file, 0,
                       where + " thickness_new_mm must be in (0, " + std::to_string(static_cast<int>(kMaxThicknessMm)) + "]");
    }
    // A sensor cast into this liner is above the liner's minimum when new and no more than twice
    // its nominal thickness: anything else is a units or copy mistake that would read as wear.
    if (!(si.thickness_new_mm > c.thickness_min_mm) || si.thickness_new_mm > 2 * c.thickness_new_mm) {
      throw InputError(file, 0,
                       where + " thickness_new_mm " + Number(si.thickness_new_mm) + " must be above concave thickness_min_mm (" +
                           Number(c.thickness_min_mm) + ") and at most twice concave thickness_new_mm (" +
                           Number(c.thickness_new_mm) + ")");
    }
    const Row& row = c.rows[static_cast<size_t>(c.RowIndex(si.row))];
    if (si.z_m < row.z_min_m || si.z_m > row.z_max_m) {
      throw InputError(file, 0,
                       where + " z_m " + std::to_string(si.z_m) + " is outside its row '" + row.name + "' [" +
                           std::to_string(row.z_min_m) + ", " + std::to_string(row.z_max_m) + "] m");
    }
    if (!(si.theta_deg >= -360 && si.theta_deg <= 360)) {
      throw InputError(file, 0, where + " theta_deg " + std::to_string(si.theta_deg) + " is outside [-360, 360]");
    }
    c.sensors.push_back(si);
  }
}

CrusherConfig LoadCrusherConfig(const std::filesystem::path& path) {
  const std::string file = path.filename().string();
  std::ifstream in(path);
  if (!in) throw InputError(file, 0, "cannot open '" + path.string() + "'");
  json j;
  try {
    j = ParseJsonUniqueKeys(in);
  } catch (const DuplicateJsonKey& e) {
    throw InputError(file, 0, e.what());
  } catch (const json::out_of_range& e) {
    throw InputError(file, 0, std::string("a number does not fit a double: ") + e.what());
  } catch (const json::parse_error& e) {
    // nlohmann reports a byte offset; turn it into a line.
    std::ifstream again(path);
    std::string text((std::istreambuf_iterator<char>(again)), std::istreambuf_iterator<char>());
    const size_t line =
        1 + static_cast<size_t>(std::count(text.begin(), text.begin() + static_cast<long>(std::min(e.byte, text.size())), '\n'));
    throw InputError(file, line, std::string("not valid JSON: ") + e.what());
  } catch (const json::exception& e) {  // a number out of range (1e999) is not a parse_error
    throw InputError(file, 0, std::string("not valid JSON: ") + e.what());
  }
  if (!j.is_object()) throw InputError(file, 0, "must hold a JSON object");
  CrusherConfig c;
  c.crusher_id = Get<std::string>(j, "crusher_id", "the top level", file);
  CheckIdentifier(c.crusher_id, "crusher_id", file);
  if (j.contains("site")) {
    c.site = Get<std::string>(j, "site", "the top level", file);
    CheckIdentifier(c.site, "site", file);
  }
  c.installed_at = ParseTime(Get<std::string>(j, "installed_at", "the top level", file), file, 0, "installed_at");
  if (!j.contains("concave") || !j["concave"].is_object()) throw InputError(file, 0, "\"concave\" object is required");
  const json& cc = j["concave"];
  c.thickness_new_mm = Get<double>(cc, "thickness_new_mm", "concave", file);
  c.thickness_min_mm = Get<double>(cc, "thickness_min_mm", "concave", file);
  if (!(c.thickness_new_mm > 0) || !(c.thickness_min_mm >= 0) || c.thickness_min_mm >= c.thickness_new_mm ||
      c.thickness_new_mm > kMaxThicknessMm) {
    throw InputError(file, 0,
                     "concave thickness_min_mm must be >= 0 and below thickness_new_mm, which must be in (0, " +
                         std::to_string(static_cast<int>(kMaxThicknessMm)) + "] mm");
  }
  if (!cc.contains("rows") || !cc["rows"].is_array() || cc["rows"].empty())
    throw InputError(file, 0, "concave.rows must be a non-empty array");
  for (const auto& r : cc["rows"]) {
    Row row;
    row.name = Get<std::string>(r, "name", "a concave row", file);
    row.z_min_m = Get<double>(r, "z_min_m", "row '" + row.name + "'", file);
    row.z_max_m = Get<double>(r, "z_max_m", "row '" + row.name + "'", file);
    if (!(row.z_max_m > row.z_min_m)) throw InputError(file, 0, "row '" + row.name + "': z_max_m must be above z_min_m");
    if (row.name.empty() || row.name.size() > 64)
      throw InputError(file, 0, "row name '" + row.name + "' must be 1-64 characters");
    if (c.RowIndex(row.name) >= 0) throw InputError(file, 0, "row '" + row.name + "' is listed twice");
    for (const Row& other : c.rows) {
      if (row.z_min_m < other.z_max_m && other.z_min_m < row.z_max_m) {
        throw InputError(file, 0, "row '" + row.name + "' overlaps row '" + other.name + "' in z (rows may touch, not overlap)");
      }
    }
    c.rows.push_back(row);
  }
  if (cc.contains("joints_theta_deg")) {
    c.joints_theta_deg = Get<std::vector<double>>(cc, "joints_theta_deg", "concave", file);
    if (c.joints_theta_deg.size() > 360) throw InputError(file, 0, "concave.joints_theta_deg lists more than 360 joints");
    for (double& t : c.joints_theta_deg) {
      if (!std::isfinite(t) || t < -360.0 || t > 360.0)
        throw InputError(file, 0, "concave.joints_theta_deg values must be angles in [-360, 360] degrees");
      t = std::fmod(t + 360.0, 360.0);
    }
  }
  if (!j.contains("sensors")) throw InputError(file, 0, "\"sensors\" array is required");
  ParseSensors(j["sensors"], file, &c);
  if (j.contains("thinnest_area")) c.thinnest_area = ParseThinnestArea(j["thinnest_area"], c.thickness_new_mm, file);
  if (j.contains("setting")) c.setting = ParseSetting(j["setting"], file);
  c.alarms = DefaultAlarmConfig(c);
  if (j.contains("alarms")) c.alarms = ParseAlarmConfig(j["alarms"], c.alarms, file);
  return c;
}

void CheckCrusherAgainstMap(const CrusherConfig& config, const WearMap& map, const std::string& file) {
  if (map.points.empty()) return;
  double lo = map.points.front().z(), hi = lo;  // the surface's z extent (its vertices)
  for (const auto& p : map.points) {
    lo = std::min(lo, p.z());
    hi = std::max(hi, p.z());
  }
  const double tol = 0.05 * (hi - lo) + 1e-3;
  char range[96];
  std::snprintf(range, sizeof range, "[%.3f, %.3f] m", lo, hi);
  for (const Row& r : config.rows) {
    if (r.z_max_m < lo - tol || r.z_min_m > hi + tol) {
      throw InputError(file, 0, "row '" + r.name + "' lies outside the wear map's z range " + range + " (wrong frame or units?)");
    }
  }
  for (const SensorInfo& s : config.sensors) {
    if (s.z_m < lo - tol || s.z_m > hi + tol) {
      throw InputError(file, 0,
                       "sensor '" + s.id + "' z_m " + std::to_string(s.z_m) + " is outside the wear map's z range " + range +
                           " (wrong frame or units?)");
    }
  }
}

std::vector<Reading> LoadReadings(const std::filesystem::path& path) {
  const std::string file = path.filename().string();
  std::vector<Reading> out;
  std::map<std::string, size_t> col;
  ReadCsv(
      path, {"time", "sensor_id", "thickness_mm"},
      [&](const std::vector<std::string>& c, size_t line) {
        Reading r;
        r.line = line;
        r.time = ParseTime(c[col["time"]], file, line, "time");
        r.sensor_id = c[col["sensor_id"]];
        if (r.sensor_id.empty()) throw InputError(file, line, "sensor_id is empty");
        r.thickness_mm = ParseNumber(c[col["thickness_mm"]], file, line, "thickness_mm");
        if (r.thickness_mm < 0) throw InputError(file, line, "thickness_mm " + c[col["thickness_mm"]] + " is negative");
        out.push_back(std::move(r));
      },
      &col);
  std::stable_sort(out.begin(), out.end(), [](const Reading& a, const Reading& b) {
    return a.sensor_id != b.sensor_id ? a.sensor_id < b.sensor_id : a.time < b.time;
  });
  return out;
}

std::vector<OperationsSample> LoadOperations(const std::filesystem::path& path) {
  const std::string file = path.filename().string();
  std::vector<OperationsSample> out;
  std::map<std::string, size_t> col;
  ReadCsv(
      path, {"time", "throughput_tph"},
      [&](const std::vector<std::string>& c, size_t line) {
        OperationsSample s;
        s.time = ParseTime(c[col["time"]], file, line, "time");
        s.throughput_tph = ParseNumber(c[col["throughput_tph"]], file, line, "throughput_tph");
        if (s.throughput_tph < 0) throw InputError(file, line, "throughput_tph is negative");
        if (col.count("power_kw") && !c[col["power_kw"]].empty())
          s.power_kw = ParseNumber(c[col["power_kw"]], file, line, "power_kw");
        if (col.count("ore_ai") && !c[col["ore_ai"]].empty()) s.ore_ai = ParseNumber(c[col["ore_ai"]], file, line, "ore_ai");
        out.push_back(s);
      },
      &col);
  std::stable_sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.time < b.time; });
  return out;
}

std::vector<Eigen::Vector3d> ParseScanPoints(const std::string& text, const std::string& file) {
  std::vector<Eigen::Vector3d> points;
  std::istringstream in(text);
  std::string line;
  size_t lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    const std::string t = Trim(line);
    if (t.empty() || t[0] == '#') continue;
    std::istringstream ls(t);
    double x, y, z;
    if (!(ls >> x >> y >> z) || !std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) {
      throw InputError(file, lineno, "expected three finite numbers 'x y z' (metres)");
    }
    points.emplace_back(x, y, z);
  }
  if (points.empty()) throw InputError(file, 0, "no points");
  return points;
}

Scan LoadScan(const std::filesystem::path& path) {
  const std::string file = "scans/" + path.filename().string();
  static const std::regex kName(R"(scan_(\d{4}-\d{2}-\d{2})\.xyz)");
  std::smatch m;
  const std::string name = path.filename().string();
  if (!std::regex_match(name, m, kName)) throw InputError(file, 0, "scan file name must be scan_YYYY-MM-DD.xyz");
  Scan s;
  s.file = file;
  s.date = ParseTime(m[1].str(), file, 0, "file name date");
  if (!std::filesystem::exists(path)) throw InputError(file, 0, "cannot open '" + path.string() + "'");
  s.points = ParseScanPoints(ReadFile(path), file);
  return s;
}

namespace {
/// Readings of `crusher`'s sensors with values they can give (LoadBundle's checks).
void CheckReadings(const CrusherConfig& crusher, const std::vector<Reading>& readings, const std::string& file) {
  for (const auto& r : readings) {
    const SensorInfo* s = crusher.FindSensor(r.sensor_id);
    if (!s) throw InputError(file, r.line, "sensor_id '" + r.sensor_id + "' is not a sensor in crusher.json");
    // A previous liner's reading (before LinerStart, kept after a reline) may be of a thicker liner;
    // the server never checks those against this one either.
    if (r.time < crusher.LinerStart()) continue;
    const std::string error = ReadingThicknessError(*s, r.thickness_mm);
    if (!error.empty()) throw InputError(file, r.line, "thickness_mm " + error);
  }
}
}  // namespace

Bundle LoadBundle(const std::filesystem::path& dir) {
  if (!std::filesystem::is_directory(dir)) throw InputError(dir.string(), 0, "bundle is not a directory");
  Bundle b;
  b.dir = dir;
  for (const char* req : {"crusher.json", "wear_map.vtk", "readings.csv"}) {
    if (!std::filesystem::exists(dir / req))
      throw InputError(req, 0, "required bundle file is missing in '" + dir.string() + "'");
  }
  b.crusher = LoadCrusherConfig(dir / "crusher.json");
  b.map = LoadWearMap(dir / "wear_map.vtk", &b.map_validation);
  CheckCrusherAgainstMap(b.crusher, b.map, "crusher.json");
  b.readings = LoadReadings(dir / "readings.csv");
  // Every reading must name a known sensor and hold a value it can give (the server's rule).
  CheckReadings(b.crusher, b.readings, "readings.csv");
  if (std::filesystem::exists(dir / "operations.csv")) b.operations = LoadOperations(dir / "operations.csv");
  b.scans = LoadScans(dir);
  b.history = LoadHistory(dir, b.crusher, b.map);
  return b;
}

std::vector<PastCampaign> LoadHistory(const std::filesystem::path& dir, const CrusherConfig& current, const WearMap& map) {
  namespace fs = std::filesystem;
  std::vector<PastCampaign> out;
  const fs::path root = dir / "history";
  std::error_code ec;
  if (!fs::exists(root, ec)) return out;
  if (!fs::is_directory(root, ec)) throw InputError("history", 0, "is not a folder (it holds one folder per earlier campaign)");
  std::vector<fs::path> folders;
  for (fs::directory_iterator e(root, ec), end; !ec && e != end; e.increment(ec))
    if (e->is_directory(ec)) folders.push_back(e->path());
  if (ec) throw InputError("history", 0, "cannot be read: " + ec.message());
  std::sort(folders.begin(), folders.end());
  for (const fs::path& f : folders) {
    PastCampaign p;
    p.name = f.filename().string();
    const std::string where = "history/" + p.name + "/";
    // A folder with none of a campaign's files is not one (notes, a backup): ignored, as unknown
    // extra files are.
    if (!fs::exists(f / "crusher.json", ec) && !fs::exists(f / "readings.csv", ec) && !fs::exists(f / "scans", ec)) continue;
    try {
      if (!fs::exists(f / "crusher.json")) throw InputError("crusher.json", 0, "required in every history folder is missing");
      p.crusher = LoadCrusherConfig(f / "crusher.json");
      CheckCrusherAgainstMap(p.crusher, map, "crusher.json");
      if (p.crusher.crusher_id != current.crusher_id)
        throw InputError("crusher.json", 0,
                         "crusher_id '" + p.crusher.crusher_id + "' is not the bundle's '" + current.crusher_id +
                             "' (history holds the same crusher's earlier liners)");
      if (!(p.crusher.installed_at < current.installed_at))
        throw InputError("crusher.json", 0,
                         "installed_at " + FormatIsoTime(p.crusher.installed_at) + " is not before the bundle's " +
                             FormatIsoTime(current.installed_at) + " (an earlier campaign)");
      if (fs::exists(f / "readings.csv")) {
        p.readings = LoadReadings(f / "readings.csv");
        CheckReadings(p.crusher, p.readings, "readings.csv");
      }
      p.scans = LoadScans(f);
    } catch (const InputError& e) {
      throw InputError(where + e.file(), e.line(), e.rule());
    } catch (const std::exception& e) {  // a folder that cannot be read: named, not a bare filesystem error
      throw InputError("history/" + p.name, 0, std::string("cannot be read: ") + e.what());
    }
    out.push_back(std::move(p));
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const PastCampaign& a, const PastCampaign& b) { return a.crusher.installed_at < b.crusher.installed_at; });
  return out;
}

std::vector<Scan> LoadScans(const std::filesystem::path& dir) {
  std::vector<Scan> scans;
  std::error_code ec;
  const auto status = std::filesystem::status(dir / "scans", ec);
  if (status.type() == std::filesystem::file_type::not_found) return scans;
  // A `scans` that is a file (a scan copied to the wrong name) would be ignored silently.
  if (status.type() != std::filesystem::file_type::directory)
    throw InputError("scans", 0, "'" + (dir / "scans").string() + "' is not a folder (scans go in scans/scan_YYYY-MM-DD.xyz)");
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(dir / "scans")) {
    if (e.path().extension() == ".xyz") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  for (const auto& f : files) scans.push_back(LoadScan(f));
  return scans;
}

}  // namespace lw::core
