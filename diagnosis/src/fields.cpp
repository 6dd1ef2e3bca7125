#include "fields.hpp"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <unordered_map>

#include "core/median.hpp"

namespace lw::diagnosis::detail {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double WeightedQuantile(std::vector<std::pair<double, double>> value_weight, double q) {
  if (value_weight.empty()) return 0;
  std::sort(value_weight.begin(), value_weight.end());
  double total = 0;
  for (const auto& vw : value_weight) total += vw.second;
  double acc = 0;
  for (const auto& vw : value_weight) {
    acc += vw.second;
    if (acc >= q * total) return vw.first;
  }
  return value_weight.back().first;
}

// Hash of face centroids on the unwrapped surface (z, arc length at the mean radius), with the
// angular direction wrapping around.
class UnwrappedIndex {
 public:
  UnwrappedIndex(const core::WearMap& map, double bucket_m, double mean_radius_m)
      : map_(map), bucket_(bucket_m), radius_(mean_radius_m) {
    circumference_buckets_ = std::max<long>(1, static_cast<long>(std::ceil(2 * kPi * radius_ / bucket_)));
    for (size_t f = 0; f < map.face_count(); ++f) {
      buckets_[Key(BucketZ(map.z[static_cast<Eigen::Index>(f)]), BucketT(map.theta_deg[static_cast<Eigen::Index>(f)]))].push_back(
          f);
    }
  }
  long BucketZ(double z) const { return static_cast<long>(std::floor(z / bucket_)); }
  long BucketT(double theta_deg) const {
    const long b = static_cast<long>(std::floor(theta_deg * kPi / 180.0 * radius_ / bucket_));
    return ((b % circumference_buckets_) + circumference_buckets_) % circumference_buckets_;
  }
  static long long Key(long bz, long bt) { return (static_cast<long long>(bz) << 32) ^ static_cast<long long>(bt); }

  /// Calls fn(face, distance_m) for faces in the (2 * reach + 1)^2 buckets around (z, theta).
  template <typename Fn>
  void Visit(double z, double theta_deg, long reach, Fn&& fn) const {
    const long bz = BucketZ(z);
    const long bt = BucketT(theta_deg);
    const long span_t = std::min<long>(2 * reach + 1, circumference_buckets_);
    for (long dz = -reach; dz <= reach; ++dz) {
      for (long k = 0; k < span_t; ++k) {
        const long t = (((bt - reach + k) % circumference_buckets_) + circumference_buckets_) % circumference_buckets_;
        auto it = buckets_.find(Key(bz + dz, t));
        if (it == buckets_.end()) continue;
        for (size_t f : it->second) {
          const auto fi = static_cast<Eigen::Index>(f);
          const double ddz = map_.z[fi] - z;
          const double arc = AngleDiffDeg(map_.theta_deg[fi], theta_deg) * kPi / 180.0 * map_.radius[fi];
          fn(f, std::sqrt(ddz * ddz + arc * arc));
        }
      }
    }
  }

 private:
  const core::WearMap& map_;
  double bucket_;
  double radius_;
  long circumference_buckets_ = 1;
  std::unordered_map<long long, std::vector<size_t>> buckets_;
};

}  // namespace

int CellGrid::CellOf(double z, double theta_deg) const {
  const double fz = (z - z0) / dz;
  double rel = std::fmod(theta_deg - t0_deg + 720.0, 360.0);
  const double span = dt_deg * static_cast<double>(nt);
  if (rel > span) {
    // Just outside the covered range: snap to the nearest edge bin when close.
    if (rel - span < 0.5 * dt_deg)
      rel = span - 1e-9;
    else if (360.0 - rel < 0.5 * dt_deg)
      rel = 0;
    else
      return -1;
  }
  long iz = static_cast<long>(std::floor(fz));
  long it = static_cast<long>(std::floor(rel / dt_deg));
  if (iz < 0 && fz > -0.5) iz = 0;
  if (iz >= static_cast<long>(nz) && fz < static_cast<double>(nz) + 0.5) iz = static_cast<long>(nz) - 1;
  it = std::clamp<long>(it, 0, static_cast<long>(nt) - 1);
  if (iz < 0 || iz >= static_cast<long>(nz)) return -1;
  return static_cast<int>(iz * static_cast<long>(nt) + it);
}

namespace {

// RMS of the cosine and sine parts of the raw map's first circumferential harmonic, relative to the
// area-weighted mean of each band of z (ten bands over the rows): one two-component sample of the
// map's own asymmetry. A run of an axisymmetric chamber should have none, so what it shows is error.
double OwnHarmonic1(const core::WearMap& map, const MapFields& f) {
  constexpr int kBands = 10;
  const double height = f.z_top - f.z_bottom;
  if (!(height > 0)) return 0.0;
  const auto nf = static_cast<Eigen::Index>(map.face_count());
  std::vector<double> sum_aw(kBands, 0.0), sum_a(kBands, 0.0);
  auto band_of = [&](Eigen::Index i) {
    return std::clamp(static_cast<int>((map.z[i] - f.z_bottom) / height * kBands), 0, kBands - 1);
  };
  for (Eigen::Index i = 0; i < nf; ++i) {
    if (!(map.wear[i] >= 0) || !(map.areas[i] > 0)) continue;
    sum_aw[static_cast<size_t>(band_of(i))] += map.areas[i] * map.wear[i];
    sum_a[static_cast<size_t>(band_of(i))] += map.areas[i];
  }
  double a = 0, b = 0, weight = 0;
  for (Eigen::Index i = 0; i < nf; ++i) {
    if (!(map.wear[i] >= 0) || !(map.areas[i] > 0)) continue;
    const auto k = static_cast<size_t>(band_of(i));
    const double mean = sum_a[k] > 0 ? sum_aw[k] / sum_a[k] : 0.0;
    if (!(mean > 0)) continue;
    const double dev = map.wear[i] / mean - 1.0, th = map.theta_deg[i] * kPi / 180.0;
    a += map.areas[i] * dev * std::cos(th);
    b += map.areas[i] * dev * std::sin(th);
    weight += map.areas[i];
  }
  if (!(weight > 0)) return 0.0;
  a *= 2.0 / weight;
  b *= 2.0 / weight;
  return std::sqrt(0.5 * (a * a + b * b));
}

}  // namespace

MapFields ComputeMapFields(const core::Bundle& bundle) {
  const core::WearMap& map = bundle.map;
  const auto nf = static_cast<Eigen::Index>(map.face_count());
  MapFields f;
  f.model = core::BuildMapModel(map);
  const Eigen::VectorXd& raw = f.model.intensity;
  std::vector<double> positive;
  for (Eigen::Index i = 0; i < nf; ++i)
    if (raw[i] > 0) positive.push_back(raw[i]);
  f.intensity_median = positive.empty() ? 1.0 : core::UpperMedian(positive);
  if (f.intensity_median <= 0) f.intensity_median = 1.0;
  f.intensity = raw / f.intensity_median;
  f.rel_sd.resize(nf);
  for (Eigen::Index i = 0; i < nf; ++i) f.rel_sd[i] = std::min(1.0, f.model.RelSd(i));
  f.rel_noise_sd.resize(nf);
  for (Eigen::Index i = 0; i < nf; ++i) {
    const double v = f.model.intensity[i];
    f.rel_noise_sd[i] =
        v > 0 && f.model.intensity_noise_sd.size() == nf ? std::min(1.0, f.model.intensity_noise_sd[i] / v) : f.rel_sd[i];
  }
  if (bundle.map_validation.looks_truncated) f.quantum_raw = 1e-6;  // "%f": six decimals

  std::vector<double> sizes;
  double area_sum = 0, radius_sum = 0;
  for (Eigen::Index i = 0; i < nf; ++i) {
    sizes.push_back(std::sqrt(2.0 * std::max(map.areas[i], 0.0)));
    area_sum += map.areas[i];
    radius_sum += map.areas[i] * map.radius[i];
  }
  f.face_size_m = std::max(core::UpperMedian(sizes), 1e-4);
  f.mean_radius_m = area_sum > 0 ? radius_sum / area_sum : 1.0;

  // Angular coverage: the complement of the largest empty arc (1 degree bins).
  {
    std::vector<bool> occupied(360, false);
    for (Eigen::Index i = 0; i < nf; ++i) occupied[static_cast<size_t>(std::clamp(map.theta_deg[i], 0.0, 359.999))] = true;
    int best_len = 0, best_end = 0;
    for (int start = 0; start < 360; ++start) {
      if (occupied[static_cast<size_t>(start)] || occupied[static_cast<size_t>((start + 359) % 360)] == false) continue;
      int len = 0;
      while (len < 360 && !occupied[static_cast<size_t>((start + len) % 360)]) ++len;
      if (len > best_len) {
        best_len = len;
        best_end = (start + len) % 360;
      }
    }
    if (best_len >= 5 && best_len < 360) {
      f.theta_lo_deg = best_end;
      f.theta_span_deg = 360.0 - best_len;
    } else {
      f.theta_lo_deg = 0;
      f.theta_span_deg = 360;
    }
  }

  f.z_bottom = std::numeric_limits<double>::max();
  f.z_top = std::numeric_limits<double>::lowest();
  for (const auto& r : bundle.crusher.rows) {
    f.z_bottom = std::min(f.z_bottom, r.z_min_m);
    f.z_top = std::max(f.z_top, r.z_max_m);
  }
  if (bundle.crusher.rows.empty() || f.z_top <= f.z_bottom) {
    f.z_bottom = nf > 0 ? map.z.minCoeff() : 0.0;
    f.z_top = nf > 0 ? map.z.maxCoeff() : 1.0;
    if (f.z_top <= f.z_bottom) f.z_top = f.z_bottom + 1.0;
  }

  f.has_normal = map.has_normal_stress() && map.normal_stress.size() == nf && map.normal_stress.maxCoeff() > 0 &&
                 f.model.normal_stress.size() == nf;
  if (f.has_normal) {
    // Normal stress smoothed with the same kernel as the wear (its sampling noise is shared with
    // the wear's: both come from the same contacts).
    Eigen::VectorXd n = f.model.normal_stress.cwiseMax(0.0);
    std::vector<std::pair<double, double>> vw;
    double n_mean = 0, i_mean = 0;
    for (Eigen::Index i = 0; i < nf; ++i) {
      vw.push_back({n[i], map.areas[i]});
      n_mean += n[i] * map.areas[i];
      i_mean += f.intensity[i] * map.areas[i];
    }
    double robust_max = WeightedQuantile(vw, 0.95);
    if (robust_max <= 0) robust_max = n.maxCoeff();
    f.normal_robust_max = robust_max;
    f.normal_to_intensity = n_mean > 0 ? i_mean / n_mean : 0.0;
    f.normal_tilde = (n / robust_max).cwiseMin(1.5);
    f.normal_i = n * f.normal_to_intensity;
    // The map smoothed like the stress, scaled to the same area-weighted mean as the intensity.
    const Eigen::VectorXd& broad = f.model.intensity_broad;
    double b_mean = 0;
    for (Eigen::Index i = 0; i < nf && broad.size() == nf; ++i) b_mean += broad[i] * map.areas[i];
    f.broad_to_intensity = b_mean > 0 ? i_mean / b_mean : 0.0;
    f.broad_i = broad.size() == nf ? Eigen::VectorXd(broad * f.broad_to_intensity) : Eigen::VectorXd::Zero(nf);
  } else {
    f.normal_tilde = Eigen::VectorXd::Ones(nf);
    f.normal_i = Eigen::VectorXd::Zero(nf);
    f.broad_i = Eigen::VectorXd::Zero(nf);
  }

  // The circumferential-mean intensity profile along z and its logarithmic slope (profile shift).
  if (nf > 0) {
    const double zlo = map.z.minCoeff(), zhi = map.z.maxCoeff();
    const double height = std::max(f.z_top - f.z_bottom, 1e-3);
    const size_t nb = std::clamp<size_t>(static_cast<size_t>(nf) / 150, 4, 24);
    const double bw = std::max((zhi - zlo) / static_cast<double>(nb), 1e-6);
    std::vector<double> sa(nb, 0.0), si(nb, 0.0);
    for (Eigen::Index i = 0; i < nf; ++i) {
      const auto b = std::min(nb - 1, static_cast<size_t>(std::max(0.0, (map.z[i] - zlo) / bw)));
      sa[b] += map.areas[i];
      si[b] += map.areas[i] * f.intensity[i];
    }
    std::vector<double> zc, li;
    for (size_t b = 0; b < nb; ++b) {
      if (sa[b] <= 0) continue;
      zc.push_back(zlo + (static_cast<double>(b) + 0.5) * bw);
      li.push_back(std::log(std::max(si[b] / sa[b], 1e-3)));
    }
    if (zc.size() >= 3) {
      // Smooth the log profile (3-point), then a centred slope over +-1 sample, per concave height.
      std::vector<double> sm(li.size());
      for (size_t k = 0; k < li.size(); ++k) {
        const size_t a = k ? k - 1 : k, b = k + 1 < li.size() ? k + 1 : k;
        sm[k] = (li[a] + li[k] + li[b]) / 3.0;
      }
      std::vector<double> d(zc.size());
      for (size_t k = 0; k < zc.size(); ++k) {
        const size_t a = k ? k - 1 : k, b = k + 1 < zc.size() ? k + 1 : k;
        d[k] = std::clamp(-(sm[b] - sm[a]) / (zc[b] - zc[a]) * height, -10.0, 10.0);
      }
      f.profile_z = zc;
      f.profile_shift_rel = d;
      double num = 0, den = 0;
      for (Eigen::Index i = 0; i < nf; ++i) {
        num += map.areas[i] * f.intensity[i] * ProfileShiftRel(f, map.z[i]);
        den += map.areas[i] * f.intensity[i];
      }
      const double mean = den > 0 ? num / den : 0.0;
      for (double& v : f.profile_shift_rel) v -= mean;
    }
  }

  // The map's own noise: the model's noise law (from wear_stderr or neighbour differences).
  f.noise_estimated = nf > 8 && f.model.noise_phi > 0;
  f.face_rel_noise = f.noise_estimated ? f.model.face_cv : kUnestimatedFaceNoise;
  if (!f.noise_estimated) {
    f.rel_sd.setConstant(kUnestimatedFaceNoise);
    f.rel_noise_sd.setConstant(kUnestimatedFaceNoise);
  }
  f.harmonic1_rel_sd =
      f.theta_span_deg >= 359.0 ? std::max(kHarmonic1PerFaceNoise * f.face_rel_noise, OwnHarmonic1(map, f)) : 0.0;
  f.band_rel_sd = kBandMeanPerFaceNoise * f.face_rel_noise;
  return f;
}

double QuantisationRel(const MapFields& fields, double intensity) {
  if (fields.quantum_raw <= 0 || intensity <= 0) return 0.0;
  return std::min(1.0, fields.quantum_raw / std::sqrt(12.0) / (intensity * fields.intensity_median));
}

double ProfileShiftRel(const MapFields& fields, double z) {
  const auto& zs = fields.profile_z;
  const auto& v = fields.profile_shift_rel;
  if (zs.empty()) return 0.0;
  if (z <= zs.front()) return v.front();
  if (z >= zs.back()) return v.back();
  const size_t k = static_cast<size_t>(std::upper_bound(zs.begin(), zs.end(), z) - zs.begin());
  const double t = (z - zs[k - 1]) / (zs[k] - zs[k - 1]);
  return v[k - 1] + t * (v[k] - v[k - 1]);
}

PointField FieldAt(const core::WearMap& map, const MapFields& fields, double z, double theta_deg) {
  PointField p;
  p.z = z;
  p.theta_deg = theta_deg;
  if (map.face_count() == 0) return p;
  const core::MapModel::Point at = fields.model.At(z, theta_deg);
  p.intensity = at.intensity / fields.intensity_median;
  const double rel =
      fields.noise_estimated ? (at.intensity > 0 ? std::min(1.0, at.sd / at.intensity) : 1.0) : kUnestimatedFaceNoise;
  p.rel_noise = std::hypot(rel, QuantisationRel(fields, p.intensity));
  const double rel_s =
      fields.noise_estimated ? (at.intensity > 0 ? std::min(1.0, at.noise_sd / at.intensity) : 1.0) : kUnestimatedFaceNoise;
  p.rel_sampling = std::hypot(rel_s, QuantisationRel(fields, p.intensity));
  if (fields.has_normal) {
    p.normal_tilde = std::min(1.5, std::max(0.0, at.normal_stress) / fields.normal_robust_max);
    p.normal_i = std::max(0.0, at.normal_stress) * fields.normal_to_intensity;
    p.broad_i = std::max(0.0, at.intensity_broad) * fields.broad_to_intensity;
  } else {
    p.normal_tilde = 1;
    p.normal_i = 0;
    p.broad_i = 0;
  }
  p.faces = static_cast<size_t>(std::lround(at.faces));
  p.area = 0;
  return p;
}

CellGrid BuildCellGrid(const core::WearMap& map, const MapFields& fields, size_t target_cells) {
  CellGrid g;
  const auto nf = static_cast<Eigen::Index>(map.face_count());
  if (nf == 0) return g;
  const double zmin = map.z.minCoeff();
  const double zmax = map.z.maxCoeff();
  const double height = std::max(zmax - zmin, 1e-3);
  const double arc = fields.theta_span_deg * kPi / 180.0 * fields.mean_radius_m;
  const double cell = std::sqrt(height * arc / static_cast<double>(std::max<size_t>(target_cells, 1)));
  // At least a few faces per cell on average.
  const double min_cell = 2.0 * fields.face_size_m;
  const double size = std::max(cell, min_cell);
  g.nz = std::max<size_t>(1, static_cast<size_t>(std::lround(height / size)));
  g.nt = std::max<size_t>(1, static_cast<size_t>(std::lround(arc / size)));
  g.z0 = zmin - 1e-9;
  g.dz = (height + 2e-9) / static_cast<double>(g.nz);
  g.t0_deg = fields.theta_lo_deg;
  g.dt_deg = fields.theta_span_deg / static_cast<double>(g.nt);
  g.cells.assign(g.nz * g.nt, PointField{});
  g.face_cell.assign(static_cast<size_t>(nf), -1);
  std::vector<double> sw(g.cells.size(), 0.0), sz(g.cells.size(), 0.0), ssd(g.cells.size(), 0.0), ssn(g.cells.size(), 0.0);
  for (auto& c : g.cells) c.normal_tilde = 0;
  for (Eigen::Index i = 0; i < nf; ++i) {
    const int c = g.CellOf(map.z[i], map.theta_deg[i]);
    g.face_cell[static_cast<size_t>(i)] = c;
    if (c < 0) continue;
    const auto ci = static_cast<size_t>(c);
    const double a = std::max(map.areas[i], 1e-12);
    sw[ci] += a;
    sz[ci] += a * map.z[i];
    ssd[ci] += a * fields.intensity[i] * fields.rel_sd[i];
    ssn[ci] += a * fields.intensity[i] * fields.rel_noise_sd[i];
    g.cells[ci].intensity += a * fields.intensity[i];
    g.cells[ci].normal_tilde += a * fields.normal_tilde[i];
    g.cells[ci].normal_i += a * fields.normal_i[i];
    g.cells[ci].broad_i += a * fields.broad_i[i];
    g.cells[ci].faces += 1;
  }
  for (size_t c = 0; c < g.cells.size(); ++c) {
    PointField& p = g.cells[c];
    const size_t iz = c / g.nt, it = c % g.nt;
    p.theta_deg = std::fmod(g.t0_deg + (static_cast<double>(it) + 0.5) * g.dt_deg, 360.0);
    p.z = g.z0 + (static_cast<double>(iz) + 0.5) * g.dz;
    if (sw[c] <= 0) continue;
    p.intensity /= sw[c];
    p.normal_tilde /= sw[c];
    p.normal_i /= sw[c];
    p.broad_i /= sw[c];
    p.z = sz[c] / sw[c];
    // Smoothed faces share their errors: the cell's relative error is their mean, not reduced.
    p.rel_noise = std::hypot(p.intensity > 0 ? ssd[c] / sw[c] / p.intensity : 1.0, QuantisationRel(fields, p.intensity));
    p.rel_sampling = std::hypot(p.intensity > 0 ? ssn[c] / sw[c] / p.intensity : 1.0, QuantisationRel(fields, p.intensity));
    p.area = sw[c];
  }
  return g;
}

ScanCells ProjectScan(const core::WearMap& map, const MapFields& fields, const CellGrid& grid, const core::Scan& scan,
                      double t_days, double thickness_new_mm) {
  ScanCells s;
  s.t_days = t_days;
  s.file = scan.file;
  s.points_total = scan.points.size();
  const size_t nf = map.face_count();
  const size_t nc = grid.cells.size();
  s.wear_mm.assign(nc, kNaN);
  s.sigma_mm.assign(nc, kNaN);
  s.points.assign(nc, 0);
  s.face_wear_mm.assign(nf, kNaN);
  if (nf == 0) return s;
  UnwrappedIndex index(map, 1.5 * fields.face_size_m, fields.mean_radius_m);
  std::vector<std::vector<double>> per_face(nf);
  std::vector<std::vector<Eigen::Vector3d>> local(nf);  // (dz, arc, wear) per point, for the noise estimate
  const double reach = 1.5 * fields.face_size_m;
  for (const Eigen::Vector3d& p : scan.points) {
    double theta = std::atan2(p.y(), p.x()) * 180.0 / kPi;
    if (theta < 0) theta += 360.0;
    size_t best = nf;
    double best_d = std::numeric_limits<double>::max();
    index.Visit(p.z(), theta, 1, [&](size_t face, double d) {
      if (d < best_d) {
        best_d = d;
        best = face;
      }
    });
    if (best == nf || best_d > reach) continue;
    const Eigen::Vector3d& c = map.centroids[best];
    const double w = (c - p).dot(map.normals[best]) * 1000.0;
    if (w < -20.0 || w > thickness_new_mm + 20.0) continue;
    per_face[best].push_back(w);
    const auto bi = static_cast<Eigen::Index>(best);
    local[best].push_back({p.z() - map.z[bi], AngleDiffDeg(theta, map.theta_deg[bi]) * kPi / 180.0 * map.radius[bi], w});
    ++s.points_used;
  }
  // Point noise: scatter about a plane fitted to each face's points (wear varies across a face).
  std::vector<double> dev;
  for (size_t f = 0; f < nf; ++f) {
    const size_t n = local[f].size();
    if (n < 6) continue;
    Eigen::MatrixXd a(static_cast<Eigen::Index>(n), 3);
    Eigen::VectorXd b(static_cast<Eigen::Index>(n));
    for (size_t k = 0; k < n; ++k) {
      const auto kk = static_cast<Eigen::Index>(k);
      a(kk, 0) = 1;
      a(kk, 1) = local[f][k].x();
      a(kk, 2) = local[f][k].y();
      b[kk] = local[f][k].z();
    }
    const Eigen::VectorXd coef = a.colPivHouseholderQr().solve(b);
    const Eigen::VectorXd res = b - a * coef;
    const double inflate = std::sqrt(static_cast<double>(n) / static_cast<double>(n - 3));
    for (Eigen::Index k = 0; k < res.size(); ++k) dev.push_back(std::fabs(res[k]) * inflate);
  }
  s.point_noise_mm = dev.size() >= 10 ? 1.4826 * core::UpperMedian(dev) : 0.5;
  s.point_noise_mm = std::max(s.point_noise_mm, 0.05);
  std::vector<double> sw(nc, 0.0), swv(nc, 0.0), svar(nc, 0.0), ssd(nc, 0.0), ssn(nc, 0.0);
  s.fields.assign(nc, PointField{});
  for (auto& pf : s.fields) pf.normal_tilde = 0;
  for (size_t f = 0; f < nf; ++f) {
    if (per_face[f].empty()) continue;
    const double mean = std::accumulate(per_face[f].begin(), per_face[f].end(), 0.0) / static_cast<double>(per_face[f].size());
    const double med = core::UpperMedian(per_face[f]);
    // Robust face value: median when enough points, else the mean.
    const double value = per_face[f].size() >= 5 ? med : mean;
    s.face_wear_mm[f] = value;
    const int c = grid.face_cell[f];
    if (c < 0) continue;
    const auto ci = static_cast<size_t>(c);
    const double a = std::max(map.areas[static_cast<Eigen::Index>(f)], 1e-12);
    sw[ci] += a;
    swv[ci] += a * value;
    const auto fi = static_cast<Eigen::Index>(f);
    s.fields[ci].intensity += a * fields.intensity[fi];
    ssd[ci] += a * fields.intensity[fi] * fields.rel_sd[fi];
    ssn[ci] += a * fields.intensity[fi] * fields.rel_noise_sd[fi];
    s.fields[ci].normal_tilde += a * fields.normal_tilde[fi];
    s.fields[ci].normal_i += a * fields.normal_i[fi];
    s.fields[ci].broad_i += a * fields.broad_i[fi];
    s.fields[ci].z += a * map.z[fi];
    s.fields[ci].faces += 1;
    svar[ci] += a * a * s.point_noise_mm * s.point_noise_mm / static_cast<double>(per_face[f].size());
    s.points[ci] += per_face[f].size();
  }
  for (size_t c = 0; c < nc; ++c) {
    if (sw[c] <= 0) continue;
    s.wear_mm[c] = swv[c] / sw[c];
    s.sigma_mm[c] = std::sqrt(svar[c]) / sw[c];
    PointField& pf = s.fields[c];
    pf.intensity /= sw[c];
    pf.normal_tilde /= sw[c];
    pf.normal_i /= sw[c];
    pf.broad_i /= sw[c];
    pf.z /= sw[c];
    pf.theta_deg = grid.cells[c].theta_deg;
    pf.rel_noise = std::hypot(pf.intensity > 0 ? ssd[c] / sw[c] / pf.intensity : 1.0, QuantisationRel(fields, pf.intensity));
    pf.rel_sampling = std::hypot(pf.intensity > 0 ? ssn[c] / sw[c] / pf.intensity : 1.0, QuantisationRel(fields, pf.intensity));
    pf.area = sw[c];
  }
  return s;
}

}  // namespace lw::diagnosis::detail
