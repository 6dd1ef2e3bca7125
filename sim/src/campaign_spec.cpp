// Campaign specs: JSON in and out, completion with defaults and checks, --effect/--fault/--preset.
#include "sim/campaign.hpp"

#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <type_traits>
#include <stdexcept>

#include "core/cmdline.hpp"
#include "core/time.hpp"

namespace lw::sim {

// ---------------------------------------------------------------------------------------------
// Spec

nlohmann::json CampaignSpec::ToJson() const {
  nlohmann::json j = {{"crusher_id", crusher_id},
                      {"installed_at", installed_at},
                      {"days", days},
                      {"thickness_new_mm", thickness_new_mm},
                      {"thickness_min_mm", thickness_min_mm},
                      {"height_m", height_m},
                      {"r_bottom_m", r_bottom_m},
                      {"r_top_m", r_top_m},
                      {"n_theta", n_theta},
                      {"n_z", n_z},
                      {"reference_wear_mm", reference_wear_mm},
                      {"reference_day", reference_day},
                      {"dem_noise", dem_noise},
                      {"poll_minutes", poll_minutes},
                      {"heartbeat_hours", heartbeat_hours},
                      {"throughput_tph", throughput_tph},
                      {"ore_ai", ore_ai},
                      {"write_operations", write_operations},
                      {"write_scan", write_scan},
                      {"scan_day", scan_day},
                      {"scan_noise_mm", scan_noise_mm},
                      {"scan_points", scan_points},
                      {"scan_occluded_deg", scan_occluded_deg}};
  j["rows"] = nlohmann::json::array();
  for (const auto& r : rows) j["rows"].push_back({{"name", r.name}, {"z_min_m", r.z_min_m}, {"z_max_m", r.z_max_m}});
  j["sensors"] = nlohmann::json::array();
  for (const auto& s : sensors)
    j["sensors"].push_back({{"id", s.id}, {"row", s.row}, {"z_m", s.z_m}, {"theta_deg", s.theta_deg}});
  j["effects"] = nlohmann::json::array();
  for (const auto& e : effects) j["effects"].push_back({{"name", e.name}, {"params", e.params}});
  j["faults"] = nlohmann::json::array();
  for (const auto& f : faults) j["faults"].push_back({{"sensor", f.sensor}, {"kind", f.kind}, {"day", f.day}, {"size", f.size}});
  return j;
}

CampaignSpec CampaignSpec::FromJson(const nlohmann::json& j) {
  CampaignSpec s;
  const std::set<std::string> known = {"crusher_id",
                                       "installed_at",
                                       "days",
                                       "thickness_new_mm",
                                       "thickness_min_mm",
                                       "height_m",
                                       "r_bottom_m",
                                       "r_top_m",
                                       "n_theta",
                                       "n_z",
                                       "reference_wear_mm",
                                       "reference_day",
                                       "dem_noise",
                                       "poll_minutes",
                                       "heartbeat_hours",
                                       "throughput_tph",
                                       "ore_ai",
                                       "write_operations",
                                       "write_scan",
                                       "scan_day",
                                       "scan_noise_mm",
                                       "scan_points",
                                       "scan_occluded_deg",
                                       "rows",
                                       "sensors",
                                       "effects",
                                       "faults",
                                       "seed",
                                       "out",
                                       "truth",
                                       "preset",
                                       "effect",
                                       "fault"};
  for (const auto& [k, v] : j.items()) {
    if (!known.count(k)) throw std::invalid_argument("unknown campaign key \"" + k + "\"");
  }
  try {
    auto get = [&](const char* key, auto& field) {
      if (!j.contains(key)) return;
      using T = std::decay_t<decltype(field)>;
      if constexpr (std::is_same_v<T, int>) {
        // nlohmann converts any number to int unchecked (2.4e98 -> undefined behaviour; found by
        // fuzz/sim_campaign): a count must be a whole number that fits.
        const nlohmann::json& v = j.at(key);
        const double d = v.is_number() ? v.get<double>() : 0.5;
        if (!v.is_number() || d != std::floor(d) || d < -2147483648.0 || d > 2147483647.0)
          throw std::invalid_argument(std::string("campaign spec: \"") + key +
                                      "\" must be a whole number that fits an int, not " + v.dump());
        field = static_cast<int>(d);
      } else {
        field = j.at(key).get<T>();
      }
    };
    get("crusher_id", s.crusher_id);
    get("installed_at", s.installed_at);
    get("days", s.days);
    get("thickness_new_mm", s.thickness_new_mm);
    get("thickness_min_mm", s.thickness_min_mm);
    get("height_m", s.height_m);
    get("r_bottom_m", s.r_bottom_m);
    get("r_top_m", s.r_top_m);
    get("n_theta", s.n_theta);
    get("n_z", s.n_z);
    get("reference_wear_mm", s.reference_wear_mm);
    get("reference_day", s.reference_day);
    get("dem_noise", s.dem_noise);
    get("poll_minutes", s.poll_minutes);
    get("heartbeat_hours", s.heartbeat_hours);
    get("throughput_tph", s.throughput_tph);
    get("ore_ai", s.ore_ai);
    get("write_operations", s.write_operations);
    get("write_scan", s.write_scan);
    get("scan_day", s.scan_day);
    get("scan_noise_mm", s.scan_noise_mm);
    get("scan_points", s.scan_points);
    get("scan_occluded_deg", s.scan_occluded_deg);
    if (j.contains("rows")) {
      for (const auto& r : j["rows"])
        s.rows.push_back({r.at("name").get<std::string>(), r.at("z_min_m").get<double>(), r.at("z_max_m").get<double>()});
    }
    if (j.contains("sensors")) {
      for (const auto& x : j["sensors"]) {
        s.sensors.push_back({x.at("id").get<std::string>(), x.at("row").get<std::string>(), x.at("z_m").get<double>(),
                             x.at("theta_deg").get<double>()});
      }
    }
    if (j.contains("effects")) {
      for (const auto& e : j["effects"]) {
        EffectSpec es{e.at("name").get<std::string>(), {}};
        if (e.contains("params")) es.params = e["params"].get<std::map<std::string, double>>();
        s.effects.push_back(es);
      }
    }
    if (j.contains("faults")) {
      for (const auto& f : j["faults"]) {
        s.faults.push_back(
            {f.at("sensor").get<std::string>(), f.at("kind").get<std::string>(), f.value("day", 0.0), f.value("size", 0.0)});
      }
    }
  } catch (const nlohmann::json::exception& e) {
    throw std::invalid_argument(std::string("campaign spec: ") + e.what());
  }
  return s;
}

namespace {

/// One parameter of an effect: its name and the closed/open range it must lie in.
struct ParamRange {
  const char* key;
  double lo, hi;
  bool hi_open;  ///< hi itself refused (a factor that would reach zero wear or a negative rate)
};

/// Refuses an effect that is unknown, has a parameter the effect does not read, or a value outside
/// what keeps the wear rate positive and finite (docs/sim.md's table of effects).
void CheckEffect(const EffectSpec& e, size_t n_sensors, double height_m, double thickness_new_mm) {
  static const std::map<std::string, std::vector<ParamRange>> kEffects = {
      {"work_hardening", {{"h", 0, 1, true}, {"tau_days", 1e-3, 1e4, false}}},
      {"hardness_gradient", {{"c", 0, 1, true}, {"onset_mm", 0, 1e4, false}, {"width_mm", 1e-3, 1e4, false}}},
      {"squeeze_wear", {{"beta", 0, 10, false}}},
      {"profile_evolution", {{"p", -5, 5, false}}},
      {"feed_segregation", {{"amplitude", 0, 1, true}, {"theta_deg", -360, 720, false}}},
      {"throughput_variation", {{"amplitude", 0, 1, true}}},
      {"material_loss",
       {{"depth_mm", 0, thickness_new_mm, false},
        {"day", 0, 1e4, false},
        {"radius_m", 1e-3, 10, false},
        {"sensor_index", 0, static_cast<double>(n_sensors) - 1, false},
        {"z_m", 0, height_m, false},
        {"theta_deg", -360, 720, false}}},
  };
  const auto it = kEffects.find(e.name);
  if (it == kEffects.end()) throw std::invalid_argument("unknown effect '" + e.name + "'");
  for (const auto& [key, value] : e.params) {
    const ParamRange* r = nullptr;
    std::string known;
    for (const ParamRange& p : it->second) {
      if (key == p.key) r = &p;
      known += (known.empty() ? "" : ", ") + std::string(p.key);
    }
    if (!r) throw std::invalid_argument("effect '" + e.name + "' has no parameter '" + key + "' (it has " + known + ")");
    const bool ok =
        value >= r->lo && (r->hi_open ? value < r->hi : value <= r->hi) && (key != "sensor_index" || value == std::floor(value));
    if (!ok) {
      char what[160];
      std::snprintf(what, sizeof what, " = %g is outside [%g, %g%s%s", value, r->lo, r->hi, r->hi_open ? ")" : "]",
                    key == "sensor_index" ? " or not a whole number" : "");
      throw std::invalid_argument("effect '" + e.name + "': " + key + what);
    }
  }
}

}  // namespace

void CampaignSpec::Complete() {
  auto require = [](bool ok, const std::string& what) {
    if (!ok) throw std::invalid_argument(what);
  };
  require(days > 0 && days <= 2000, "days must be in (0, 2000]");
  require(thickness_new_mm > thickness_min_mm && thickness_min_mm >= 0, "thickness_new_mm must exceed thickness_min_mm >= 0");
  require(height_m > 0 && r_bottom_m > 0 && r_top_m > 0, "height_m, r_bottom_m and r_top_m must be positive");
  require(n_theta >= 8 && n_z >= 6 && static_cast<long long>(n_theta) * n_z <= 2000000,
          "n_theta >= 8, n_z >= 6, n_theta * n_z <= 2e6");
  require(dem_noise >= 0 && dem_noise < 0.5, "dem_noise must be in [0, 0.5)");
  require(poll_minutes > 0 && heartbeat_hours > 0, "poll_minutes and heartbeat_hours must be positive");
  require(reference_wear_mm > 0 && reference_wear_mm < thickness_new_mm, "reference_wear_mm must be in (0, thickness_new_mm)");
  require(core::ParseIsoTime(installed_at).has_value(), "installed_at '" + installed_at + "' is not an ISO-8601 time");
  require(poll_minutes >= 1 && heartbeat_hours >= 0.1, "poll_minutes must be >= 1 and heartbeat_hours >= 0.1");
  require(reference_day > 0 && reference_day <= 2000, "reference_day must be in (0, 2000]");
  require(throughput_tph > 0 && throughput_tph <= 1e5, "throughput_tph must be in (0, 1e5]");
  require(ore_ai >= 0 && ore_ai <= 10, "ore_ai must be in [0, 10]");
  require(scan_noise_mm >= 0 && scan_noise_mm <= 100, "scan_noise_mm must be in [0, 100]");
  require(scan_points >= 0 && scan_points <= 10000000, "scan_points must be in [0, 1e7]");
  require(scan_occluded_deg >= 0 && scan_occluded_deg < 360, "scan_occluded_deg must be in [0, 360)");
  require(scan_day <= days, "scan_day must not be after the last day (days)");
  if (rows.empty()) {
    const double h = height_m / 3.0;
    rows = {{"LDWN", 0.0, h}, {"LMID", h, 2 * h}, {"LUP", 2 * h, height_m}};
  }
  if (sensors.empty()) {
    // 2 in the upper row, 4 in each of the others, at angles that leave room between them.
    auto centre = [&](const std::string& name) {
      for (const auto& r : rows) {
        if (r.name == name) return 0.5 * (r.z_min_m + r.z_max_m);
      }
      return 0.5 * height_m;
    };
    int id = 1001;
    const std::vector<std::pair<std::string, std::vector<double>>> layout = {
        {rows.back().name, {30, 210}}, {rows[rows.size() / 2].name, {0, 90, 180, 270}}, {rows.front().name, {45, 135, 225, 315}}};
    for (const auto& [row, thetas] : layout) {
      for (double th : thetas) sensors.push_back({std::to_string(id++), row, centre(row), th});
    }
  }
  std::set<std::string> row_names;
  for (const auto& r : rows) {
    require(row_names.insert(r.name).second, "row '" + r.name + "' is listed twice");
    require(r.z_min_m < r.z_max_m, "row '" + r.name + "' needs z_min_m < z_max_m");
  }
  std::set<std::string> ids;
  for (const auto& s : sensors) {
    require(ids.insert(s.id).second, "sensor id '" + s.id + "' is listed twice");
    require(s.z_m >= 0 && s.z_m <= height_m, "sensor '" + s.id + "' z_m is outside the concave");
    require(row_names.count(s.row) == 1, "sensor '" + s.id + "' names unknown row '" + s.row + "'");
  }
  // The generated record: one reading per poll per sensor must stay a file a machine can hold.
  require(days * 1440.0 / poll_minutes * static_cast<double>(sensors.size()) <= 5e7,
          "days x sensors / poll_minutes asks for more than 50,000,000 readings");
  for (const auto& e : effects) CheckEffect(e, sensors.size(), height_m, thickness_new_mm);
  static const std::set<std::string> kFaults = {"dropout", "flicker", "crack", "stuck", "dead"};
  for (const auto& f : faults) {
    require(kFaults.count(f.kind) == 1, "unknown fault kind '" + f.kind + "'");
    require(ids.count(f.sensor) == 1, "fault names unknown sensor '" + f.sensor + "'");
    require(f.day >= 0 && f.size >= 0 && f.size <= 1000,
            "fault '" + f.sensor + ":" + f.kind + "' needs day >= 0 and size in [0, 1000]");
  }
}

namespace {
/// A finite number and nothing else ("0.3x", "nan" and "" are refused), as core::ParseNumber.
double SpecNumber(const std::string& what, const std::string& text) {
  try {
    return core::ParseNumber("", text);
  } catch (const core::UsageError&) {
    throw std::invalid_argument(what + ": '" + text + "' is not a number");
  }
}
}  // namespace

EffectSpec ParseEffect(const std::string& text) {
  EffectSpec e;
  const size_t colon = text.find(':');
  e.name = text.substr(0, colon);
  if (colon == std::string::npos) return e;
  std::stringstream ss(text.substr(colon + 1));
  std::string kv;
  while (std::getline(ss, kv, ',')) {
    const size_t eq = kv.find('=');
    if (eq == std::string::npos) throw std::invalid_argument("--effect '" + text + "': expected key=value, got '" + kv + "'");
    e.params[kv.substr(0, eq)] = SpecNumber("--effect '" + text + "'", kv.substr(eq + 1));
  }
  return e;
}

FaultSpec ParseFault(const std::string& text) {
  std::vector<std::string> parts;
  std::stringstream ss(text);
  std::string p;
  while (std::getline(ss, p, ':')) parts.push_back(p);
  if (parts.size() < 3) throw std::invalid_argument("--fault '" + text + "': expected sensor:kind:day[:size]");
  FaultSpec f{parts[0], parts[1], 0, 0};
  f.day = SpecNumber("--fault '" + text + "': the day", parts[2]);
  if (parts.size() > 3) f.size = SpecNumber("--fault '" + text + "': the size", parts[3]);
  return f;
}

void ApplyPreset(const std::string& name, CampaignSpec* spec) {
  if (name == "reference") return;
  if (name == "paper") {
    // Ou & Chen 2023: LDWN ~6x LUP and ~2x LMID, late acceleration (softer casting core), and
    // work hardening where impact is high (Eq. 9 over-predicts up to ~5 mm mid-lower).
    spec->effects.push_back({"work_hardening", {{"h", 0.45}, {"tau_days", 6}}});
    spec->effects.push_back({"hardness_gradient", {{"c", 0.25}, {"onset_mm", 25}, {"width_mm", 30}}});
    return;
  }
  throw std::invalid_argument("unknown preset '" + name + "' (reference or paper)");
}

}  // namespace lw::sim
