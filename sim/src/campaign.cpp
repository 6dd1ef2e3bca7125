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

#include "campaign_model.hpp"

namespace lw::sim {
using namespace model;

// ---------------------------------------------------------------------------------------------
// Generation

namespace {

struct Throughput {
  std::vector<double> q;  // hourly relative wear-rate factor from tonnage x abrasiveness
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

// The one random stream of a campaign, drawn from by every stage in turn (the normal distribution
// keeps its second value between draws, so it is one object too): a seed gives one campaign.
struct Draws {
  explicit Draws(uint64_t seed) : rng(seed) {}
  std::mt19937_64 rng;
  std::normal_distribution<double> gauss{0.0, 1.0};
  std::uniform_real_distribution<double> uni{0.0, 1.0};
};

core::CrusherConfig MakeCrusher(const CampaignSpec& s) {
  core::CrusherConfig crusher;
  crusher.crusher_id = s.crusher_id;
  crusher.installed_at = *core::ParseIsoTime(s.installed_at);
  crusher.thickness_new_mm = s.thickness_new_mm;
  crusher.thickness_min_mm = s.thickness_min_mm;
  crusher.rows = s.rows;
  for (const auto& x : s.sensors) crusher.sensors.push_back({x.id, x.row, x.z_m, x.theta_deg, s.thickness_new_mm, {}});
  return crusher;
}

// Mesh: truncated cone, n_theta x n_z quads split in two triangles, wound inward.
core::WearMap MakeMesh(const CampaignSpec& s) {
  auto radius_at = [&](double z) { return s.r_bottom_m + (s.r_top_m - s.r_bottom_m) * z / s.height_m; };
  core::WearMap m;
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
  return m;
}

// Fields. The DEM map = true abrasion intensity x DEM error: per-face scatter plus patchy,
// spatially correlated error at the scale of contact patches (several random modes, 3-8 waves
// around the circumference, 2-5 along z): what a finite DEM run leaves in its averages.
void MakeFields(const CampaignSpec& s, Draws& draws, core::WearMap& m, Eigen::VectorXd& intensity_true, Eigen::VectorXd& normal) {
  auto& [rng, gauss, uni] = draws;
  const auto nf = static_cast<Eigen::Index>(m.face_count());
  struct Mode {
    double amp, kth, kz, ph;
  };
  std::vector<Mode> modes;
  for (int i = 0; i < 6; ++i) {
    modes.push_back(
        {gauss(rng) * 0.4, static_cast<double>(3 + static_cast<int>(uni(rng) * 6)), 2.0 + 3.0 * uni(rng), 2 * kPi * uni(rng)});
  }
  intensity_true.resize(nf);
  normal.resize(nf);
  m.wear.resize(nf);
  m.normal_stress.resize(nf);
  m.shear_stress.resize(nf);
  for (Eigen::Index i = 0; i < nf; ++i) {
    const double zeta = m.z[i] / s.height_m, th = m.theta_deg[i];
    intensity_true[i] = Abrasion(zeta);
    normal[i] = NormalStress(zeta, th);
    double smooth = 0;
    for (const auto& md : modes) smooth += md.amp * std::cos(md.kth * th * kDeg + md.kz * kPi * zeta + md.ph);
    const double err = std::exp(s.dem_noise * (0.8 * gauss(rng) + 0.6 * smooth));
    m.wear[i] = intensity_true[i] * err;
    m.normal_stress[i] = 2.0e5 * normal[i] * std::exp(0.05 * gauss(rng));
    m.shear_stress[i] = 5.0e4 * intensity_true[i] * std::exp(0.05 * gauss(rng));
  }
}

// Where each sensor sits and the true intensity and normal stress there.
void PlaceSensors(const CampaignSpec& s, Eigen::VectorXd& intensity, Eigen::VectorXd& normal, Eigen::VectorXd& z,
                  Eigen::VectorXd& theta) {
  const auto ns = static_cast<Eigen::Index>(s.sensors.size());
  intensity.resize(ns);
  normal.resize(ns);
  z.resize(ns);
  theta.resize(ns);
  for (Eigen::Index k = 0; k < ns; ++k) {
    const auto& x = s.sensors[static_cast<size_t>(k)];
    z[k] = x.z_m;
    theta[k] = x.theta_deg;
    intensity[k] = Abrasion(x.z_m / s.height_m);
    normal[k] = NormalStress(x.z_m / s.height_m, x.theta_deg);
  }
}

// Calibration: without effects, the mean LDWN sensor wears reference_wear_mm by reference_day.
double WearRate(const CampaignSpec& s, const Eigen::VectorXd& sensor_intensity) {
  double sum = 0;
  int cnt = 0;
  for (Eigen::Index k = 0; k < sensor_intensity.size(); ++k) {
    if (s.sensors[static_cast<size_t>(k)].row == s.rows.front().name) {
      sum += sensor_intensity[k];
      ++cnt;
    }
  }
  const double mean_i = cnt ? sum / cnt : sensor_intensity.maxCoeff();
  return s.reference_wear_mm / (s.reference_day * mean_i);
}

std::vector<core::OperationsSample> MakeOperations(const CampaignSpec& s, const Throughput& tp, core::TimePoint installed_at) {
  std::vector<core::OperationsSample> operations;
  for (size_t h = 0; h < static_cast<size_t>(s.days * 24.0); ++h) {
    core::OperationsSample o;
    o.time = core::AddDays(installed_at, static_cast<double>(h) / 24.0);
    o.throughput_tph = tp.tph[h];
    o.ore_ai = tp.ai[h];
    o.power_kw = 250.0 + 0.11 * tp.tph[h];
    operations.push_back(o);
  }
  return operations;
}

// Readings of sensor `k` from its true thickness, with its faults, appended to `readings`.
void ReadSensor(const Campaign& c, size_t k, Draws& draws, std::vector<core::Reading>& readings) {
  const CampaignSpec& s = c.spec();
  const double poll_days = s.poll_minutes / 1440.0;
  const auto& x = s.sensors[k];
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
    const double truth = c.TrueSensorThickness(k, day);
    double value = std::max(0.0, std::floor(truth));
    bool silent = false;
    for (const FaultSpec* f : faults) {
      if (day < f->day) continue;
      if (f->kind == "dropout" && day < f->day + std::max(0.5, f->size)) silent = true;
      if (f->kind == "flicker" && day < f->day + std::max(1.0, f->size) && truth - std::floor(truth) < 0.35) {
        flicker_phase = !flicker_phase;
        // The loop at the face is still half-cut; a new liner has no loop above its face, so the
        // ladder never reads more than its top.
        if (flicker_phase) value = std::min(value + 1, std::floor(s.thickness_new_mm));
      }
      if (f->kind == "crack") {
        if (crack_level < 0) crack_level = std::floor(c.TrueSensorThickness(k, f->day)) - std::max(1.0, f->size);
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
      const double jitter = draws.uni(draws.rng) * 20.0 / 86400.0;
      readings.push_back({core::AddDays(c.crusher().installed_at, day + jitter), x.id, value, 0});
      last_value = value;
      last_time = day;
    }
  }
}

// Laser scan of the worn surface: points on the as-new faces moved away from the axis by the
// true wear, with noise and one occluded sector.
std::vector<Eigen::Vector3d> Scan(const Campaign& c, Draws& draws) {
  auto& [rng, gauss, uni] = draws;
  const CampaignSpec& s = c.spec();
  const core::WearMap& m = c.map();
  const auto nf = static_cast<Eigen::Index>(m.face_count());
  std::vector<Eigen::Vector3d> scan;
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
    scan.push_back(pt - m.normals[static_cast<size_t>(i)] * depth_m);  // normals point inward
  }
  return scan;
}

}  // namespace

Campaign GenerateCampaign(const CampaignSpec& input, uint64_t seed) {
  Campaign c;
  c.spec_ = input;
  c.spec_.Complete();
  c.seed_ = seed;
  const CampaignSpec& s = c.spec_;
  Draws draws(seed);

  c.crusher_ = MakeCrusher(s);
  c.map_ = MakeMesh(s);
  MakeFields(s, draws, c.map_, c.intensity_true_, c.normal_);
  const auto nf = static_cast<Eigen::Index>(c.map_.face_count());
  const auto ns = static_cast<Eigen::Index>(s.sensors.size());
  PlaceSensors(s, c.sensor_intensity_, c.sensor_normal_, c.sensor_z_, c.sensor_theta_);
  c.k_mm_per_day_ = WearRate(s, c.sensor_intensity_);

  // The integrated truth starts from no wear at hour 0.
  c.face_now_ = Eigen::VectorXd::Zero(nf);
  c.sensor_now_ = Eigen::VectorXd::Zero(ns);
  c.face_daily_.push_back(c.face_now_);
  for (Eigen::Index k = 0; k < ns; ++k) c.sensor_hourly_flat_.push_back(0.0);

  // Operations (needed by the integration).
  const size_t hours = static_cast<size_t>(std::ceil(std::max(s.days, s.reference_day) * 24.0)) + 24 * 400;
  const Throughput tp = MakeThroughput(s, Find(s.effects, "throughput_variation"), hours, draws.rng);
  c.operations_ = MakeOperations(s, tp, c.crusher_.installed_at);
  // Keep the wear factor series for on-demand integration.
  c.throughput_q_ = tp.q;

  c.Integrate(s.days);

  for (Eigen::Index k = 0; k < ns; ++k) ReadSensor(c, static_cast<size_t>(k), draws, c.readings_);
  if (s.write_scan) c.scan_ = Scan(c, draws);
  return c;
}

// ---------------------------------------------------------------------------------------------
// Output

void Campaign::WriteBundle(const std::filesystem::path& dir) const {
  core::Bundle b;
  b.crusher = crusher_;
  b.map = map_;
  b.readings = readings_;
  if (spec_.write_operations) b.operations = operations_;
  if (spec_.write_scan && !scan_.empty()) {
    const double day = spec_.scan_day < 0 ? spec_.days : spec_.scan_day;
    b.scans.push_back({core::AddDays(crusher_.installed_at, day), "", scan_});
  }
  // campaign.json marks the folder as generated: `linerwatch-sim run` regenerates this truth from it.
  core::WriteBundle(
      b, dir,
      {{"campaign.json",
        nlohmann::json{{"generator", "linerwatch-sim campaign"}, {"seed", seed_}, {"spec", spec_.ToJson()}}.dump(1) + "\n"}});
}

}  // namespace lw::sim
