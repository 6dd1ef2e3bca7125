#include "dem/chamber.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>

namespace lw::dem {
namespace {

constexpr double kPi = 3.14159265358979323846;

[[noreturn]] void Fail(const std::string& file, const std::string& key, const std::string& rule) {
  throw std::invalid_argument(file + ": chamber." + key + ": " + rule);
}

double Number(const nlohmann::json& obj, const std::string& key, double fallback, const std::string& file,
              const std::string& path, double lo, double hi) {
  if (!obj.contains(key)) return fallback;
  const auto& v = obj.at(key);
  if (!v.is_number()) Fail(file, path + key, "must be a number");
  const double x = v.get<double>();
  if (!std::isfinite(x) || x < lo || x > hi)
    Fail(file, path + key, "must be between " + nlohmann::json(lo).dump() + " and " + nlohmann::json(hi).dump());
  return x;
}

void CheckKeys(const nlohmann::json& obj, const std::set<std::string>& known, const std::string& file, const std::string& path) {
  for (auto it = obj.begin(); it != obj.end(); ++it)
    if (!known.count(it.key())) Fail(file, path + it.key(), "unknown key (see docs/dem.md)");
}

Profile ProfileFromJson(const nlohmann::json& v, const std::string& file, const std::string& path) {
  if (!v.is_array() || v.size() < 2) Fail(file, path, "must be an array of at least two [z_m, r_m] points");
  Profile p;
  for (const auto& pt : v) {
    if (!pt.is_array() || pt.size() != 2 || !pt[0].is_number() || !pt[1].is_number())
      Fail(file, path, "every point must be [z_m, r_m]");
    const double z = pt[0].get<double>(), r = pt[1].get<double>();
    if (!std::isfinite(z) || !std::isfinite(r) || r <= 0 || r > 10 || std::abs(z) > 20)
      Fail(file, path, "point [" + std::to_string(z) + ", " + std::to_string(r) + "] is out of range (0 < r <= 10 m)");
    if (!p.points.empty() && z <= p.points.back().first) Fail(file, path, "z must increase from point to point");
    p.points.push_back({z, r});
  }
  return p;
}

}  // namespace

double Profile::RadiusAt(double z) const {
  if (z <= points.front().first) return points.front().second;
  if (z >= points.back().first) return points.back().second;
  for (size_t i = 1; i < points.size(); ++i) {
    if (z <= points[i].first) {
      const auto& a = points[i - 1];
      const auto& b = points[i];
      return a.second + (b.second - a.second) * (z - a.first) / (b.first - a.first);
    }
  }
  return points.back().second;
}

double ChamberSpec::closed_side_setting_m() const {
  return concave.RadiusAt(0.0) - mantle.RadiusAt(0.0) - eccentric_throw_m;
}
double ChamberSpec::open_side_setting_m() const {
  return concave.RadiusAt(0.0) - mantle.RadiusAt(0.0) + eccentric_throw_m;
}
double ChamberSpec::max_radius_m() const {
  double r = 0;
  for (const auto& c : psd) r = std::max(r, c.radius_m);
  return r;
}
double ChamberSpec::min_radius_m() const {
  double r = 1e9;
  for (const auto& c : psd) r = std::min(r, c.radius_m);
  return r;
}
double ChamberSpec::rayleigh_time_s() const {
  const double shear = youngs_modulus_pa / (2.0 * (1.0 + poisson_ratio));
  return kPi * min_radius_m() * std::sqrt(density_kg_m3 / shear) / (0.1631 * poisson_ratio + 0.8766);
}

ChamberSpec ChamberFromCrusherJson(const nlohmann::json& crusher, const std::string& file) {
  ChamberSpec s;
  if (crusher.contains("crusher_id") && crusher["crusher_id"].is_string()) s.name = crusher["crusher_id"].get<std::string>();
  nlohmann::json c = nlohmann::json::object();
  if (crusher.contains("chamber")) {
    c = crusher.at("chamber");
    if (!c.is_object()) throw std::invalid_argument(file + ": chamber: must be an object (docs/dem.md)");
  }
  CheckKeys(c, {"concave",       "mantle",        "css_m",       "eccentric_throw_m", "speed_rpm",       "feed_rate_tph",
                "psd",           "density_kg_m3", "simulated_s", "timestep_s",        "dump_interval_s", "youngs_modulus_pa",
                "poisson_ratio", "restitution",   "friction",    "rolling_friction",  "finnie_k",        "mesh_n_theta",
                "mesh_n_z",      "seed",          "windows"},
            file, "");

  // Concave: a cone (height, bottom and top radius) or a profile.
  const nlohmann::json concave = c.value("concave", nlohmann::json::object());
  if (!concave.is_object()) Fail(file, "concave", "must be an object");
  CheckKeys(concave, {"height_m", "r_bottom_m", "r_top_m", "profile"}, file, "concave.");
  if (concave.contains("profile")) {
    s.concave = ProfileFromJson(concave["profile"], file, "concave.profile");
    if (std::abs(s.concave.z_min()) > 1e-9) Fail(file, "concave.profile", "must start at z = 0 (the discharge edge)");
  } else {
    const double h = Number(concave, "height_m", 3.0, file, "concave.", 0.3, 10);
    const double rb = Number(concave, "r_bottom_m", 1.15, file, "concave.", 0.1, 10);
    const double rt = Number(concave, "r_top_m", 1.90, file, "concave.", 0.1, 10);
    s.concave.points = {{0.0, rb}, {h, rt}};
  }
  s.eccentric_throw_m = Number(c, "eccentric_throw_m", 0.03, file, "", 0.0, 0.2);

  // Mantle: a cone from its bottom radius at z = 0 to its top, or a profile.
  const nlohmann::json mantle = c.value("mantle", nlohmann::json::object());
  if (!mantle.is_object()) Fail(file, "mantle", "must be an object");
  CheckKeys(mantle, {"r_bottom_m", "r_top_m", "z_top_m", "z_bottom_m", "profile"}, file, "mantle.");
  if (mantle.contains("profile")) {
    s.mantle = ProfileFromJson(mantle["profile"], file, "mantle.profile");
    if (c.contains("css_m")) Fail(file, "css_m", "give either css_m or a mantle profile, not both");
  } else {
    const double css = Number(c, "css_m", 0.19, file, "", 0.01, 1.0);
    if (mantle.contains("r_bottom_m") && c.contains("css_m"))
      Fail(file, "css_m", "give either css_m or mantle.r_bottom_m, not both");
    const double rb = mantle.contains("r_bottom_m") ? Number(mantle, "r_bottom_m", 0, file, "mantle.", 0.05, 10)
                                                    : s.concave.RadiusAt(0.0) - css - s.eccentric_throw_m;
    const double rt = Number(mantle, "r_top_m", 0.30, file, "mantle.", 0.05, 10);
    const double zt = Number(mantle, "z_top_m", 0.92 * s.height_m(), file, "mantle.", 0.1, 12);
    const double zb = Number(mantle, "z_bottom_m", -0.4, file, "mantle.", -3, -0.05);
    if (rb <= 0.05) Fail(file, "css_m", "leaves no room for a mantle (bottom radius " + std::to_string(rb) + " m)");
    const double slope = (rt - rb) / zt;
    s.mantle.points = {{zb, rb + slope * zb}, {0.0, rb}, {zt, rt}};
  }
  if (s.mantle.z_min() > -0.05) Fail(file, "mantle", "must reach below the discharge edge (z < 0)");
  if (s.mantle.z_max() < 0.75 * s.height_m()) Fail(file, "mantle", "must reach at least three quarters of the concave's height");

  s.speed_rpm = Number(c, "speed_rpm", 150, file, "", 10, 3000);
  s.feed_rate_tph = Number(c, "feed_rate_tph", 40000, file, "", 1, 1e6);
  s.density_kg_m3 = Number(c, "density_kg_m3", 2700, file, "", 500, 10000);
  s.simulated_s = Number(c, "simulated_s", 16, file, "", 0.01, 3600);
  s.timestep_s = Number(c, "timestep_s", 4e-4, file, "", 1e-7, 1e-2);
  s.dump_interval_s = Number(c, "dump_interval_s", 0.5, file, "", 1e-4, 100);
  s.youngs_modulus_pa = Number(c, "youngs_modulus_pa", 1e7, file, "", 1e5, 1e12);
  s.poisson_ratio = Number(c, "poisson_ratio", 0.3, file, "", 0.0, 0.49);
  s.restitution = Number(c, "restitution", 0.3, file, "", 0.01, 0.99);
  s.friction = Number(c, "friction", 0.6, file, "", 0.0, 2.0);
  s.rolling_friction = Number(c, "rolling_friction", 0.3, file, "", 0.0, 2.0);
  s.finnie_k = Number(c, "finnie_k", 1.0, file, "", 1e-9, 1e9);
  s.mesh_n_theta = static_cast<int>(Number(c, "mesh_n_theta", 96, file, "", 8, 2000));
  s.mesh_n_z = static_cast<int>(Number(c, "mesh_n_z", 36, file, "", 2, 2000));
  s.seed = static_cast<unsigned>(Number(c, "seed", 1, file, "", 0, 1e6));
  s.windows = static_cast<int>(Number(c, "windows", 0, file, "", 0, 100));
  if (s.windows == 1) Fail(file, "windows", "must be 0 (automatic) or at least 2");

  if (c.contains("psd")) {
    const auto& p = c["psd"];
    if (!p.is_array() || p.empty()) Fail(file, "psd", "must be a non-empty array of {\"size_mm\", \"mass_fraction\"}");
    for (const auto& e : p) {
      if (!e.is_object() || !e.contains("size_mm") || !e.contains("mass_fraction"))
        Fail(file, "psd", "every class needs \"size_mm\" (sphere diameter) and \"mass_fraction\"");
      CheckKeys(e, {"size_mm", "mass_fraction"}, file, "psd[].");
      SizeClass sc;
      sc.radius_m = Number(e, "size_mm", 0, file, "psd[].", 1, 3000) / 2000.0;
      sc.mass_fraction = Number(e, "mass_fraction", 0, file, "psd[].", 1e-6, 1);
      s.psd.push_back(sc);
    }
  } else {
    s.psd = {{0.045, 0.3}, {0.060, 0.4}, {0.075, 0.3}};
  }
  double sum = 0;
  for (const auto& sc : s.psd) sum += sc.mass_fraction;
  if (std::abs(sum - 1.0) > 1e-3) Fail(file, "psd", "mass fractions sum to " + std::to_string(sum) + ", not 1");

  // Consistency: the chamber must pass its largest particle and keep the mantle off the concave.
  for (int i = 0; i <= 100; ++i) {
    const double z = s.height_m() * i / 100.0;
    if (s.concave.RadiusAt(z) - s.mantle.RadiusAt(z) - s.eccentric_throw_m <= 0)
      Fail(file, "mantle", "touches the concave at z = " + std::to_string(z) + " m during gyration");
  }
  const double css = s.closed_side_setting_m();
  if (css < 2.0 * s.max_radius_m() * 1.1)
    Fail(file, "psd",
         "the largest particle (" + std::to_string(2000 * s.max_radius_m()) + " mm) does not pass the closed side setting (" +
             std::to_string(1000 * css) +
             " mm): with no breakage in LIGGGHTS-PUBLIC the chamber would jam; feed the product size range");
  if (s.timestep_s > 0.2 * s.rayleigh_time_s())
    Fail(file, "timestep_s",
         "is " + std::to_string(s.timestep_s) + " s, above 20 % of the Rayleigh time of the smallest particle (" +
             std::to_string(s.rayleigh_time_s()) + " s)");
  if (s.dump_interval_s < s.timestep_s) Fail(file, "dump_interval_s", "is shorter than the time step");
  if (s.simulated_s < 4 * s.dump_interval_s) Fail(file, "simulated_s", "must cover at least 4 dump intervals");
  return s;
}

nlohmann::json ToJson(const ChamberSpec& s) {
  nlohmann::json j;
  auto profile = [](const Profile& p) {
    nlohmann::json a = nlohmann::json::array();
    for (const auto& [z, r] : p.points) a.push_back({z, r});
    return a;
  };
  j["concave"] = {{"profile", profile(s.concave)}};
  j["mantle"] = {{"profile", profile(s.mantle)}};
  j["eccentric_throw_m"] = s.eccentric_throw_m;
  j["speed_rpm"] = s.speed_rpm;
  j["feed_rate_tph"] = s.feed_rate_tph;
  j["psd"] = nlohmann::json::array();
  for (const auto& c : s.psd) j["psd"].push_back({{"size_mm", c.radius_m * 2000.0}, {"mass_fraction", c.mass_fraction}});
  j["density_kg_m3"] = s.density_kg_m3;
  j["simulated_s"] = s.simulated_s;
  j["timestep_s"] = s.timestep_s;
  j["dump_interval_s"] = s.dump_interval_s;
  j["youngs_modulus_pa"] = s.youngs_modulus_pa;
  j["poisson_ratio"] = s.poisson_ratio;
  j["restitution"] = s.restitution;
  j["friction"] = s.friction;
  j["rolling_friction"] = s.rolling_friction;
  j["finnie_k"] = s.finnie_k;
  j["mesh_n_theta"] = s.mesh_n_theta;
  j["mesh_n_z"] = s.mesh_n_z;
  j["seed"] = s.seed;
  j["windows"] = s.windows;
  return j;
}

}  // namespace lw::dem
