#include "core/map_model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>

namespace lw::core {

namespace {

constexpr double kCutoff = 2.5;  // kernel support in bandwidths

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  return v[mid];
}

/// Local-linear (in z) kernel sums around a point: the estimate is the intercept of a weighted
/// line in z, which removes the one-sided bias of a plain kernel mean at the feed and discharge
/// edges (the thinnest point is often at the discharge edge).
struct Sums {
  double s0 = 0, s1 = 0, s2 = 0, t0 = 0, t1 = 0, n0 = 0;
  void Add(double w, double dz, double y, double nrm) {
    s0 += w;
    s1 += w * dz;
    s2 += w * dz * dz;
    t0 += w * y;
    t1 += w * dz * y;
    n0 += w * nrm;
  }
  bool linear = true;  ///< local-linear in z; false: local-constant (plain kernel mean)
  bool Linear() const { return linear && s0 > 0 && s0 * s2 - s1 * s1 > 1e-6 * s0 * s2 && s2 > 0; }
  double Value() const {
    if (!(s0 > 0)) return std::numeric_limits<double>::quiet_NaN();
    if (!Linear()) return t0 / s0;
    return (s2 * t0 - s1 * t1) / (s0 * s2 - s1 * s1);
  }
  /// Weight of an observation at offset dz (weight w) in Value().
  double Weight(double w, double dz) const {
    if (!Linear()) return w / s0;
    return w * (s2 - s1 * dz) / (s0 * s2 - s1 * s1);
  }
};

/// Gaussian kernel on the unwrapped surface, sd h along z and ha around the circumference (a
/// gyratory chamber varies much faster along z than around), cut at kCutoff sd.
struct Kernel {
  const WearMap& map;
  const Eigen::VectorXd& y;
  const Eigen::VectorXd* normal;
  double h;
  double ha;
  bool linear = true;
  std::shared_ptr<const SurfaceIndex> owned;
  const SurfaceIndex& index;
  Kernel(const WearMap& m, const Eigen::VectorXd& values, const Eigen::VectorXd* n, double bandwidth, double bandwidth_arc = 0,
         std::shared_ptr<const SurfaceIndex> idx = nullptr)
      : map(m),
        y(values),
        normal(n),
        h(bandwidth),
        ha(bandwidth_arc > 0 ? bandwidth_arc : bandwidth),
        owned(idx ? std::move(idx) : std::make_shared<const SurfaceIndex>(m, kCutoff * bandwidth, kCutoff * ha)),
        index(*owned) {}

  /// Weight of face j at offset (dz, arc); 0 beyond the cut.
  double W(uint32_t j, double dz, double arc) const {
    const double q = dz * dz / (h * h) + arc * arc / (ha * ha);
    if (q > kCutoff * kCutoff) return 0.0;
    return map.areas[static_cast<Eigen::Index>(j)] * std::exp(-0.5 * q);
  }

  /// Sums at (z, theta) over faces except `skip` (-1: none).
  Sums At(double z, double theta, double radius, long skip) const {
    Sums s;
    s.linear = linear;
    index.Visit(z, theta, radius, [&](uint32_t j, double dz, double arc) {
      if (static_cast<long>(j) == skip) return;
      const double w = W(j, dz, arc);
      if (w <= 0) return;
      const auto jj = static_cast<Eigen::Index>(j);
      s.Add(w, dz, y[jj], normal ? (*normal)[jj] : 0.0);
    });
    return s;
  }
  /// Variance of Value() given per-face variances.
  double Variance(const Sums& s, double z, double theta, double radius, long skip, const Eigen::VectorXd& var) const {
    double v = 0;
    // Sums::Weight(), its divisions done once.
    const bool lin = s.Linear();
    const double inv = lin ? 1.0 / (s.s0 * s.s2 - s.s1 * s.s1) : 1.0 / s.s0;
    index.Visit(z, theta, radius, [&](uint32_t j, double dz, double arc) {
      if (static_cast<long>(j) == skip) return;
      const double w = W(j, dz, arc);
      if (w <= 0) return;
      const double l = lin ? w * (s.s2 - s.s1 * dz) * inv : w * inv;
      v += l * l * var[static_cast<Eigen::Index>(j)];
    });
    return v;
  }
  /// Variance() for both forms at once (one visit): first the local-constant, then the local-linear.
  std::pair<double, double> Variances(const Sums& s, double z, double theta, double radius, long skip, const Eigen::VectorXd& var) const {
    Sums sl = s;
    sl.linear = true;
    // Sums::Weight() of either form, its divisions done once.
    const bool lin = sl.Linear();
    const double inv_s0 = 1.0 / s.s0, inv_det = lin ? 1.0 / (s.s0 * s.s2 - s.s1 * s.s1) : 0.0;
    double vc = 0, vl = 0;
    index.Visit(z, theta, radius, [&](uint32_t j, double dz, double arc) {
      if (static_cast<long>(j) == skip) return;
      const double w = W(j, dz, arc);
      if (w <= 0) return;
      const double v = var[static_cast<Eigen::Index>(j)], lc = w * inv_s0, ll = lin ? w * (s.s2 - s.s1 * dz) * inv_det : lc;
      vc += lc * lc * v;
      vl += ll * ll * v;
    });
    return {vc, vl};
  }
  double EffectiveFaces(double z, double theta) const {
    double s0 = 0, s2 = 0;
    index.Visit(z, theta, -1, [&](uint32_t j, double dz, double arc) {
      const double w = W(j, dz, arc);
      s0 += w;
      s2 += w * w;
    });
    return s2 > 0 ? s0 * s0 / s2 : 0;
  }
};

}  // namespace

double MapModel::FaceVariance(double m) const { return noise_phi * std::pow(std::max(m, 0.0), noise_power); }

double MapModel::RelSd(Eigen::Index i) const {
  const double v = intensity[i];
  return v > 0 ? intensity_sd[i] / v : 1.0;
}

MapModel::Point MapModel::At(double z, double theta_deg) const {
  Point p;
  if (!map || map->face_count() == 0) return p;
  const WearMap& m = *map;
  if (bandwidth_m > 0) {
    const Eigen::VectorXd* nrm = normal_stress.size() ? &m.normal_stress : nullptr;
    Kernel k(m, clean, nrm, bandwidth_m, bandwidth_arc_m, index);
    k.linear = local_linear;
    const Sums s = k.At(z, theta_deg, -1, -1);
    if (s.s0 > 0) {
      p.intensity = std::max(0.0, s.Value());
      p.sd = std::sqrt(k.Variance(s, z, theta_deg, -1, -1, face_var) + std::pow(smoothing_error_rel * p.intensity, 2));
      if (nrm && normal_index) {
        Kernel kn(m, *nrm, nullptr, normal_bandwidth_m, 3.0 * bandwidth_arc_m, normal_index);
        kn.linear = false;
        const Sums sn = kn.At(z, theta_deg, -1, -1);
        p.normal_stress = sn.s0 > 0 ? sn.t0 / sn.s0 : 0.0;
      }
      p.faces = k.EffectiveFaces(z, theta_deg);
      return p;
    }
  }
  // No smoothing, or the point is off the mesh: the nearest face.
  Eigen::Index best = 0;
  double best_d = std::numeric_limits<double>::max();
  for (Eigen::Index i = 0; i < m.z.size(); ++i) {
    double dth = std::fmod(m.theta_deg[i] - theta_deg, 360.0);
    if (dth > 180.0) dth -= 360.0;
    if (dth < -180.0) dth += 360.0;
    const double arc = m.radius[i] * dth * M_PI / 180.0;
    const double d = (m.z[i] - z) * (m.z[i] - z) + arc * arc;
    if (d < best_d) {
      best_d = d;
      best = i;
    }
  }
  p.intensity = intensity[best];
  p.sd = intensity_sd[best];
  p.normal_stress = normal_stress.size() ? normal_stress[best] : 0.0;
  p.faces = 1;
  return p;
}

MapModel BuildMapModel(const WearMap& map, const MapModelOptions& options) {
  MapModel model;
  model.map = &map;
  const Eigen::Index n = static_cast<Eigen::Index>(map.face_count());
  model.clean = map.wear.size() == n ? Eigen::VectorXd(map.wear.cwiseMax(0.0)) : Eigen::VectorXd::Zero(n);
  model.intensity = model.clean;
  model.intensity_sd = Eigen::VectorXd::Zero(n);
  if (map.has_normal_stress() && map.normal_stress.size() == n) model.normal_stress = map.normal_stress;
  if (n == 0) return model;
  const Eigen::VectorXd* nrm = model.normal_stress.size() ? &map.normal_stress : nullptr;

  std::vector<double> sizes(static_cast<size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) sizes[static_cast<size_t>(i)] = std::sqrt(2.0 * std::max(map.areas[i], 0.0));
  model.face_size_m = std::max(Median(sizes), 1e-4);
  const double extent = std::max(map.z.maxCoeff() - map.z.minCoeff(), 10 * model.face_size_m);

  // 1. Pilot: each face predicted from its nearest neighbours (leave-one-out, 1.5 face sizes).
  Eigen::VectorXd pilot(n), pilot_neff(n);
  {
    const Kernel k(map, model.clean, nullptr, 1.5 * model.face_size_m);
    for (Eigen::Index i = 0; i < n; ++i) {
      double s0 = 0, sy = 0, s2 = 0;
      k.index.Visit(map.z[i], map.theta_deg[i], map.radius[i], [&](uint32_t j, double dz, double arc) {
        if (static_cast<Eigen::Index>(j) == i) return;
        const double w = k.W(j, dz, arc);
        if (w <= 0) return;
        s0 += w;
        sy += w * model.clean[static_cast<Eigen::Index>(j)];
        s2 += w * w;
      });
      pilot[i] = s0 > 0 ? sy / s0 : model.clean[i];
      pilot_neff[i] = s2 > 0 ? s0 * s0 / s2 : 0;
    }
  }

  // 2. Noise law var = phi m: a face's wear sums the energies of the contacts it received, so its
  //    variance grows like its mean (compound Poisson). phi from wear_stderr (the spread of the
  //    run's windows) when the map has it, else from each face against its neighbours; the top 2 %
  //    of ratios trimmed either way (spikes).
  {
    const bool use_stderr = map.has_wear_stderr() && map.wear_stderr.size() == n && map.wear_stderr.maxCoeff() > 0;
    std::vector<double> ratio;
    for (Eigen::Index i = 0; i < n; ++i) {
      if (pilot[i] <= 0) continue;
      if (use_stderr) {
        ratio.push_back(map.wear_stderr[i] * map.wear_stderr[i] / pilot[i]);
      } else if (pilot_neff[i] > 0) {
        const double d = model.clean[i] - pilot[i];
        ratio.push_back(d * d / (pilot[i] * (1.0 + 1.0 / pilot_neff[i])));
      }
    }
    std::sort(ratio.begin(), ratio.end());
    const size_t keep = ratio.size() - ratio.size() / 50;
    double sum = 0;
    for (size_t k = 0; k < keep; ++k) sum += ratio[k];
    model.noise_power = 1.0;
    model.noise_phi = keep ? sum / static_cast<double>(keep) : 0.0;
    model.noise_source = use_stderr ? "wear_stderr (" + (map.windows > 0 ? std::to_string(map.windows) + " windows" : std::string("windows not stated")) + ")"
                                    : "neighbour differences";
  }

  // 3. Outliers: a face far above its neighbourhood is capped (one-sided: DEM spikes are faces a
  //    few particles hit hard, at the feed and discharge edges mostly).
  if (options.robust) {
    for (Eigen::Index i = 0; i < n; ++i) {
      if (pilot[i] <= 0) continue;
      const double cap = pilot[i] + options.outlier_z * std::sqrt(model.FaceVariance(pilot[i]));
      if (model.clean[i] > cap) {
        model.clean[i] = cap;
        ++model.outlier_faces;
      }
    }
  }

  // 4. Bandwidth: along z, and around the circumference 1, 3 or 8 times that (a gyratory chamber's
  //    wear changes much faster along z than around; the data decide how much).
  std::vector<std::pair<double, double>> candidates;  // (along z, around)
  if (options.bandwidth_m > 0) {
    candidates.push_back({options.bandwidth_m, options.bandwidth_m});
    model.bandwidth_method = "fixed";
  } else if (options.bandwidth_m < 0) {
    const double mean_area = map.areas.sum() / static_cast<double>(n);
    const double half_circumference = M_PI * std::max(1e-3, map.radius.mean());
    for (double h = model.face_size_m; h <= 0.2 * extent + 1e-12; h *= 1.4) {
      for (double ratio : {1.0, 3.0, 8.0}) {
        const double ha = std::min(ratio * h, half_circumference);
        if (ratio > 1.0 && ha <= h * 1.01) continue;
        // Work bound: faces visited per face (the kernel's bounding disc) x faces: about 2e9 terms
        // at most for the final smoothing (a million-face map keeps to a few face sizes).
        const double visits = M_PI * std::pow(kCutoff * std::max(h, ha), 2) / std::max(mean_area, 1e-12);
        if (visits * static_cast<double>(n) > 2e9 && !candidates.empty()) continue;
        candidates.push_back({h, ha});
      }
    }
    model.bandwidth_method = "cross-validation";
  }
  if (candidates.empty()) {
    model.bandwidth_m = 0;
    model.bandwidth_method = "none";
    for (Eigen::Index i = 0; i < n; ++i) model.intensity_sd[i] = std::sqrt(model.FaceVariance(pilot[i]));
    std::vector<double> cv;
    for (Eigen::Index i = 0; i < n; ++i)
      if (pilot[i] > 0) cv.push_back(std::sqrt(model.FaceVariance(pilot[i])) / pilot[i]);
    model.face_cv = Median(cv);
    return model;
  }
  const Eigen::Index step = std::max<Eigen::Index>(1, n / static_cast<Eigen::Index>(std::max<size_t>(options.max_cv_faces, 1)));
  std::vector<Eigen::Index> eval;
  for (Eigen::Index i = 0; i < n; i += step) eval.push_back(i);
  Eigen::VectorXd pilot_var(n);
  for (Eigen::Index i = 0; i < n; ++i) pilot_var[i] = model.FaceVariance(pilot[i]);
  const size_t nh = candidates.size();
  // Every bandwidth with both forms: local-constant, and local-linear in z (less biased where the
  // intensity changes steeply at the edges, noisier there). Index c = 2 * bandwidth + form.
  const size_t nc = 2 * nh;
  std::vector<std::vector<double>> loo(nc, std::vector<double>(eval.size(), std::numeric_limits<double>::quiet_NaN()));
  std::vector<std::vector<double>> loo_var(nc, std::vector<double>(eval.size(), 0.0));
  for (size_t c = 0; c < nh; ++c) {
    // Both forms from one pass over the neighbours (their sums are the same; only the weights differ).
    const Kernel k(map, model.clean, nullptr, candidates[c].first, candidates[c].second);
    for (size_t e = 0; e < eval.size(); ++e) {
      const Eigen::Index i = eval[e];
      Sums s = k.At(map.z[i], map.theta_deg[i], map.radius[i], static_cast<long>(i));
      if (!(s.s0 > 0)) continue;
      const auto [var_constant, var_linear] = k.Variances(s, map.z[i], map.theta_deg[i], map.radius[i], static_cast<long>(i), pilot_var);
      for (int form = 0; form < 2; ++form) {
        const size_t cc = 2 * c + static_cast<size_t>(form);
        s.linear = form == 1;
        loo[cc][e] = std::max(0.0, s.Value());
        loo_var[cc][e] = form == 1 ? var_linear : var_constant;
      }
    }
  }
  std::vector<double> score(nc, 0.0);
  double area_sum = 0, noise_sum = 0, m2_sum = 0;
  for (size_t e = 0; e < eval.size(); ++e) {
    bool all = true;
    for (size_t c = 0; c < nc; ++c) all = all && std::isfinite(loo[c][e]);
    if (!all) continue;
    const double a = map.areas[eval[e]];
    area_sum += a;
    noise_sum += a * pilot_var[eval[e]];
    // Squared error, clipped at 3 noise standard deviations (Huber-like): a few spike faces must
    // not choose the scale for the whole liner.
    const double clip2 = 9.0 * std::max(pilot_var[eval[e]], 1e-300);
    for (size_t c = 0; c < nc; ++c) score[c] += a * std::min(clip2, std::pow(model.clean[eval[e]] - loo[c][e], 2));
  }
  size_t best = 0;
  for (size_t c = 1; c < nc; ++c)
    if (score[c] < score[best]) best = c;
  model.bandwidth_m = candidates[best / 2].first;
  model.bandwidth_arc_m = candidates[best / 2].second;
  model.local_linear = best % 2 == 1;
  for (size_t c = 0; c < nh; ++c)
    model.cv_curve.push_back({candidates[c].first, score[best] > 0 ? std::min(score[2 * c], score[2 * c + 1]) / score[best] : 1.0});
  // The smoothing's own error: what the cross-validated error holds beyond the faces' noise and the
  // noise of the prediction, relative to the field's mean square.
  if (area_sum > 0) {
    double var_pred = 0;
    for (size_t e = 0; e < eval.size(); ++e) {
      if (!std::isfinite(loo[best][e])) continue;
      bool all = true;
      for (size_t c = 0; c < nc; ++c) all = all && std::isfinite(loo[c][e]);
      if (!all) continue;
      var_pred += map.areas[eval[e]] * loo_var[best][e];
      m2_sum += map.areas[eval[e]] * loo[best][e] * loo[best][e];
    }
    const double bias2 = std::max(0.0, (score[best] - noise_sum - var_pred) / area_sum);
    model.smoothing_error_rel = m2_sum > 0 ? std::sqrt(bias2 / (m2_sum / area_sum)) : 0.0;
  }

  // 5. The field at the chosen bandwidth, and its standard error.
  {
    Kernel k(map, model.clean, nrm, model.bandwidth_m, model.bandwidth_arc_m);
    k.linear = model.local_linear;
    std::vector<Sums> sums(static_cast<size_t>(n));
    for (Eigen::Index i = 0; i < n; ++i) {
      sums[static_cast<size_t>(i)] = k.At(map.z[i], map.theta_deg[i], map.radius[i], -1);
      const Sums& s = sums[static_cast<size_t>(i)];
      model.intensity[i] = s.s0 > 0 ? std::max(0.0, s.Value()) : model.clean[i];
    }
    // Normal stress at three times the wear's scale: its sampling noise is shared with the wear's
    // (the same contacts), and at the wear's own scale it would carry the wear map's error into
    // every stress-based hypothesis (a map over-predicting where it happened to sample more
    // contacts would look like work hardening). The stress field's real pattern is broad.
    if (nrm) {
      model.normal_bandwidth_m = 3.0 * model.bandwidth_m;
      Kernel kn(map, *nrm, nullptr, model.normal_bandwidth_m, 3.0 * model.bandwidth_arc_m);
      kn.linear = false;
      model.normal_index = kn.owned;
      for (Eigen::Index i = 0; i < n; ++i) {
        const Sums sn = kn.At(map.z[i], map.theta_deg[i], map.radius[i], -1);
        model.normal_stress[i] = sn.s0 > 0 ? sn.t0 / sn.s0 : (*nrm)[i];
      }
    }
    Eigen::VectorXd& var = model.face_var;
    var.resize(n);
    for (Eigen::Index i = 0; i < n; ++i) var[i] = model.FaceVariance(model.intensity[i]);
    model.index = k.owned;
    for (Eigen::Index i = 0; i < n; ++i) {
      const double v = k.Variance(sums[static_cast<size_t>(i)], map.z[i], map.theta_deg[i], map.radius[i], -1, var);
      model.intensity_sd[i] = std::sqrt(v + std::pow(model.smoothing_error_rel * model.intensity[i], 2));
    }
  }
  std::vector<double> cv;
  for (Eigen::Index i = 0; i < n; ++i)
    if (model.intensity[i] > 0) cv.push_back(std::sqrt(model.FaceVariance(model.intensity[i])) / model.intensity[i]);
  model.face_cv = Median(cv);
  return model;
}

}  // namespace lw::core
