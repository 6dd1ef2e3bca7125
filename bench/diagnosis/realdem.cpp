#include "realdem.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <random>
#include <stdexcept>

#include "core/reconstruction.hpp"
#include "core/surface_index.hpp"

namespace lw::bench {
namespace {

constexpr double kPi = 3.14159265358979323846;

std::string Iso(const core::TimePoint& t0, double days) {
  return core::FormatIsoTime(core::AddDays(t0, days));
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

double Quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())))];
}

// CELL_DATA SCALARS arrays of a legacy ASCII VTK (name -> values), each of `faces` values.
std::map<std::string, Eigen::VectorXd> ReadCellScalars(const std::filesystem::path& path, size_t faces) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open " + path.string());
  std::map<std::string, Eigen::VectorXd> out;
  std::string tok;
  bool cell = false;
  while (in >> tok) {
    if (tok == "CELL_DATA") {
      size_t n = 0;
      in >> n;
      if (n != faces)
        throw std::runtime_error(path.string() + ": CELL_DATA " + std::to_string(n) + " != " + std::to_string(faces) +
                                 " faces of wear_map.vtk");
      cell = true;
    } else if (tok == "POINT_DATA") {
      cell = false;
    } else if (tok == "SCALARS" && cell) {
      std::string name, type, lut, lut_name;
      in >> name >> type >> lut;
      if (lut != "LOOKUP_TABLE") in >> lut;  // component count given
      in >> lut_name;
      Eigen::VectorXd v(static_cast<Eigen::Index>(faces));
      for (size_t i = 0; i < faces; ++i)
        if (!(in >> v[static_cast<Eigen::Index>(i)])) throw std::runtime_error(path.string() + ": array " + name + " is short");
      out[name] = v;
    }
  }
  return out;
}

/// The truth's smoothing evaluated at a point (z, theta): a top-hat over the faces within the
/// index's reach, a plain area-weighted mean or local-linear in z (RealDemSpec::truth_local_linear).
/// NaN where no face is within reach.
double SmoothTruthAt(const core::WearMap& map, const core::SurfaceIndex& index, const Eigen::VectorXd& values, double z,
                     double theta_deg, double radius, bool local_linear) {
  double s0 = 0, s1 = 0, s2 = 0, t0 = 0, t1 = 0;
  index.ForEachWithin(z, theta_deg, radius, [&](uint32_t j, double) {
    const auto jj = static_cast<Eigen::Index>(j);
    const double a = map.areas[jj], dz = map.z[jj] - z, v = values[jj];
    s0 += a;
    s1 += a * dz;
    s2 += a * dz * dz;
    t0 += a * v;
    t1 += a * dz * v;
  });
  if (!(s0 > 0)) return std::numeric_limits<double>::quiet_NaN();
  const double det = s0 * s2 - s1 * s1;
  if (local_linear && det > 1e-6 * s0 * s2 && s2 > 0) return std::max(0.0, (s2 * t0 - s1 * t1) / det);
  return t0 / s0;
}

/// The truth's smoothing over every face (SmoothTruthAt at each face's centroid).
Eigen::VectorXd SmoothTruth(const core::WearMap& map, const Eigen::VectorXd& values, double radius, bool local_linear) {
  if (!local_linear) return core::SmoothOverSurface(map, values, radius);
  const Eigen::Index n = values.size();
  if (radius <= 0 || n == 0) return values;
  const core::SurfaceIndex index(map, radius);
  Eigen::VectorXd out(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double v = SmoothTruthAt(map, index, values, map.z[i], map.theta_deg[i], map.radius[i], true);
    out[i] = std::isfinite(v) ? v : values[i];
  }
  return out;
}

}  // namespace

std::vector<DemRun> LoadDemRuns(const std::filesystem::path& dir) {
  std::vector<std::filesystem::path> folders;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.is_directory() && std::filesystem::exists(e.path() / "wear_windows.vtk") &&
        std::filesystem::exists(e.path() / "crusher.json"))
      folders.push_back(e.path());
  std::sort(folders.begin(), folders.end());
  std::vector<DemRun> runs;
  for (const auto& f : folders) {
    DemRun r;
    r.name = f.filename().string();
    r.dir = f;
    r.crusher = core::LoadCrusherConfig(f / "crusher.json");
    // Geometry from wear_map.vtk (the same mesh); the per-window arrays from wear_windows.vtk (no
    // `wear` array there, so not a map core's importer accepts: read its CELL_DATA SCALARS here).
    r.mesh = core::LoadWearMap(f / "wear_map.vtk");
    const auto arrays = ReadCellScalars(f / "wear_windows.vtk", r.mesh.face_count());
    for (int k = 1;; ++k) {
      const auto w = arrays.find("wear_w" + std::to_string(k));
      if (w == arrays.end()) break;
      r.wear_w.push_back(w->second);
      const auto n = arrays.find("normal_stress_w" + std::to_string(k));
      if (n != arrays.end()) r.normal_w.push_back(n->second);
    }
    if (r.normal_w.size() != r.wear_w.size()) r.normal_w.clear();
    if (r.wear_w.size() < 4) throw std::runtime_error(f.string() + ": fewer than 4 wear windows");
    runs.push_back(std::move(r));
  }
  return runs;
}

void ShrinkTowardsFinerPrototype(core::ReconstructionPlan& plan, double hz_m, double ha_m) {
  const core::WearMap& m = *plan.map;
  const core::MapModel& model = plan.model;
  const Eigen::Index n = m.z.size();
  // Kernel mean and its noise variance at (z, theta), brute force (a measurement, 4,320 faces).
  auto fine = [&](double z, double th, double& value, double& var) {
    double s0 = 0, s1 = 0, s2 = 0;
    for (Eigen::Index j = 0; j < n; ++j) {
      const double dz = m.z[j] - z;
      if (std::fabs(dz) > 3 * hz_m) continue;
      const double arc = m.radius[j] * (std::fmod(m.theta_deg[j] - th + 540.0, 360.0) - 180.0) * kPi / 180.0;
      const double q = dz * dz / (hz_m * hz_m) + arc * arc / (ha_m * ha_m);
      if (q > 9) continue;
      const double w = m.areas[j] * std::exp(-0.5 * q);
      s0 += w;
      s1 += w * model.clean[j];
      s2 += w * w * model.face_var[j];
    }
    value = s0 > 0 ? s1 / s0 : 0.0;
    var = s0 > 0 ? s2 / (s0 * s0) : 0.0;
  };
  auto band = [](double z) { return static_cast<long>(std::floor(z / 0.1)); };
  Eigen::VectorXd L(n), VL(n);
  std::map<long, std::pair<double, double>> excess;  // band -> (sum of relative excess, faces)
  for (Eigen::Index i = 0; i < n; ++i) {
    fine(m.z[i], m.theta_deg[i], L[i], VL[i]);
    const double B = plan.intensity[i];
    if (!(B > 0)) continue;
    const double d = (L[i] - B) / B;
    auto& e = excess[band(m.z[i])];
    e.first += d * d - VL[i] / (B * B);
    e.second += 1;
  }
  auto shrink = [&](double B, double l, double vl, double z) {
    const auto it = excess.find(band(z));
    if (!(B > 0) || it == excess.end()) return B;
    const double tau2 = std::max(0.0, it->second.first / it->second.second) * B * B;
    return tau2 + vl > 0 ? B + tau2 / (tau2 + vl) * (l - B) : B;
  };
  for (Eigen::Index i = 0; i < n; ++i) plan.intensity[i] = shrink(plan.intensity[i], L[i], VL[i], m.z[i]);
  for (size_t s = 0; s < plan.crusher->sensors.size(); ++s) {
    const auto& sn = plan.crusher->sensors[s];
    double l = 0, vl = 0;
    fine(sn.z_m, sn.theta_deg, l, vl);
    const auto k = static_cast<Eigen::Index>(s);
    plan.sensor_intensity[k] = shrink(plan.sensor_intensity[k], l, vl, sn.z_m);
  }
}

WindowSplitChoice ChooseScaleByWindowSplit(const core::WearMap& m, const std::vector<Eigen::VectorXd>& windows) {
  WindowSplitChoice out;
  const size_t K = windows.size();
  const Eigen::Index n = m.z.size();
  if (K < 2 || n == 0) return out;
  std::vector<double> sizes;
  for (Eigen::Index i = 0; i < n; ++i) sizes.push_back(std::sqrt(2.0 * std::max(m.areas[i], 0.0)));
  const double face = std::max(Median(sizes), 1e-4);
  const double extent = std::max(m.z.maxCoeff() - m.z.minCoeff(), 10 * face);
  const double half_circ = kPi * std::max(1e-3, m.radius.mean());
  // Faces by z, so each face visits only the band of z its kernel reaches.
  std::vector<Eigen::Index> order(static_cast<size_t>(n));
  std::iota(order.begin(), order.end(), Eigen::Index{0});
  std::sort(order.begin(), order.end(), [&](Eigen::Index a, Eigen::Index b) { return m.z[a] < m.z[b]; });
  std::vector<double> zs;
  for (Eigen::Index i : order) zs.push_back(m.z[i]);
  double best = std::numeric_limits<double>::max();
  std::vector<std::tuple<double, double, double>> curve;
  for (double hz = face; hz <= 0.2 * extent + 1e-12; hz *= 1.4) {
    for (double ratio : {1.0, 3.0, 8.0, 24.0}) {
      const double ha = std::min(ratio * hz, half_circ);
      if (ratio > 1.0 && ha <= hz * 1.01) continue;
      std::vector<Eigen::VectorXd> S(K, Eigen::VectorXd::Zero(n));
      for (Eigen::Index i = 0; i < n; ++i) {
        const auto b = std::lower_bound(zs.begin(), zs.end(), m.z[i] - 2.5 * hz) - zs.begin();
        const auto e = std::upper_bound(zs.begin(), zs.end(), m.z[i] + 2.5 * hz) - zs.begin();
        double s0 = 0;
        std::vector<double> sy(K, 0.0);
        for (auto p = b; p < e; ++p) {
          const Eigen::Index j = order[static_cast<size_t>(p)];
          const double dz = m.z[j] - m.z[i];
          const double arc = 0.5 * (m.radius[i] + m.radius[j]) *
                             (std::fmod(m.theta_deg[j] - m.theta_deg[i] + 540.0, 360.0) - 180.0) * kPi / 180.0;
          const double q = dz * dz / (hz * hz) + arc * arc / (ha * ha);
          if (q > 6.25) continue;
          const double w = m.areas[j] * std::exp(-0.5 * q);
          s0 += w;
          for (size_t k = 0; k < K; ++k) sy[k] += w * std::max(0.0, windows[k][j]);
        }
        for (size_t k = 0; k < K; ++k) S[k][i] = s0 > 0 ? sy[k] / s0 : std::max(0.0, windows[k][i]);
      }
      const double kd = static_cast<double>(K);
      double cv = 0, var1 = 0;
      for (Eigen::Index i = 0; i < n; ++i) {
        double mean = 0;
        for (size_t k = 0; k < K; ++k) mean += S[k][i];
        mean /= kd;
        double ss = 0;
        for (size_t k = 0; k < K; ++k) {
          const double train = (mean * kd - S[k][i]) / (kd - 1.0);
          cv += m.areas[i] * std::pow(train - std::max(0.0, windows[k][i]), 2);
          ss += std::pow(S[k][i] - mean, 2);
        }
        var1 += m.areas[i] * ss / (kd - 1.0);
      }
      const double score = cv / kd - var1 * (1.0 / (kd - 1.0) - 1.0 / kd);
      curve.emplace_back(hz, ha, score);
      if (score < best) {
        best = score;
        out.hz = hz;
        out.ha = ha;
      }
    }
  }
  for (auto& [hz, ha, sc] : curve) out.curve.emplace_back(hz, ha, best > 0 ? sc / best : 1.0);
  return out;
}

std::vector<Eigen::VectorXd> RealDemCampaign::MapWindowWear() const {
  std::vector<Eigen::VectorXd> out;
  for (int w : map_windows) out.push_back(run_.wear_w[static_cast<size_t>(w)]);
  return out;
}

RealDemCampaign::RealDemCampaign(const DemRun& run, const RealDemSpec& spec) : run_(run), spec_(spec) {
  const size_t K = run.wear_w.size();
  std::vector<int> order(K);
  std::iota(order.begin(), order.end(), 0);
  std::mt19937_64 rng(spec.seed);
  std::shuffle(order.begin(), order.end(), rng);
  map_windows.assign(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(K / 2));
  truth_windows.assign(order.begin() + static_cast<std::ptrdiff_t>(K / 2), order.end());
  std::sort(map_windows.begin(), map_windows.end());
  std::sort(truth_windows.begin(), truth_windows.end());

  // The bundle's map: the sum of the map windows, their spread, their mean normal stress.
  map_.points = run.mesh.points;
  map_.faces = run.mesh.faces;
  const Eigen::Index n = static_cast<Eigen::Index>(map_.faces.size());
  const double a = static_cast<double>(map_windows.size());
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(n), sum2 = Eigen::VectorXd::Zero(n), nsum = Eigen::VectorXd::Zero(n);
  for (int w : map_windows) {
    sum += run.wear_w[static_cast<size_t>(w)];
    sum2 += run.wear_w[static_cast<size_t>(w)].cwiseAbs2();
    if (!run.normal_w.empty()) nsum += run.normal_w[static_cast<size_t>(w)];
  }
  map_.wear = sum;
  const Eigen::VectorXd mean = sum / a;
  map_.wear_stderr = (std::sqrt(a) * ((sum2 / a - mean.cwiseAbs2()).cwiseMax(0.0) * a / (a - 1)).cwiseSqrt()).eval();
  if (spec.with_normal && !run.normal_w.empty()) {
    map_.normal_stress = nsum / a;
    map_.shear_stress = 0.3 * map_.normal_stress;
  }
  map_.windows = static_cast<int>(map_windows.size());
  map_.title = "linerwatch dem " + run.name + " windows=" + std::to_string(map_windows.size()) + " (benchmark split)";
  map_.ComputeGeometry();

  // The truth: the other windows' mean, smoothed heavily (top-hat, not the map model's kernel).
  core::WearMap tm = run.mesh;
  Eigen::VectorXd tsum = Eigen::VectorXd::Zero(n), tn = Eigen::VectorXd::Zero(n);
  for (int w : truth_windows) {
    tsum += run.wear_w[static_cast<size_t>(w)];
    if (!run.normal_w.empty()) tn += run.normal_w[static_cast<size_t>(w)];
  }
  double zlo = std::numeric_limits<double>::max(), zhi = std::numeric_limits<double>::lowest();
  for (const auto& r : run.crusher.rows) {
    zlo = std::min(zlo, r.z_min_m);
    zhi = std::max(zhi, r.z_max_m);
  }
  const double height = std::max(zhi - zlo, 1e-3);
  const double radius = spec.truth_radius_frac * height;
  truth_radius_m_ = radius;
  const Eigen::VectorXd T = SmoothTruth(tm, tsum.cwiseMax(0.0), radius, spec.truth_local_linear);
  const Eigen::VectorXd N =
      run.normal_w.empty() ? Eigen::VectorXd::Ones(n) : SmoothTruth(tm, tn, radius, spec.truth_local_linear);
  std::vector<double> pos, nv;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (T[i] > 0) pos.push_back(T[i]);
    nv.push_back(N[i]);
  }
  const double med = std::max(Median(pos), 1e-300);
  const double nmax = std::max(Quantile(nv, 0.95), 1e-300);
  double i_mean = 0, n_mean = 0, asum = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    i_mean += tm.areas[i] * T[i] / med;
    n_mean += tm.areas[i] * N[i];
    asum += tm.areas[i];
  }
  const double n_to_i = n_mean > 0 ? i_mean / n_mean : 0;
  const double z_mid = 0.5 * (zlo + zhi);
  auto make_from = [&](double t, double nval, double z, double theta_deg) {
    Point p;
    p.intensity = t / med;
    p.normal_tilde = std::min(1.5, nval / nmax);
    p.normal_i = nval * n_to_i;
    p.zn = (z - z_mid) / height;
    p.theta = theta_deg * kPi / 180.0;
    return p;
  };
  for (Eigen::Index i = 0; i < n; ++i) faces_.push_back(make_from(T[i], N[i], tm.z[i], tm.theta_deg[i]));
  // A sensor reads the truth at its own point (the truth's smoothing evaluated there), not at the
  // nearest face's centroid: on a real map's steep height profile a face row's centroids sit a
  // third of a face height from a sensor between them, and the nearest one's value is several per
  // cent off the point's, the same sign for every sensor at that height, which biased each row's
  // scale. The nearest face is kept where the smoothing reaches no face.
  const core::SurfaceIndex truth_index(tm, std::max(radius, 1e-6));
  const Eigen::VectorXd tpos = tsum.cwiseMax(0.0);
  for (const auto& s : run.crusher.sensors) {
    Eigen::Index best = 0;
    double bd = std::numeric_limits<double>::max();
    for (Eigen::Index i = 0; i < n; ++i) {
      double dth = std::fmod(tm.theta_deg[i] - s.theta_deg + 540.0, 360.0) - 180.0;
      const double arc = tm.radius[i] * dth * kPi / 180.0, dz = tm.z[i] - s.z_m;
      if (dz * dz + arc * arc < bd) {
        bd = dz * dz + arc * arc;
        best = i;
      }
    }
    sensor_face_.push_back(best);
    double t = radius > 0 ? SmoothTruthAt(tm, truth_index, tpos, s.z_m, s.theta_deg, -1, spec.truth_local_linear) : T[best];
    double n_at = run.normal_w.empty() || !(radius > 0)
                      ? N[best]
                      : SmoothTruthAt(tm, truth_index, tn, s.z_m, s.theta_deg, -1, spec.truth_local_linear);
    if (!std::isfinite(t)) t = T[best];
    if (!std::isfinite(n_at)) n_at = N[best];
    sensors_.push_back(make_from(t, n_at, s.z_m, s.theta_deg));
  }
  // Rate: without effects, the truth's most worn face reaches 85 % of (new - minimum) at `days`
  // (the liner near its end: the thinnest point matters).
  double i_max = 0;
  for (const Point& p : faces_) i_max = std::max(i_max, p.intensity);
  rate_ = 0.85 * (run.crusher.thickness_new_mm - run.crusher.thickness_min_mm) / (std::max(i_max, 1e-6) * spec.days);
  double qs = 0;
  int qn = 0;
  for (double t = 0.125; t < spec.days; t += 0.25) {
    qs += Throughput(t);
    ++qn;
  }
  q_mean_ = qs / qn;
  double nt = 0, at = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    nt += tm.areas[i] * faces_[static_cast<size_t>(i)].normal_tilde;
    at += tm.areas[i];
  }
  normal_tilde_mean_ = nt > 0 ? nt / at : 1.0;
}

void RealDemCampaign::TruthConstruction(Eigen::VectorXd& faces, Eigen::VectorXd& sensors) const {
  faces = SmoothTruth(map_, map_.wear.cwiseMax(0.0), truth_radius_m_, spec_.truth_local_linear);
  // At each sensor's point, as the campaign's sensors read the truth.
  sensors.resize(static_cast<Eigen::Index>(sensor_face_.size()));
  const std::optional<core::SurfaceIndex> index =
      truth_radius_m_ > 0 ? std::optional<core::SurfaceIndex>(std::in_place, map_, truth_radius_m_) : std::nullopt;
  const Eigen::VectorXd pos = map_.wear.cwiseMax(0.0);
  for (size_t s = 0; s < sensor_face_.size(); ++s) {
    const auto& sn = run_.crusher.sensors[s];
    const double v = index ? SmoothTruthAt(map_, *index, pos, sn.z_m, sn.theta_deg, -1, spec_.truth_local_linear)
                           : std::numeric_limits<double>::quiet_NaN();
    sensors[static_cast<Eigen::Index>(s)] = std::isfinite(v) ? v : faces[sensor_face_[s]];
  }
}

double RealDemCampaign::Throughput(double t) const {
  if (t >= 30 && t < 36) return 0.05;
  return 1.0 + 0.35 * std::sin(2 * kPi * t / 23.0);
}

double RealDemCampaign::Wear(const Point& p, double day, double new_mm) const {
  const RealDemSpec& s = spec_;
  const double dth = std::remainder(p.theta - s.feed_theta_deg * kPi / 180.0, 2 * kPi);
  double base;
  if (!s.alt_forms) {
    base = rate_ * (p.intensity + s.squeeze_beta * p.normal_i);
    base *= 1.0 + s.feed_amplitude * std::cos(dth);
  } else {
    // Squeeze quadratic in normal stress (mean-matched to the linear form's size); segregation a
    // 120-degree sector (+A there, -A/2 elsewhere: mean 1), edges smoothed over 10 degrees.
    base = rate_ * (p.intensity + s.squeeze_beta * p.normal_i * p.normal_tilde / normal_tilde_mean_);
    const double in = 1.0 / (1.0 + std::exp((std::fabs(dth) - kPi / 3) / (10.0 * kPi / 180.0)));
    base *= 1.0 + s.feed_amplitude * (1.5 * in - 0.5);
  }
  const double dt = 0.25;
  double w = 0;
  for (double t = 0; t < day - 1e-12; t += dt) {
    const double step = std::min(dt, day - t), tm = t + 0.5 * step;
    double f = base;
    if (!s.alt_forms) {
      if (s.hardening_h > 0) f *= 1.0 - s.hardening_h * p.normal_tilde * (1.0 - std::exp(-tm / s.hardening_tau_days));
      if (s.profile_p != 0) f *= std::max(0.05, 1.0 + s.profile_p * p.zn * tm / 100.0);
      if (s.throughput_phi > 0) f *= 1.0 + s.throughput_phi * (Throughput(tm) / q_mean_ - 1.0);
      if (s.gradient_g > 0) {
        const double x = std::clamp((w - s.gradient_onset_mm) / (new_mm / 2 - s.gradient_onset_mm), 0.0, 1.0);
        f *= 1.0 + s.gradient_g * x;
      }
    } else {
      if (s.hardening_h > 0) f *= 1.0 - s.hardening_h * p.normal_tilde * tm / (tm + s.hardening_tau_days);
      if (s.profile_p != 0) f *= std::exp(s.profile_p * p.zn * tm / 100.0);
      if (s.throughput_phi > 0) f *= std::pow(std::max(Throughput(tm), 0.0) / q_mean_, s.throughput_phi);
      // A softer layer below the onset: a step (over 2 mm), at a depth the sensors reach.
      if (s.gradient_g > 0) f *= 1.0 + s.gradient_g / (1.0 + std::exp(-(w - s.gradient_onset_mm) / 1.0));
    }
    w += step * f;
  }
  return std::min(w, new_mm);
}

double RealDemCampaign::TrueSensorThickness(size_t index, double day) const {
  const auto& s = run_.crusher.sensors[index];
  const double new_mm = s.thickness_new_mm > 0 ? s.thickness_new_mm : run_.crusher.thickness_new_mm;
  double w = Wear(sensors_[index], day, new_mm);
  if (s.id == spec_.loss_sensor && day >= spec_.loss_day) w += spec_.loss_mm;
  w += Crater(s.z_m, s.theta_deg, map_.radius[sensor_face_[index]], day);
  return std::max(0.0, new_mm - w);
}

double RealDemCampaign::Crater(double z, double theta_deg, double radius_m, double day) const {
  if (spec_.crater_mm <= 0 || day < spec_.crater_day) return 0;
  const double arc = std::remainder(theta_deg - spec_.crater_theta_deg, 360.0) * kPi / 180.0 * radius_m;
  const double r = std::hypot(z - spec_.crater_z, arc);
  return spec_.crater_mm * std::clamp((spec_.crater_radius_m + 0.005 - r) / 0.01, 0.0, 1.0);
}

Eigen::VectorXd RealDemCampaign::TrueFaceWear(double day) const {
  Eigen::VectorXd w(static_cast<Eigen::Index>(faces_.size()));
  for (size_t i = 0; i < faces_.size(); ++i) {
    const auto fi = static_cast<Eigen::Index>(i);
    w[fi] = std::min(
        Wear(faces_[i], day, run_.crusher.thickness_new_mm) + Crater(map_.z[fi], map_.theta_deg[fi], map_.radius[fi], day),
        run_.crusher.thickness_new_mm);
  }
  return w;
}

void RealDemCampaign::WriteBundle(const std::filesystem::path& dir) const {
  std::filesystem::create_directories(dir);
  std::filesystem::copy_file(run_.dir / "crusher.json", dir / "crusher.json", std::filesystem::copy_options::overwrite_existing);
  std::vector<std::pair<std::string, const Eigen::VectorXd*>> arrays = {{"wear", &map_.wear}, {"wear_stderr", &map_.wear_stderr}};
  if (map_.has_normal_stress()) {
    arrays.push_back({"normal_stress_average", &map_.normal_stress});
    arrays.push_back({"shear_stress_average", &map_.shear_stress});
  }
  core::WriteWearMapVtk(dir / "wear_map.vtk", map_, arrays);
  const core::TimePoint t0 = run_.crusher.installed_at;
  std::mt19937_64 rng(spec_.seed * 7919 + 17);
  {
    std::ofstream r(dir / "readings.csv");
    r << "time,sensor_id,thickness_mm\n";
    const double step = spec_.report_hours / 24.0;
    for (size_t i = 0; i < run_.crusher.sensors.size(); ++i) {
      const auto& sn = run_.crusher.sensors[i];
      double stuck = -1;
      // Tabulated truth (0.25-day steps), interpolated.
      std::vector<double> tab;
      for (double t = 0; t <= spec_.days + 0.5; t += 0.25) tab.push_back(TrueSensorThickness(i, t));
      for (double t = step; t <= spec_.days + 1e-9; t += step) {
        const double x = t / 0.25;
        const auto j = static_cast<size_t>(x);
        const double f = x - static_cast<double>(j);
        double th = j + 1 < tab.size() ? tab[j] * (1 - f) + tab[j + 1] * f : tab.back();
        double value = std::max(0.0, std::floor(th));
        if (sn.id == spec_.stuck_sensor && t >= spec_.stuck_from_day) {
          if (stuck < 0) stuck = value;
          value = stuck;
        }
        r << Iso(t0, t) << "," << sn.id << "," << value << "\n";
      }
    }
  }
  if (spec_.with_operations) {
    std::ofstream o(dir / "operations.csv");
    o << "time,throughput_tph\n";
    for (double t = 0; t <= spec_.days; t += 1.0) o << Iso(t0, t) << "," << 3500.0 * Throughput(t + 0.5) << "\n";
  }
  if (spec_.with_scan) {
    std::filesystem::create_directories(dir / "scans");
    const Eigen::VectorXd w = TrueFaceWear(spec_.scan_day);
    std::ofstream sc(dir / "scans" / ("scan_" + Iso(t0, spec_.scan_day).substr(0, 10) + ".xyz"));
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    std::normal_distribution<double> gauss(0.0, 1.0);
    for (size_t f = 0; f < map_.faces.size(); ++f) {
      const auto& fc = map_.faces[f];
      for (int k = 0; k < 4; ++k) {
        double a = uni(rng), b = uni(rng);
        if (a + b > 1) {
          a = 1 - a;
          b = 1 - b;
        }
        const Eigen::Vector3d p0 = map_.points[fc[0]], p1 = map_.points[fc[1]], p2 = map_.points[fc[2]];
        const Eigen::Vector3d p = p0 + a * (p1 - p0) + b * (p2 - p0);
        const double depth = (w[static_cast<Eigen::Index>(f)] + spec_.scan_noise_mm * gauss(rng)) / 1000.0;
        const Eigen::Vector3d q = p - map_.normals[f] * depth;  // behind the as-new face
        char line[96];
        std::snprintf(line, sizeof line, "%.6f %.6f %.6f\n", q.x(), q.y(), q.z());
        sc << line;
      }
    }
  }
}

double TruthThinnest(const core::ReconstructionPlan& plan, const core::ThinnestAreas& areas,
                     const Eigen::VectorXd& truth_remaining) {
  const core::ThinnestArea& a = areas.liner;
  if (!a.whole_row) return core::ThinnestPatchOf(plan, truth_remaining, -1, a.patch_m, a.shape).thickness_mm;
  double thin = std::numeric_limits<double>::quiet_NaN();
  for (const auto& row : areas.rows) thin = std::fmin(thin, core::AreaMean(plan, truth_remaining, row));
  return thin;
}

double FiniteMedian(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

}  // namespace lw::bench
