#include "sim/campaign.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>

#include <Eigen/Geometry>

#include "core/cmdline.hpp"
#include "core/time.hpp"

namespace lw::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

double Param(const EffectSpec& e, const char* key, double fallback) {
  auto it = e.params.find(key);
  return it == e.params.end() ? fallback : it->second;
}

const EffectSpec* Find(const std::vector<EffectSpec>& effects, const std::string& name) {
  for (const auto& e : effects) {
    if (e.name == name) return &e;
  }
  return nullptr;
}

// Reduced-order chamber model (docs/sim.md). zeta = z / height, 0 at the discharge.
// Abrasive sliding work rises towards the discharge (finer, faster rock); Finnie's angle factor
// keeps it the dominant term of the DEM wear.
double Abrasion(double zeta) { return 0.06 + std::pow(std::clamp(1.0 - zeta, 0.0, 1.5), 1.5); }
// Compressive (normal) stress peaks where rock is nipped, in the mid-lower chamber, with a mild
// two-lobed variation around the circumference from the eccentric throw.
double NormalStress(double zeta, double theta_deg) {
  return 0.05 + std::exp(-std::pow((zeta - 0.3) / 0.2, 2.0)) * (1.0 + 0.1 * std::cos(2.0 * theta_deg * kDeg)) / 1.1;
}

double SmoothStep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

std::string Iso(const core::TimePoint& t0, double day) { return core::FormatIsoTime(core::AddDays(t0, day)); }

}  // namespace

// ---------------------------------------------------------------------------------------------
// Spec

nlohmann::json CampaignSpec::ToJson() const {
  nlohmann::json j = {{"crusher_id", crusher_id}, {"installed_at", installed_at}, {"days", days},
                      {"thickness_new_mm", thickness_new_mm}, {"thickness_min_mm", thickness_min_mm},
                      {"height_m", height_m}, {"r_bottom_m", r_bottom_m}, {"r_top_m", r_top_m},
                      {"n_theta", n_theta}, {"n_z", n_z}, {"reference_wear_mm", reference_wear_mm},
                      {"reference_day", reference_day}, {"dem_noise", dem_noise}, {"poll_minutes", poll_minutes},
                      {"heartbeat_hours", heartbeat_hours}, {"throughput_tph", throughput_tph}, {"ore_ai", ore_ai},
                      {"write_operations", write_operations}, {"write_scan", write_scan}, {"scan_day", scan_day},
                      {"scan_noise_mm", scan_noise_mm}, {"scan_points", scan_points},
                      {"scan_occluded_deg", scan_occluded_deg}};
  j["rows"] = nlohmann::json::array();
  for (const auto& r : rows) j["rows"].push_back({{"name", r.name}, {"z_min_m", r.z_min_m}, {"z_max_m", r.z_max_m}});
  j["sensors"] = nlohmann::json::array();
  for (const auto& s : sensors) j["sensors"].push_back({{"id", s.id}, {"row", s.row}, {"z_m", s.z_m}, {"theta_deg", s.theta_deg}});
  j["effects"] = nlohmann::json::array();
  for (const auto& e : effects) j["effects"].push_back({{"name", e.name}, {"params", e.params}});
  j["faults"] = nlohmann::json::array();
  for (const auto& f : faults) j["faults"].push_back({{"sensor", f.sensor}, {"kind", f.kind}, {"day", f.day}, {"size", f.size}});
  return j;
}

CampaignSpec CampaignSpec::FromJson(const nlohmann::json& j) {
  CampaignSpec s;
  const std::set<std::string> known = {"crusher_id", "installed_at", "days", "thickness_new_mm", "thickness_min_mm",
                                       "height_m", "r_bottom_m", "r_top_m", "n_theta", "n_z", "reference_wear_mm",
                                       "reference_day", "dem_noise", "poll_minutes", "heartbeat_hours",
                                       "throughput_tph", "ore_ai", "write_operations", "write_scan", "scan_day",
                                       "scan_noise_mm", "scan_points", "scan_occluded_deg", "rows", "sensors",
                                       "effects", "faults", "seed", "out", "truth", "preset", "effect", "fault"};
  for (const auto& [k, v] : j.items()) {
    if (!known.count(k)) throw std::invalid_argument("unknown campaign key \"" + k + "\"");
  }
  try {
    auto get = [&](const char* key, auto& field) {
      if (j.contains(key)) field = j.at(key).get<std::decay_t<decltype(field)>>();
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
      for (const auto& r : j["rows"]) s.rows.push_back({r.at("name").get<std::string>(), r.at("z_min_m").get<double>(), r.at("z_max_m").get<double>()});
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
        s.faults.push_back({f.at("sensor").get<std::string>(), f.at("kind").get<std::string>(), f.value("day", 0.0), f.value("size", 0.0)});
      }
    }
  } catch (const nlohmann::json::exception& e) {
    throw std::invalid_argument(std::string("campaign spec: ") + e.what());
  }
  return s;
}

void CampaignSpec::Complete() {
  auto require = [](bool ok, const std::string& what) {
    if (!ok) throw std::invalid_argument(what);
  };
  require(days > 0 && days <= 2000, "days must be in (0, 2000]");
  require(thickness_new_mm > thickness_min_mm && thickness_min_mm >= 0, "thickness_new_mm must exceed thickness_min_mm >= 0");
  require(height_m > 0 && r_bottom_m > 0 && r_top_m > 0, "height_m, r_bottom_m and r_top_m must be positive");
  require(n_theta >= 8 && n_z >= 6 && n_theta * n_z <= 2000000, "n_theta >= 8, n_z >= 6, n_theta * n_z <= 2e6");
  require(dem_noise >= 0 && dem_noise < 0.5, "dem_noise must be in [0, 0.5)");
  require(poll_minutes > 0 && heartbeat_hours > 0, "poll_minutes and heartbeat_hours must be positive");
  require(reference_wear_mm > 0 && reference_wear_mm < thickness_new_mm, "reference_wear_mm must be in (0, thickness_new_mm)");
  require(core::ParseIsoTime(installed_at).has_value(), "installed_at '" + installed_at + "' is not an ISO-8601 time");
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
        {rows.back().name, {30, 210}},
        {rows[rows.size() / 2].name, {0, 90, 180, 270}},
        {rows.front().name, {45, 135, 225, 315}}};
    for (const auto& [row, thetas] : layout) {
      for (double th : thetas) sensors.push_back({std::to_string(id++), row, centre(row), th});
    }
  }
  std::set<std::string> ids;
  for (const auto& s : sensors) {
    require(ids.insert(s.id).second, "sensor id '" + s.id + "' is listed twice");
    require(s.z_m >= 0 && s.z_m <= height_m, "sensor '" + s.id + "' z_m is outside the concave");
  }
  static const std::set<std::string> kEffects = {"work_hardening", "hardness_gradient", "squeeze_wear", "profile_evolution",
                                                 "feed_segregation", "throughput_variation", "material_loss"};
  for (const auto& e : effects) require(kEffects.count(e.name) == 1, "unknown effect '" + e.name + "'");
  static const std::set<std::string> kFaults = {"dropout", "flicker", "crack", "stuck", "dead"};
  for (const auto& f : faults) {
    require(kFaults.count(f.kind) == 1, "unknown fault kind '" + f.kind + "'");
    require(ids.count(f.sensor) == 1, "fault names unknown sensor '" + f.sensor + "'");
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

// ---------------------------------------------------------------------------------------------
// Generation

namespace {

struct Throughput {
  std::vector<double> q;   // hourly relative wear-rate factor from tonnage x abrasiveness
  std::vector<double> tph, ai;
};

Throughput MakeThroughput(const CampaignSpec& s, const EffectSpec* effect, size_t hours, std::mt19937_64& rng) {
  Throughput t;
  t.q.assign(hours, 1.0);
  t.tph.assign(hours, s.throughput_tph);
  t.ai.assign(hours, s.ore_ai);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  if (!effect) {
    for (size_t h = 0; h < hours; ++h) t.tph[h] = s.throughput_tph * (1.0 + 0.01 * gauss(rng));  // meter noise only
    return t;
  }
  const double a = Param(*effect, "amplitude", 0.4);
  // Slow swings (ore blend, availability), ramps, and two or three unplanned stops.
  double ph[4], per[4];
  for (int i = 0; i < 4; ++i) {
    ph[i] = 2 * kPi * uni(rng);
    per[i] = 24.0 * (3.0 + 17.0 * uni(rng));
  }
  std::vector<std::pair<double, double>> stops;
  const int n_stops = 2 + static_cast<int>(uni(rng) * 2);
  for (int i = 0; i < n_stops; ++i) stops.emplace_back(uni(rng) * s.days * 24.0, 12.0 + 24.0 * uni(rng));
  for (size_t h = 0; h < hours; ++h) {
    double swing = 0;
    for (int i = 0; i < 4; ++i) swing += std::sin(2 * kPi * static_cast<double>(h) / per[i] + ph[i]) / 2.0;
    double tph = s.throughput_tph * std::max(0.0, 1.0 + a * std::clamp(swing, -1.0, 1.0));
    for (const auto& [start, len] : stops) {
      if (static_cast<double>(h) >= start && static_cast<double>(h) < start + len) tph = 0;
    }
    const double ai = std::max(0.05, s.ore_ai * (1.0 + 0.5 * a * std::sin(2 * kPi * static_cast<double>(h) / per[0] + ph[1])));
    t.tph[h] = tph;
    t.ai[h] = ai;
    // Bond: wear per tonne ~ (Ai + 0.22); rate ~ tonnage x that.
    t.q[h] = (tph / s.throughput_tph) * ((ai + 0.22) / (s.ore_ai + 0.22));
  }
  return t;
}

}  // namespace


Campaign GenerateCampaign(const CampaignSpec& input, uint64_t seed) {
  Campaign c;
  c.spec_ = input;
  c.spec_.Complete();
  c.seed_ = seed;
  const CampaignSpec& s = c.spec_;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> uni(0.0, 1.0);

  // Crusher config.
  c.crusher_.crusher_id = s.crusher_id;
  c.crusher_.installed_at = *core::ParseIsoTime(s.installed_at);
  c.crusher_.thickness_new_mm = s.thickness_new_mm;
  c.crusher_.thickness_min_mm = s.thickness_min_mm;
  c.crusher_.rows = s.rows;
  for (const auto& x : s.sensors) c.crusher_.sensors.push_back({x.id, x.row, x.z_m, x.theta_deg, s.thickness_new_mm, {}});

  // Mesh: truncated cone, n_theta x n_z quads split in two triangles, wound inward.
  auto radius_at = [&](double z) { return s.r_bottom_m + (s.r_top_m - s.r_bottom_m) * z / s.height_m; };
  core::WearMap& m = c.map_;
  for (int k = 0; k <= s.n_z; ++k) {
    const double z = s.height_m * k / s.n_z;
    for (int j = 0; j < s.n_theta; ++j) {
      const double th = 2 * kPi * j / s.n_theta;
      m.points.emplace_back(radius_at(z) * std::cos(th), radius_at(z) * std::sin(th), z);
    }
  }
  for (int k = 0; k < s.n_z; ++k) {
    for (int j = 0; j < s.n_theta; ++j) {
      const auto a = static_cast<uint32_t>(k * s.n_theta + j), b = static_cast<uint32_t>(k * s.n_theta + (j + 1) % s.n_theta);
      const auto up = static_cast<uint32_t>(s.n_theta);
      m.faces.push_back({a, a + up, b});
      m.faces.push_back({b, a + up, b + up});
    }
  }
  m.ComputeGeometry();
  const auto nf = static_cast<Eigen::Index>(m.face_count());

  // Fields. The DEM map = true abrasion intensity x DEM error: per-face scatter plus patchy,
  // spatially correlated error at the scale of contact patches (several random modes, 3-8 waves
  // around the circumference, 2-5 along z): what a finite DEM run leaves in its averages.
  struct Mode {
    double amp, kth, kz, ph;
  };
  std::vector<Mode> modes;
  for (int i = 0; i < 6; ++i) {
    modes.push_back({gauss(rng) * 0.4, static_cast<double>(3 + static_cast<int>(uni(rng) * 6)),
                     2.0 + 3.0 * uni(rng), 2 * kPi * uni(rng)});
  }
  c.intensity_true_.resize(nf);
  c.normal_.resize(nf);
  m.wear.resize(nf);
  m.normal_stress.resize(nf);
  m.shear_stress.resize(nf);
  for (Eigen::Index i = 0; i < nf; ++i) {
    const double zeta = m.z[i] / s.height_m, th = m.theta_deg[i];
    c.intensity_true_[i] = Abrasion(zeta);
    c.normal_[i] = NormalStress(zeta, th);
    double smooth = 0;
    for (const auto& md : modes) smooth += md.amp * std::cos(md.kth * th * kDeg + md.kz * kPi * zeta + md.ph);
    const double err = std::exp(s.dem_noise * (0.8 * gauss(rng) + 0.6 * smooth));
    m.wear[i] = c.intensity_true_[i] * err;
    m.normal_stress[i] = 2.0e5 * c.normal_[i] * std::exp(0.05 * gauss(rng));
    m.shear_stress[i] = 5.0e4 * c.intensity_true_[i] * std::exp(0.05 * gauss(rng));
  }
  const auto ns = static_cast<Eigen::Index>(s.sensors.size());
  c.sensor_intensity_.resize(ns);
  c.sensor_normal_.resize(ns);
  c.sensor_z_.resize(ns);
  c.sensor_theta_.resize(ns);
  for (Eigen::Index k = 0; k < ns; ++k) {
    const auto& x = s.sensors[static_cast<size_t>(k)];
    c.sensor_z_[k] = x.z_m;
    c.sensor_theta_[k] = x.theta_deg;
    c.sensor_intensity_[k] = Abrasion(x.z_m / s.height_m);
    c.sensor_normal_[k] = NormalStress(x.z_m / s.height_m, x.theta_deg);
  }
  // Calibration: without effects, the mean LDWN sensor wears reference_wear_mm by reference_day.
  double sum = 0;
  int cnt = 0;
  for (Eigen::Index k = 0; k < ns; ++k) {
    if (s.sensors[static_cast<size_t>(k)].row == s.rows.front().name) {
      sum += c.sensor_intensity_[k];
      ++cnt;
    }
  }
  const double mean_i = cnt ? sum / cnt : c.sensor_intensity_.maxCoeff();
  c.k_mm_per_day_ = s.reference_wear_mm / (s.reference_day * mean_i);

  c.face_now_ = Eigen::VectorXd::Zero(nf);
  c.sensor_now_ = Eigen::VectorXd::Zero(ns);
  c.face_daily_.push_back(c.face_now_);
  for (Eigen::Index k = 0; k < ns; ++k) c.sensor_hourly_flat_.push_back(0.0);

  // Operations (needed by the integration).
  const size_t hours = static_cast<size_t>(std::ceil(std::max(s.days, s.reference_day) * 24.0)) + 24 * 400;
  const Throughput tp = MakeThroughput(s, Find(s.effects, "throughput_variation"), hours, rng);
  c.operations_.clear();
  for (size_t h = 0; h < static_cast<size_t>(s.days * 24.0); ++h) {
    core::OperationsSample o;
    o.time = core::AddDays(c.crusher_.installed_at, static_cast<double>(h) / 24.0);
    o.throughput_tph = tp.tph[h];
    o.ore_ai = tp.ai[h];
    o.power_kw = 250.0 + 0.11 * tp.tph[h];
    c.operations_.push_back(o);
  }
  // Keep the wear factor series for on-demand integration.
  c.throughput_q_ = tp.q;

  c.Integrate(s.days);

  // Readings from the true sensor thickness, with faults.
  const double poll_days = s.poll_minutes / 1440.0;
  for (Eigen::Index k = 0; k < ns; ++k) {
    const auto& x = s.sensors[static_cast<size_t>(k)];
    std::vector<const FaultSpec*> faults;
    for (const auto& f : s.faults) {
      if (f.sensor == x.id) faults.push_back(&f);
    }
    double last_value = -1, last_time = -1e9;
    double crack_level = -1;
    double stuck_value = -1;
    bool flicker_phase = false;
    bool dead = false;
    const auto polls = static_cast<long>(std::floor(s.days / poll_days + 1e-9));
    for (long p = 0; p <= polls; ++p) {
      const double day = static_cast<double>(p) * poll_days;
      const double truth = c.TrueSensorThickness(static_cast<size_t>(k), day);
      double value = std::max(0.0, std::floor(truth));
      bool silent = false;
      for (const FaultSpec* f : faults) {
        if (day < f->day) continue;
        if (f->kind == "dropout" && day < f->day + std::max(0.5, f->size)) silent = true;
        if (f->kind == "flicker" && day < f->day + std::max(1.0, f->size) && truth - std::floor(truth) < 0.35) {
          flicker_phase = !flicker_phase;
          if (flicker_phase) value += 1;  // the loop at the face is still half-cut
        }
        if (f->kind == "crack") {
          if (crack_level < 0) crack_level = std::floor(c.TrueSensorThickness(static_cast<size_t>(k), f->day)) - std::max(1.0, f->size);
          value = std::min(value, crack_level);
        }
        if (f->kind == "stuck") {
          if (stuck_value < 0) stuck_value = value;
          value = stuck_value;
        }
        if (f->kind == "dead") {
          if (!dead) {
            dead = true;
            value = 0;  // every loop reads open once, then the board is silent
          } else {
            silent = true;
          }
        }
      }
      if (silent) continue;
      if (value != last_value || day - last_time >= s.heartbeat_hours / 24.0 - 1e-9) {
        const double jitter = uni(rng) * 20.0 / 86400.0;
        c.readings_.push_back({core::AddDays(c.crusher_.installed_at, day + jitter), x.id, value, 0});
        last_value = value;
        last_time = day;
      }
    }
  }

  // Laser scan of the worn surface: points on the as-new faces moved away from the axis by the
  // true wear, with noise and one occluded sector.
  if (s.write_scan) {
    const double day = s.scan_day < 0 ? s.days : s.scan_day;
    const Eigen::VectorXd wear = c.TrueFaceWear(day);
    std::vector<double> cdf(static_cast<size_t>(nf));
    double acc = 0;
    for (Eigen::Index i = 0; i < nf; ++i) cdf[static_cast<size_t>(i)] = (acc += m.areas[i]);
    const double occ = 360.0 * uni(rng);
    for (int p = 0; p < s.scan_points; ++p) {
      const double u = uni(rng) * acc;
      const auto i = static_cast<Eigen::Index>(std::lower_bound(cdf.begin(), cdf.end(), u) - cdf.begin());
      double r1 = uni(rng), r2 = uni(rng);
      if (r1 + r2 > 1) {
        r1 = 1 - r1;
        r2 = 1 - r2;
      }
      const auto& f = m.faces[static_cast<size_t>(i)];
      const Eigen::Vector3d pt = m.points[f[0]] + r1 * (m.points[f[1]] - m.points[f[0]]) + r2 * (m.points[f[2]] - m.points[f[0]]);
      double th = std::atan2(pt.y(), pt.x()) / kDeg;
      if (th < 0) th += 360;
      if (std::fmod(th - occ + 720.0, 360.0) < s.scan_occluded_deg) continue;
      const double depth_m = (wear[i] + s.scan_noise_mm * gauss(rng)) / 1000.0;
      c.scan_.push_back(pt - m.normals[static_cast<size_t>(i)] * depth_m);  // normals point inward
    }
  }
  return c;
}

void Campaign::Integrate(double to_day) const {
  const CampaignSpec& s = spec_;
  const long target = static_cast<long>(std::ceil(to_day * 24.0));
  if (target <= hours_done_) return;
  const EffectSpec* hard = Find(s.effects, "work_hardening");
  const EffectSpec* grad = Find(s.effects, "hardness_gradient");
  const EffectSpec* squeeze = Find(s.effects, "squeeze_wear");
  const EffectSpec* profile = Find(s.effects, "profile_evolution");
  const EffectSpec* feed = Find(s.effects, "feed_segregation");
  const EffectSpec* loss = Find(s.effects, "material_loss");
  const auto ns = sensor_now_.size();
  const double dt = 1.0 / 24.0;

  auto ProfileShift = [&](double day) { return profile ? Param(*profile, "p", 0.6) * 0.15 * day / s.reference_day : 0.0; };
  double profile_norm = 1.0;
  auto rate = [&](double zeta, double theta, double normal, double d, double day, double q) {
    double w = Abrasion(zeta);
    if (profile) {
      // The worn chamber nips rock higher up: the wear profile slides up the liner. The same
      // tonnage does the same total work, so the shifted profile keeps the liner-mean intensity.
      w = Abrasion(zeta - ProfileShift(day)) * profile_norm;
    }
    double m = 1.0;
    if (hard) {
      const double h = Param(*hard, "h", 0.4), tau = Param(*hard, "tau_days", 6);
      m *= 1.0 - h * std::pow(normal, 1.5) * std::tanh(day / tau);
    }
    if (grad) {
      const double cc = Param(*grad, "c", 0.2), d0 = Param(*grad, "onset_mm", 25), wd = Param(*grad, "width_mm", 30);
      m /= 1.0 - cc * SmoothStep((d - d0) / wd);
    }
    if (feed) {
      const double A = Param(*feed, "amplitude", 0.15), tf = Param(*feed, "theta_deg", 0);
      m *= 1.0 + A * std::cos((theta - tf) * kDeg) * (0.6 + 0.4 * (1.0 - zeta));
    }
    double extra = 0;
    if (squeeze) extra = Param(*squeeze, "beta", 0.2) * 0.5 * std::pow(normal, 1.2);
    return k_mm_per_day_ * q * (w * m + extra);
  };

  for (long h = hours_done_; h < target; ++h) {
    const double day = static_cast<double>(h) / 24.0;
    const double q = static_cast<size_t>(h) < throughput_q_.size() ? throughput_q_[static_cast<size_t>(h)] : 1.0;
    if (profile) {
      double a0 = 0, a1 = 0;
      for (int i = 0; i < 60; ++i) {
        const double zeta = (i + 0.5) / 60.0;
        a0 += Abrasion(zeta);
        a1 += Abrasion(zeta - ProfileShift(day));
      }
      profile_norm = a0 / a1;
    }
    for (Eigen::Index i = 0; i < face_now_.size(); ++i) {
      face_now_[i] += dt * rate(map_.z[i] / s.height_m, map_.theta_deg[i], normal_[i], face_now_[i], day, q);
    }
    for (Eigen::Index k = 0; k < ns; ++k) {
      sensor_now_[k] += dt * rate(sensor_z_[k] / s.height_m, sensor_theta_[k], sensor_normal_[k], sensor_now_[k], day, q);
    }
    if (loss) {
      const double t0 = Param(*loss, "day", 40);
      if (day <= t0 && day + dt > t0) {
        const auto si = static_cast<Eigen::Index>(Param(*loss, "sensor_index", 6));
        const double z0 = Param(*loss, "z_m", si < ns ? sensor_z_[si] : 0.5);
        const double th0 = Param(*loss, "theta_deg", si < ns ? sensor_theta_[si] : 0);
        const double depth = Param(*loss, "depth_mm", 10), sigma = Param(*loss, "radius_m", 0.1);
        const double r0 = s.r_bottom_m + (s.r_top_m - s.r_bottom_m) * z0 / s.height_m;
        auto crater = [&](double z, double th) {
          double dth = std::fmod(th - th0 + 540.0, 360.0) - 180.0;
          const double arc = r0 * dth * kDeg;
          return depth * std::exp(-((z - z0) * (z - z0) + arc * arc) / (2 * sigma * sigma));
        };
        for (Eigen::Index i = 0; i < face_now_.size(); ++i) face_now_[i] += crater(map_.z[i], map_.theta_deg[i]);
        for (Eigen::Index k = 0; k < ns; ++k) sensor_now_[k] += crater(sensor_z_[k], sensor_theta_[k]);
      }
    }
    for (Eigen::Index k = 0; k < ns; ++k) sensor_hourly_flat_.push_back(sensor_now_[k]);
    if ((h + 1) % 24 == 0) face_daily_.push_back(face_now_);
  }
  hours_done_ = target;
}

double Campaign::TrueSensorThickness(size_t index, double day) const {
  Integrate(day + 1.0 / 24.0);
  const auto ns = static_cast<size_t>(sensor_now_.size());
  const double hf = std::max(0.0, day * 24.0);
  const auto h0 = static_cast<size_t>(hf);
  const double f = hf - static_cast<double>(h0);
  const double w0 = sensor_hourly_flat_[h0 * ns + index];
  const double w1 = (h0 + 1) * ns + index < sensor_hourly_flat_.size() ? sensor_hourly_flat_[(h0 + 1) * ns + index] : w0;
  return spec_.thickness_new_mm - (w0 + f * (w1 - w0));
}

Eigen::VectorXd Campaign::TrueFaceWear(double day) const {
  Integrate(std::ceil(day) + 1.0);
  const auto d0 = static_cast<size_t>(std::max(0.0, std::floor(day)));
  const double f = day - static_cast<double>(d0);
  if (d0 + 1 >= face_daily_.size()) return face_daily_.back();
  return face_daily_[d0] + f * (face_daily_[d0 + 1] - face_daily_[d0]);
}

// ---------------------------------------------------------------------------------------------
// Output

void Campaign::WriteBundle(const std::filesystem::path& dir) const {
  namespace fs = std::filesystem;
  if (fs::exists(dir) && !(fs::is_directory(dir) && fs::is_empty(dir))) {
    throw std::runtime_error("output '" + dir.string() + "' exists and is not an empty directory");
  }
  const fs::path tmp = dir.string() + ".partial-" + std::to_string(seed_);
  fs::remove_all(tmp);
  fs::create_directories(tmp);
  try {
    nlohmann::json cj = {{"crusher_id", crusher_.crusher_id}, {"installed_at", core::FormatIsoTime(crusher_.installed_at)}};
    cj["concave"] = {{"thickness_new_mm", crusher_.thickness_new_mm}, {"thickness_min_mm", crusher_.thickness_min_mm}, {"rows", nlohmann::json::array()}};
    for (const auto& r : crusher_.rows) cj["concave"]["rows"].push_back({{"name", r.name}, {"z_min_m", r.z_min_m}, {"z_max_m", r.z_max_m}});
    cj["sensors"] = nlohmann::json::array();
    for (const auto& x : crusher_.sensors) {
      cj["sensors"].push_back({{"id", x.id}, {"row", x.row}, {"z_m", x.z_m}, {"theta_deg", x.theta_deg}, {"thickness_new_mm", x.thickness_new_mm}});
    }
    std::ofstream(tmp / "crusher.json") << cj.dump(2) << "\n";
    // Marks the folder as generated: `linerwatch-sim run` regenerates this truth from it.
    std::ofstream(tmp / "campaign.json") << nlohmann::json{{"generator", "linerwatch-sim campaign"}, {"seed", seed_}, {"spec", spec_.ToJson()}}.dump(1) << "\n";
    core::WriteWearMapVtk(tmp / "wear_map.vtk", map_,
                          {{"wear", &map_.wear}, {"normal_stress_average", &map_.normal_stress}, {"shear_stress_average", &map_.shear_stress}});
    {
      std::ofstream r(tmp / "readings.csv");
      r << "time,sensor_id,thickness_mm\n";
      for (const auto& x : readings_) r << core::FormatIsoTime(x.time) << ',' << x.sensor_id << ',' << x.thickness_mm << '\n';
    }
    if (spec_.write_operations) {
      std::ofstream o(tmp / "operations.csv");
      o << "time,throughput_tph,power_kw,ore_ai\n";
      o.setf(std::ios::fixed);
      o.precision(2);
      for (const auto& x : operations_) o << core::FormatIsoTime(x.time) << ',' << x.throughput_tph << ',' << *x.power_kw << ',' << *x.ore_ai << '\n';
    }
    if (spec_.write_scan && !scan_.empty()) {
      fs::create_directories(tmp / "scans");
      const double day = spec_.scan_day < 0 ? spec_.days : spec_.scan_day;
      const std::string date = Iso(crusher_.installed_at, day).substr(0, 10);
      std::ofstream sc(tmp / "scans" / ("scan_" + date + ".xyz"));
      sc.setf(std::ios::fixed);
      sc.precision(5);
      for (const auto& p : scan_) sc << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
    }
  } catch (...) {
    fs::remove_all(tmp);
    throw;
  }
  if (fs::exists(dir)) fs::remove(dir);
  fs::rename(tmp, dir);
}

nlohmann::json Campaign::TruthJson() const {
  nlohmann::json j;
  j["seed"] = seed_;
  j["spec"] = spec_.ToJson();
  j["k_mm_per_day"] = k_mm_per_day_;
  j["sensors"] = nlohmann::json::object();
  for (size_t k = 0; k < crusher_.sensors.size(); ++k) {
    nlohmann::json series = nlohmann::json::array();
    for (int d = 0; d <= static_cast<int>(spec_.days); ++d) series.push_back(TrueSensorThickness(k, d));
    j["sensors"][crusher_.sensors[k].id] = {{"true_thickness_mm_daily", series}};
  }
  return j;
}

}  // namespace lw::sim
