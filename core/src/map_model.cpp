#include "core/map_model.hpp"

#include <algorithm>
#include <atomic>
#include <thread>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>

#include "core/median.hpp"

namespace lw::core {

namespace {

constexpr double kCutoff = 2.5;  // kernel support in bandwidths

/// Runs fn(begin, end) over [0, n) on `threads` threads, in chunks handed out in order. Each face's
/// result depends only on the inputs, never on the split, so every value is the same for any
/// thread count (test MapModel.SameResultWithOneOrTwoThreads).
template <typename Fn>
void ParallelFor(Eigen::Index n, int threads, Fn&& fn, Eigen::Index kChunk = 2048) {
  if (threads <= 1 || n <= kChunk) {
    fn(Eigen::Index{0}, n);
    return;
  }
  std::atomic<Eigen::Index> next{0};
  auto worker = [&] {
    for (;;) {
      const Eigen::Index b = next.fetch_add(kChunk);
      if (b >= n) return;
      fn(b, std::min(n, b + kChunk));
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
  worker();
  for (std::thread& t : pool) t.join();
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
  std::pair<double, double> Variances(const Sums& s, double z, double theta, double radius, long skip,
                                      const Eigen::VectorXd& var) const {
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

/// Variance of Sums::Value() from the sums over the faces of w^2 var, w^2 var dz and w^2 var dz^2.
double EstimateVariance(const Sums& s, double v0, double v1, double v2) {
  if (s.Linear()) {
    const double d = s.s0 * s.s2 - s.s1 * s.s1;
    return (s.s2 * s.s2 * v0 - 2.0 * s.s2 * s.s1 * v1 + s.s1 * s.s1 * v2) / (d * d);
  }
  return v0 / (s.s0 * s.s0);
}

/// Intersection of confidence intervals over a ladder of kernels (increasing scale along z): the
/// estimate of the largest kernel whose confidence interval still intersects those of every smaller
/// one (Goldenshluger-Nemirovski / Katkovnik). Where the field is flat the noise decides and the
/// largest kernel wins; where it changes faster than a kernel's scale (the discharge-edge band of
/// a real DEM map) the larger kernels' estimates leave the smaller ones' intervals and the scale
/// stops there: a local bandwidth without a global trade-off between noise and edge bias.
struct IciResult {
  double value = std::numeric_limits<double>::quiet_NaN();
  double var = 0;
  size_t level = 0;
};
/// The ladder's steps in increasing order: Step() until done; `out` is the estimate chosen.
struct IciState {
  double lo = -std::numeric_limits<double>::max(), hi = std::numeric_limits<double>::max();
  IciResult out;
  bool done = false;
  void Step(size_t k, double v, double vv, double gamma) {
    const double sd = std::sqrt(std::max(vv, 0.0));
    lo = std::max(lo, v - gamma * sd);
    hi = std::min(hi, v + gamma * sd);
    if (lo > hi && std::isfinite(out.value)) {
      done = true;
      return;
    }
    out.value = v;
    out.var = vv;
    out.level = k;
  }
};
/// All steps of the ladder in one pass over the neighbours of (z, theta): the steps share the
/// circumferential scale `ha` and the top step's index covers them all; per step the kernel sums
/// and the sums that give the estimate's variance (for the local-linear form too).
IciResult Ici(const WearMap& map, const Eigen::VectorXd& y, const std::vector<double>& ladder, double ha, bool linear,
              const SurfaceIndex& index, double z, double theta, double radius, long skip, const Eigen::VectorXd& var,
              double gamma) {
  const size_t nk = ladder.size();
  struct Acc {
    Sums s;
    double v0 = 0, v1 = 0, v2 = 0;  // sum w^2 var, w^2 var dz, w^2 var dz^2
  };
  std::vector<Acc> acc(nk);
  std::vector<double> inv_h2(nk);
  for (size_t k = 0; k < nk; ++k) {
    inv_h2[k] = 1.0 / (ladder[k] * ladder[k]);
    acc[k].s.linear = linear;
  }
  const double cut2 = kCutoff * kCutoff, inv_ha2 = 1.0 / (ha * ha);
  index.Visit(z, theta, radius, [&](uint32_t j, double dz, double arc) {
    if (static_cast<long>(j) == skip) return;
    const double qa = arc * arc * inv_ha2;
    if (qa > cut2) return;
    const auto jj = static_cast<Eigen::Index>(j);
    const double base = map.areas[jj] * std::exp(-0.5 * qa), yj = y[jj], vj = var[jj], dz2 = dz * dz;
    for (size_t k = nk; k-- > 0;) {
      const double qz = dz2 * inv_h2[k];
      if (qz + qa > cut2) break;  // smaller steps are narrower still
      const double w = base * std::exp(-0.5 * qz);
      Acc& a = acc[k];
      a.s.Add(w, dz, yj, 0.0);
      const double w2v = w * w * vj;
      a.v0 += w2v;
      a.v1 += w2v * dz;
      a.v2 += w2v * dz2;
    }
  });
  IciState st;
  for (size_t k = 0; k < nk && !st.done; ++k) {
    const Acc& a = acc[k];
    if (!(a.s.s0 > 0)) continue;
    st.Step(k, a.s.Value(), EstimateVariance(a.s, a.v0, a.v1, a.v2), gamma);
  }
  return st.out;
}

/// Kernel sums of one scale (sd h along z, ha around) on a regular grid over the unwrapped surface
/// instead of face by face: linear binning for kernel smoothers (Wand 1994; Fan and Marron 1994).
/// Each face's area, area x value and area^2 x variance are spread onto the four grid nodes around
/// it (z, angle), bilinearly; the Gaussian is separable, so the sums every node needs (the
/// local-linear moments and the variance sums of Ici()) are two 1-D convolutions: around each row
/// of nodes (periodic, in angle, at the row's mean radius), then along z. Each node's estimate and
/// its variance are then interpolated back to the faces with the same bilinear weights. The grid
/// has kBinsPerSd steps per sd along z and around (at the largest radius); the kernel is cut at
/// kCutoff sd along each axis (a rectangle: the face-by-face kernel's cut is an ellipse). Rows of
/// nodes no face is next to are not computed. `variance`/`var`: null when only the value is needed.
constexpr double kBinsPerSd = 4.0;

struct BinnedGrid {
  double zmin = 0, dz = 1, dth = 1;  // dth: radians per column
  long nz = 1, na = 1;
  BinnedGrid(const WearMap& map, double h, double ha) {
    zmin = map.z.minCoeff();
    dz = h / kBinsPerSd;
    nz = static_cast<long>(std::ceil((map.z.maxCoeff() - zmin) / dz)) + 2;
    const double rmax = std::max(map.radius.maxCoeff(), 1e-6);
    na = std::max<long>(4, static_cast<long>(std::ceil(2.0 * M_PI * rmax / (ha / kBinsPerSd))));
    dth = 2.0 * M_PI / static_cast<double>(na);
  }
  double Cells() const { return static_cast<double>(nz) * static_cast<double>(na); }
  /// Face i's lower-left node (row, column) and its fractions towards the next row and column.
  void Locate(const WearMap& map, Eigen::Index i, long& iz, double& fz, long& ia, double& fa) const {
    const double u = (map.z[i] - zmin) / dz;
    iz = std::clamp<long>(static_cast<long>(std::floor(u)), 0, nz - 2);
    fz = std::clamp(u - static_cast<double>(iz), 0.0, 1.0);
    double t = std::fmod(map.theta_deg[i], 360.0) / 360.0 * static_cast<double>(na);
    if (!(t >= 0)) t = std::isfinite(t) ? t + static_cast<double>(na) : 0.0;
    const double ft = std::floor(t);
    ia = static_cast<long>(ft) % na;
    fa = std::clamp(t - ft, 0.0, 1.0);
  }
};

void BinnedStep(const WearMap& map, const Eigen::VectorXd& y, const Eigen::VectorXd* var, double h, double ha, bool linear,
                int threads, Eigen::VectorXd& value, Eigen::VectorXd* variance) {
  const Eigen::Index n = map.z.size();
  const BinnedGrid g(map, h, ha);
  const long nz = g.nz, na = g.na;
  const auto cells = static_cast<size_t>(nz * na);
  const bool want_var = var && variance;
  std::vector<double> a0(cells, 0.0), ay(cells, 0.0), av(want_var ? cells : 0, 0.0);
  std::vector<double> rsum(static_cast<size_t>(nz), 0.0), wsum(static_cast<size_t>(nz), 0.0);
  std::vector<char> need(static_cast<size_t>(nz), 0);
  for (Eigen::Index i = 0; i < n; ++i) {
    long iz, ia;
    double fz, fa;
    g.Locate(map, i, iz, fz, ia, fa);
    const long ib = (ia + 1) % na;
    const double a = map.areas[i], ayi = a * y[i], avi = want_var ? a * a * (*var)[i] : 0.0;
    for (int dzr = 0; dzr < 2; ++dzr) {
      const long row = iz + dzr;
      const double wz = dzr ? fz : 1.0 - fz;
      need[static_cast<size_t>(row)] = 1;
      rsum[static_cast<size_t>(row)] += wz * a * map.radius[i];
      wsum[static_cast<size_t>(row)] += wz * a;
      for (int dc = 0; dc < 2; ++dc) {
        const double w = wz * (dc ? fa : 1.0 - fa);
        const size_t cell = static_cast<size_t>(row * na + (dc ? ib : ia));
        a0[cell] += w * a;
        ay[cell] += w * ayi;
        if (want_var) av[cell] += w * avi;
      }
    }
  }
  // The sums at every node of the rows faces need, row by row along z. Around (periodic in angle)
  // each source row is convolved once for every offset along z (the elliptical cut: a row |d|
  // steps away reaches sqrt(kCutoff^2 - (d / kBinsPerSd)^2) sd around), cut by cut from the
  // narrowest, kept for the 2 mz + 1 output rows that read it; then along z the moments of Sums
  // (and the variance sums of Ici()) are summed from them. The arc length is taken at the mean of
  // the output row's and the source row's radius, as face by face: each cut also holds the
  // convolution with the kernel's derivative by the radius, and the output row adds it times half
  // the radius difference (first order; on a cone the rows a kernel reaches differ by a few %).
  const long mz = static_cast<long>(std::floor(kCutoff * kBinsPerSd + 1e-9));
  std::vector<double> radius(static_cast<size_t>(nz), 0.0);  // each row's mean radius (rows with faces)
  for (long row = 0; row < nz; ++row)
    if (wsum[static_cast<size_t>(row)] > 0)
      radius[static_cast<size_t>(row)] = std::max(rsum[static_cast<size_t>(row)] / wsum[static_cast<size_t>(row)], 1e-9);
  const long slots = 2 * mz + 1, nlev = mz + 1, arrays = want_var ? 3 : 2;
  std::vector<double> val(cells, std::numeric_limits<double>::quiet_NaN()), vv(want_var ? cells : 0, 0.0);
  std::vector<double> ez(static_cast<size_t>(nlev));
  for (long d = 0; d <= mz; ++d) ez[static_cast<size_t>(d)] = std::exp(-0.5 * std::pow(static_cast<double>(d) / kBinsPerSd, 2));
  const Eigen::Index chunk = std::max<Eigen::Index>(4 * mz, (nz + 2 * threads - 1) / std::max(1, 2 * threads));
  ParallelFor(
      nz, threads,
      [&](Eigen::Index begin, Eigen::Index end) {
        // ring[slot][array][level][column], slot = source row mod slots
        std::vector<double> ring(static_cast<size_t>(slots * arrays * nlev * 2 * na));
        std::vector<long> held(static_cast<size_t>(slots), -1);
        std::vector<double> buf, kern, dkern, acc(static_cast<size_t>(8 * na));
        std::vector<long> cut(static_cast<size_t>(nlev));
        // The cut `lev` of source row src's convolution (deriv: by the radius) of array arr.
        auto level = [&](long src, long arr, long lev, long deriv) {
          return ring.data() + ((((src % slots) * arrays + arr) * nlev + lev) * 2 + deriv) * na;
        };
        auto load = [&](long src) {
          if (held[static_cast<size_t>(src % slots)] == src) return;
          held[static_cast<size_t>(src % slots)] = src;
          const double r = radius[static_cast<size_t>(src)];
          const double ku = ha / (r * g.dth);  // kernel sd in columns
          for (long l = 0; l < nlev; ++l) {
            const double reach = std::sqrt(std::max(0.0, kCutoff * kCutoff - std::pow(static_cast<double>(l) / kBinsPerSd, 2)));
            cut[static_cast<size_t>(l)] = std::min<long>(static_cast<long>(std::floor(reach * ku + 1e-9)), (na - 1) / 2);
          }
          const long m = cut[0];
          kern.resize(static_cast<size_t>(m + 1));
          dkern.resize(static_cast<size_t>(m + 1));
          for (long arr = 0; arr < arrays; ++arr) {
            const double* data = (arr == 0 ? a0.data() : arr == 1 ? ay.data() : av.data()) + src * na;
            const double power = arr == 2 ? 1.0 : 0.5;  // the variance sums weigh by the squared kernel
            for (long j = 0; j <= m; ++j) {
              const double u2 = std::pow(static_cast<double>(j) / ku, 2);
              kern[static_cast<size_t>(j)] = std::exp(-power * u2);
              dkern[static_cast<size_t>(j)] = -2.0 * power * u2 / r * kern[static_cast<size_t>(j)];
            }
            buf.resize(static_cast<size_t>(na + 2 * m));
            for (long c = 0; c < na + 2 * m; ++c) buf[static_cast<size_t>(c)] = data[((c - m) % na + na) % na];
            const double* mid = buf.data() + m;
            // From the narrowest cut (the farthest row) to the widest, adding the taps in between.
            for (long deriv = 0; deriv < 2; ++deriv) {
              const std::vector<double>& kk = deriv ? dkern : kern;
              double* prev = nullptr;
              long have = -1;
              for (long l = nlev - 1; l >= 0; --l) {
                double* out = level(src, arr, l, deriv);
                if (prev)
                  std::copy(prev, prev + na, out);
                else
                  std::fill(out, out + na, 0.0);
                for (long j = have + 1; j <= cut[static_cast<size_t>(l)]; ++j) {
                  const double kj = kk[static_cast<size_t>(j)];
                  if (j == 0) {
                    for (long c = 0; c < na; ++c) out[c] += kj * mid[c];
                  } else {
                    for (long c = 0; c < na; ++c) out[c] += kj * (mid[c - j] + mid[c + j]);
                  }
                }
                have = std::max(have, cut[static_cast<size_t>(l)]);
                prev = out;
              }
            }
          }
        };
        for (Eigen::Index row = begin; row < end; ++row) {
          if (!need[static_cast<size_t>(row)]) continue;
          std::fill(acc.begin(), acc.end(), 0.0);
          double* s0 = acc.data();
          double *s1 = s0 + na, *s2 = s1 + na, *t0 = s2 + na, *t1 = t0 + na, *v0 = t1 + na, *v1 = v0 + na, *v2 = v1 + na;
          for (long d = -mz; d <= mz; ++d) {
            const long src = row + d;
            if (src < 0 || src >= nz || !(wsum[static_cast<size_t>(src)] > 0)) continue;
            load(src);
            const long l = std::labs(d);
            const double x = static_cast<double>(d) * g.dz, e = ez[static_cast<size_t>(l)];
            const double e1 = e * x, e2 = e1 * x;
            const double dr = wsum[static_cast<size_t>(row)] > 0
                                  ? 0.5 * (radius[static_cast<size_t>(row)] - radius[static_cast<size_t>(src)])
                                  : 0.0;
            const double *p0 = level(src, 0, l, 0), *q0 = level(src, 0, l, 1);
            const double *py = level(src, 1, l, 0), *qy = level(src, 1, l, 1);
            for (long c = 0; c < na; ++c) {
              const double a = p0[c] + dr * q0[c], b = py[c] + dr * qy[c];
              s0[c] += e * a;
              s1[c] += e1 * a;
              s2[c] += e2 * a;
              t0[c] += e * b;
              t1[c] += e1 * b;
            }
            if (want_var) {
              const double f = e * e, f1 = f * x, f2 = f1 * x;
              const double *pv = level(src, 2, l, 0), *qv = level(src, 2, l, 1);
              for (long c = 0; c < na; ++c) {
                const double a = pv[c] + dr * qv[c];
                v0[c] += f * a;
                v1[c] += f1 * a;
                v2[c] += f2 * a;
              }
            }
          }
          for (long c = 0; c < na; ++c) {
            Sums s;
            s.s0 = s0[c];
            s.s1 = s1[c];
            s.s2 = s2[c];
            s.t0 = t0[c];
            s.t1 = t1[c];
            s.linear = linear;
            if (!(s.s0 > 0)) continue;
            const auto cell = static_cast<size_t>(row * na + c);
            val[cell] = s.Value();
            if (want_var) vv[cell] = EstimateVariance(s, v0[c], v1[c], v2[c]);
          }
        }
      },
      chunk);
  // Back to the faces: the nodes around each, with the weights it was spread with.
  value.resize(n);
  if (variance) variance->resize(n);
  ParallelFor(n, threads, [&](Eigen::Index begin, Eigen::Index end) {
    for (Eigen::Index i = begin; i < end; ++i) {
      long iz, ia;
      double fz, fa;
      g.Locate(map, i, iz, fz, ia, fa);
      const long ib = (ia + 1) % na;
      double sw = 0, sv = 0, svv = 0;
      for (int dzr = 0; dzr < 2; ++dzr) {
        for (int dc = 0; dc < 2; ++dc) {
          const double w = (dzr ? fz : 1.0 - fz) * (dc ? fa : 1.0 - fa);
          const auto cell = static_cast<size_t>((iz + dzr) * na + (dc ? ib : ia));
          if (!(w > 0) || !std::isfinite(val[cell])) continue;
          sw += w;
          sv += w * val[cell];
          if (want_var) svv += w * vv[cell];
        }
      }
      value[i] = sw > 0 ? sv / sw : std::numeric_limits<double>::quiet_NaN();
      if (variance) (*variance)[i] = sw > 0 && want_var ? svv / sw : std::numeric_limits<double>::quiet_NaN();
    }
  });
}

}  // namespace

double MapModel::FaceVariance(double m) const {
  return noise_phi * std::pow(std::max(m, 0.0), noise_power);
}

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
      const double v = k.Variance(s, z, theta_deg, -1, -1, face_var);
      p.sd = std::sqrt(v + std::pow(smoothing_error_rel * p.intensity, 2));
      p.noise_sd = std::sqrt(v);
      if (local_ladder_m.size() > 1 && index) {
        // The same local scale as the faces get (Eq. 9's row scale sees the faces' averaging).
        const IciResult r =
            Ici(m, clean, local_ladder_m, bandwidth_arc_m, local_linear, *index, z, theta_deg, -1, -1, ref_var, local_gamma);
        if (std::isfinite(r.value) && r.level + 1 < local_ladder_m.size()) {
          p.intensity = std::max(0.0, r.value);
          p.sd = std::sqrt(2.0 * r.var);
          p.noise_sd = std::sqrt(r.var);
        }
      }
      if (nrm && normal_index) {
        Kernel kn(m, *nrm, &clean, normal_bandwidth_m, 3.0 * bandwidth_arc_m, normal_index);
        kn.linear = false;
        const Sums sn = kn.At(z, theta_deg, -1, -1);
        p.normal_stress = sn.s0 > 0 ? sn.t0 / sn.s0 : 0.0;
        p.intensity_broad = sn.s0 > 0 ? sn.n0 / sn.s0 : 0.0;
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
  p.noise_sd = intensity_noise_sd.size() == intensity_sd.size() ? intensity_noise_sd[best] : p.sd;
  p.normal_stress = normal_stress.size() ? normal_stress[best] : 0.0;
  p.intensity_broad = intensity_broad.size() ? intensity_broad[best] : 0.0;
  p.faces = 1;
  return p;
}

namespace {

/// 1. Pilot: each face predicted from its nearest neighbours (leave-one-out, 1.5 face sizes).
struct Pilot {
  Eigen::VectorXd value;  ///< per face: its neighbours' weighted mean, the face left out
  Eigen::VectorXd neff;   ///< per face: the effective number of those neighbours
};

Pilot PilotEstimate(const WearMap& map, const MapModel& model, int threads) {
  const Eigen::Index n = model.clean.size();
  Pilot out{Eigen::VectorXd(n), Eigen::VectorXd(n)};
  Eigen::VectorXd& pilot = out.value;
  Eigen::VectorXd& pilot_neff = out.neff;
  const Kernel k(map, model.clean, nullptr, 0.5 * model.face_size_m, 3.0 * model.face_size_m);
  ParallelFor(n, threads, [&](Eigen::Index begin, Eigen::Index end) {
    for (Eigen::Index i = begin; i < end; ++i) {
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
  });
  return out;
}

/// 2. Noise law var = phi m^p: a face's wear sums the energies of the contacts it received, so its
///    variance grows like its mean (compound Poisson, p = 1) when contacts are independent, and
///    like its square (p = 2, a constant relative scatter) when they come in bursts (a few heavy
///    particles, the same rock hitting again): real LIGGGHTS maps are close to p = 2, with a face's
///    relative scatter about the same everywhere. p is fitted (log-log, in [1, 2]) and phi then,
///    from wear_stderr (the spread of the run's windows) when the map has it, else from each face
///    against its neighbours; the top 2 % of ratios trimmed either way (spikes).
void FitNoiseLaw(const WearMap& map, const Pilot& pilot_estimate, MapModel& model) {
  const Eigen::Index n = model.clean.size();
  const Eigen::VectorXd& pilot = pilot_estimate.value;
  const Eigen::VectorXd& pilot_neff = pilot_estimate.neff;
  const bool use_stderr = map.has_wear_stderr() && map.wear_stderr.size() == n && map.wear_stderr.maxCoeff() > 0;
  std::vector<std::pair<double, double>> obs;  // (mean, squared deviation)
  for (Eigen::Index i = 0; i < n; ++i) {
    if (pilot[i] <= 0) continue;
    if (use_stderr) {
      obs.push_back({pilot[i], map.wear_stderr[i] * map.wear_stderr[i]});
    } else if (pilot_neff[i] > 0) {
      const double d = model.clean[i] - pilot[i];
      obs.push_back({pilot[i], d * d / (1.0 + 1.0 / pilot_neff[i])});
    }
  }
  // p from the slope of log E[d^2] against log m over ten bins of m (bin means, not logs of
  // single squares: those are biased by the chi-square's skew).
  double p = 1.0;
  if (obs.size() >= 50) {
    std::sort(obs.begin(), obs.end());
    const size_t bins = 10, per = obs.size() / bins;
    double sx = 0, sy = 0, sxx = 0, sxy = 0, nb = 0;
    for (size_t b = 0; b < bins; ++b) {
      double m = 0, v = 0;
      for (size_t k = b * per; k < (b + 1) * per; ++k) {
        m += obs[k].first;
        v += obs[k].second;
      }
      if (!(m > 0 && v > 0)) continue;
      const double x = std::log(m / static_cast<double>(per)), y = std::log(v / static_cast<double>(per));
      sx += x;
      sy += y;
      sxx += x * x;
      sxy += x * y;
      nb += 1;
    }
    const double den = nb * sxx - sx * sx;
    if (nb >= 3 && den > 1e-12) p = std::clamp((nb * sxy - sx * sy) / den, 1.0, 2.0);
  }
  std::vector<double> ratio;
  for (const auto& [m, d2] : obs) ratio.push_back(d2 / std::pow(m, p));
  std::sort(ratio.begin(), ratio.end());
  const size_t keep = ratio.size() - ratio.size() / 50;
  double sum = 0;
  for (size_t k = 0; k < keep; ++k) sum += ratio[k];
  model.noise_power = p;
  model.noise_phi = keep ? sum / static_cast<double>(keep) : 0.0;
  model.noise_source =
      use_stderr ? "wear_stderr (" +
                       (map.windows > 0 ? std::to_string(map.windows) + " windows" : std::string("windows not stated")) + ")"
                 : "neighbour differences";
}

/// 3. Outliers: a face far above its neighbourhood is capped (one-sided: DEM spikes are faces a
///    few particles hit hard, at the feed and discharge edges mostly).
void CapOutliers(const Eigen::VectorXd& pilot, const MapModelOptions& options, MapModel& model) {
  const Eigen::Index n = model.clean.size();
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
}

/// 4. Bandwidth: along z, and around the circumference 1, 3 or 8 times that (a gyratory chamber's
///    wear changes much faster along z than around; the data decide how much).
std::vector<std::pair<double, double>> BandwidthCandidates(const WearMap& map, const MapModelOptions& options, MapModel& model) {
  const Eigen::Index n = model.clean.size();
  const double extent = std::max(map.z.maxCoeff() - map.z.minCoeff(), 10 * model.face_size_m);
  std::vector<std::pair<double, double>> candidates;  // (along z, around)
  if (options.bandwidth_m > 0) {
    candidates.push_back({options.bandwidth_m, options.bandwidth_arc_m > 0 ? options.bandwidth_arc_m : options.bandwidth_m});
    model.bandwidth_method = "fixed";
  } else if (options.bandwidth_m < 0) {
    const double mean_area = map.areas.sum() / static_cast<double>(n);
    const double half_circumference = M_PI * std::max(1e-3, map.radius.mean());
    for (double h = model.face_size_m; h <= 0.2 * extent + 1e-12; h *= 1.4) {
      for (double ratio : {1.0, 3.0, 8.0, 24.0, 1e9}) {
        const double ha = std::min(ratio * h, half_circumference);
        if (ratio > 1.0 && ha <= h * 1.01) continue;
        if (ratio > 8.0 && !candidates.empty() && candidates.back().first == h && candidates.back().second >= ha * 0.99) continue;
        // Work bound: faces visited per face (the kernel's bounding disc) x faces: about 2e9 terms
        // at most for the final smoothing (a million-face map keeps to a few face sizes).
        const double visits = M_PI * std::pow(kCutoff * std::max(h, ha), 2) / std::max(mean_area, 1e-12);
        if (visits * static_cast<double>(n) > 2e9 && !candidates.empty()) continue;
        candidates.push_back({h, ha});
      }
    }
    model.bandwidth_method = "cross-validation";
  }
  return candidates;
}

/// No bandwidth to choose from: each face as it is, with its noise law's sd.
void WithoutSmoothing(const Eigen::VectorXd& pilot, MapModel& model) {
  const Eigen::Index n = model.clean.size();
  model.bandwidth_m = 0;
  model.bandwidth_method = "none";
  for (Eigen::Index i = 0; i < n; ++i) model.intensity_sd[i] = std::sqrt(model.FaceVariance(pilot[i]));
  model.intensity_noise_sd = model.intensity_sd;
  std::vector<double> cv;
  for (Eigen::Index i = 0; i < n; ++i)
    if (pilot[i] > 0) cv.push_back(std::sqrt(model.FaceVariance(pilot[i])) / pilot[i]);
  model.face_cv = UpperMedian(cv);
}

/// 4. (continued) The candidate (bandwidth and form) of least cross-validated error, on up to
/// max_cv_faces faces, and the smoothing's own error at it.
void ChooseBandwidth(const WearMap& map, const std::vector<std::pair<double, double>>& candidates, const Eigen::VectorXd& pilot,
                     const MapModelOptions& options, int threads, MapModel& model) {
  const Eigen::Index n = model.clean.size();
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
    Kernel k(map, model.clean, nullptr, candidates[c].first, candidates[c].second);
    // Both forms from the same sums (one pass over the neighbours).
    ParallelFor(static_cast<Eigen::Index>(eval.size()), threads, [&](Eigen::Index begin, Eigen::Index end) {
      for (auto e = static_cast<size_t>(begin); e < static_cast<size_t>(end); ++e) {
        const Eigen::Index i = eval[e];
        Sums s = k.At(map.z[i], map.theta_deg[i], map.radius[i], static_cast<long>(i));
        if (!(s.s0 > 0)) continue;
        for (int form = 0; form < 2; ++form) {
          s.linear = form == 1;
          loo[2 * c + static_cast<size_t>(form)][e] = std::max(0.0, s.Value());
        }
      }
    });
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
    model.cv_curve.push_back(
        {candidates[c].first, score[best] > 0 ? std::min(score[2 * c], score[2 * c + 1]) / score[best] : 1.0});
  // The smoothing's own error: what the cross-validated error holds beyond the faces' noise and the
  // noise of the prediction, relative to the field's mean square.
  if (area_sum > 0) {
    // The prediction noise of the chosen candidate only (the others' is not needed).
    Kernel k(map, model.clean, nullptr, candidates[best / 2].first, candidates[best / 2].second);
    k.linear = best % 2 == 1;
    ParallelFor(static_cast<Eigen::Index>(eval.size()), threads, [&](Eigen::Index begin, Eigen::Index end) {
      for (auto e = static_cast<size_t>(begin); e < static_cast<size_t>(end); ++e) {
        const Eigen::Index i = eval[e];
        if (!std::isfinite(loo[best][e])) continue;
        const Sums s = k.At(map.z[i], map.theta_deg[i], map.radius[i], static_cast<long>(i));
        loo_var[best][e] = k.Variance(s, map.z[i], map.theta_deg[i], map.radius[i], static_cast<long>(i), pilot_var);
      }
    });
    // The error is not clipped here: the clip that keeps spike faces from choosing the scale would
    // drop the heavy tail of the faces' noise from the error but not from the noise law, and the
    // difference would read as no smoothing error at all (a finely meshed LIGGGHTS map, whose
    // small faces have spikier noise, gave 0 in most cases).
    double var_pred = 0, error_sum = 0;
    for (size_t e = 0; e < eval.size(); ++e) {
      if (!std::isfinite(loo[best][e])) continue;
      bool all = true;
      for (size_t c = 0; c < nc; ++c) all = all && std::isfinite(loo[c][e]);
      if (!all) continue;
      const double a = map.areas[eval[e]];
      var_pred += a * loo_var[best][e];
      m2_sum += a * loo[best][e] * loo[best][e];
      error_sum += a * std::pow(model.clean[eval[e]] - loo[best][e], 2);
    }
    const double bias2 = std::max(0.0, (error_sum - noise_sum - var_pred) / area_sum);
    model.smoothing_error_rel = m2_sum > 0 ? std::sqrt(bias2 / (m2_sum / area_sum)) : 0.0;
  }
}

/// Normal stress at three times the wear's scale: its sampling noise is shared with the wear's
/// (the same contacts), and at the wear's own scale it would carry the wear map's error into
/// every stress-based hypothesis (a map over-predicting where it happened to sample more
/// contacts would look like work hardening). The stress field's real pattern is broad.
void SmoothNormalStress(const WearMap& map, const Eigen::VectorXd& normal, bool binned, int threads, MapModel& model) {
  const Eigen::Index n = model.clean.size();
  model.normal_bandwidth_m = 3.0 * model.bandwidth_m;
  Kernel kn(map, normal, nullptr, model.normal_bandwidth_m, 3.0 * model.bandwidth_arc_m);
  kn.linear = false;
  model.normal_index = kn.owned;
  model.intensity_broad.resize(n);
  if (binned) {
    Eigen::VectorXd v;
    BinnedStep(map, normal, nullptr, kn.h, kn.ha, false, threads, v, nullptr);
    for (Eigen::Index i = 0; i < n; ++i) model.normal_stress[i] = std::isfinite(v[i]) ? v[i] : normal[i];
    BinnedStep(map, model.clean, nullptr, kn.h, kn.ha, false, threads, v, nullptr);
    for (Eigen::Index i = 0; i < n; ++i) model.intensity_broad[i] = std::isfinite(v[i]) ? v[i] : model.clean[i];
  } else {
    // The stress's kernel carries the capped wear as its second value (Sums::n0): both in one pass.
    Kernel kb(map, normal, &model.clean, kn.h, kn.ha, kn.owned);
    kb.linear = false;
    ParallelFor(n, threads, [&](Eigen::Index begin, Eigen::Index end) {
      for (Eigen::Index i = begin; i < end; ++i) {
        const Sums sn = kb.At(map.z[i], map.theta_deg[i], map.radius[i], -1);
        model.normal_stress[i] = sn.s0 > 0 ? sn.t0 / sn.s0 : normal[i];
        model.intensity_broad[i] = sn.s0 > 0 ? sn.n0 / sn.s0 : model.clean[i];
      }
    });
  }
}

/// The faces' variance and standard errors at the chosen bandwidth (kernel `k`; `sums`, its sums
/// per face, unless `binned`) and, with `ici`, at the local scale (6.) where that is smaller.
void LocalScaleAndError(const WearMap& map, const Kernel& k, const std::vector<Sums>& sums, bool binned, bool ici,
                        const MapModelOptions& options, int threads, MapModel& model) {
  const Eigen::Index n = model.clean.size();
  Eigen::VectorXd& var = model.face_var;
  // With the local scale (6.) the variance comes from its pass over the neighbours (its top step
  // is this kernel, on the same face variances); without it, or where that pass finds no
  // estimate, from this kernel here.
  if (ici) {
    model.local_gamma = options.local_gamma;
    model.ref_var = model.face_var;
    model.local_bandwidth_m = Eigen::VectorXd::Zero(n);
  }
  // Face i's result from its local-scale estimate r (none: no local scale, or no estimate) and
  // the variance at the chosen bandwidth (called only when needed).
  auto finish = [&](Eigen::Index i, const IciResult* r, auto&& top_variance) {
    double v = std::numeric_limits<double>::quiet_NaN();
    if (r && std::isfinite(r->value)) {
      model.local_bandwidth_m[i] = model.local_ladder_m[r->level];
      if (r->level + 1 < model.local_ladder_m.size()) {
        model.intensity[i] = std::max(0.0, r->value);
        // Stopped below the top: the estimate's bias is bounded by about its own sd (that is
        // where the intervals stop intersecting), so its error is counted twice.
        model.intensity_sd[i] = std::sqrt(2.0 * r->var);
        model.intensity_noise_sd[i] = std::sqrt(r->var);
        return;
      }
      v = r->var;  // the global scale: the value of 5., its variance from the top step
    }
    if (!std::isfinite(v)) v = top_variance();
    model.intensity_sd[i] = std::sqrt(v + std::pow(model.smoothing_error_rel * model.intensity[i], 2));
    model.intensity_noise_sd[i] = std::sqrt(v);
  };
  // 6. Local scale along z (ICI): the cross-validated scale is right on average over the liner,
  //    and the average is dominated by the many faces where the field is flat; where it changes
  //    within a kernel (a real map's discharge-edge band holds several times the wear of the
  //    band above), a smaller scale is used, as small as the data show the change to be real.
  if (binned) {
    // Step by step over the whole map, each face's intervals kept between steps.
    std::vector<IciState> state(ici ? static_cast<size_t>(n) : 0);
    Eigen::VectorXd val, top_var;
    const size_t nk = ici ? model.local_ladder_m.size() : 1;
    for (size_t s = 0; s < nk; ++s) {
      const double h = ici ? model.local_ladder_m[s] : model.bandwidth_m;
      BinnedStep(map, model.clean, &var, h, model.bandwidth_arc_m, model.local_linear, threads, val, &top_var);
      for (Eigen::Index i = 0; ici && i < n; ++i) {
        IciState& st = state[static_cast<size_t>(i)];
        if (!st.done && std::isfinite(val[i])) st.Step(s, val[i], top_var[i], model.local_gamma);
      }
    }
    for (Eigen::Index i = 0; i < n; ++i)
      finish(i, ici ? &state[static_cast<size_t>(i)].out : nullptr, [&] { return top_var[i]; });
  } else {
    ParallelFor(n, threads, [&](Eigen::Index begin, Eigen::Index end) {
      for (Eigen::Index i = begin; i < end; ++i) {
        IciResult r;
        if (ici)
          r = Ici(map, model.clean, model.local_ladder_m, model.bandwidth_arc_m, model.local_linear, *model.index, map.z[i],
                  map.theta_deg[i], map.radius[i], -1, model.ref_var, model.local_gamma);
        finish(i, ici ? &r : nullptr,
               [&] { return k.Variance(sums[static_cast<size_t>(i)], map.z[i], map.theta_deg[i], map.radius[i], -1, var); });
      }
    });
  }
  if (ici) {
    for (Eigen::Index i = 0; i < n; ++i) model.face_var[i] = model.FaceVariance(model.intensity[i]);
  }
}

/// 5. The field at the chosen bandwidth, and its standard error.
void SmoothField(const WearMap& map, const Eigen::VectorXd* nrm, const MapModelOptions& options, int threads, MapModel& model) {
  const Eigen::Index n = model.clean.size();
  Kernel k(map, model.clean, nrm, model.bandwidth_m, model.bandwidth_arc_m);
  k.linear = model.local_linear;
  model.index = k.owned;
  // The ladder of the local scale (6.).
  if (model.bandwidth_method == "cross-validation" && options.local_scale) {
    for (double h = 0.25 * model.face_size_m; h < model.bandwidth_m * 0.999; h *= 1.4) model.local_ladder_m.push_back(h);
    model.local_ladder_m.push_back(model.bandwidth_m);
  }
  const bool ici = model.local_ladder_m.size() > 1;
  // Large maps: the kernel sums on a grid (BinnedStep), unless the finest scale's grid would be
  // much larger than the map (a map very long along z for its face size).
  const double finest = ici ? model.local_ladder_m.front() : model.bandwidth_m;
  const bool binned = static_cast<size_t>(n) > options.binned_above_faces &&
                      BinnedGrid(map, finest, model.bandwidth_arc_m).Cells() <= 16.0 * static_cast<double>(n) + 1e6;
  std::vector<Sums> sums(binned ? 0 : static_cast<size_t>(n));
  if (binned) {
    Eigen::VectorXd v;
    BinnedStep(map, model.clean, nullptr, model.bandwidth_m, model.bandwidth_arc_m, model.local_linear, threads, v, nullptr);
    for (Eigen::Index i = 0; i < n; ++i) model.intensity[i] = std::isfinite(v[i]) ? std::max(0.0, v[i]) : model.clean[i];
  } else {
    ParallelFor(n, threads, [&](Eigen::Index begin, Eigen::Index end) {
      for (Eigen::Index i = begin; i < end; ++i) {
        sums[static_cast<size_t>(i)] = k.At(map.z[i], map.theta_deg[i], map.radius[i], -1);
        const Sums& s = sums[static_cast<size_t>(i)];
        model.intensity[i] = s.s0 > 0 ? std::max(0.0, s.Value()) : model.clean[i];
      }
    });
  }
  if (nrm) SmoothNormalStress(map, *nrm, binned, threads, model);
  Eigen::VectorXd& var = model.face_var;
  var.resize(n);
  for (Eigen::Index i = 0; i < n; ++i) var[i] = model.FaceVariance(model.intensity[i]);
  LocalScaleAndError(map, k, sums, binned, ici, options, threads, model);
}

}  // namespace

MapModel BuildMapModel(const WearMap& map, const MapModelOptions& options) {
  MapModel model;
  model.map = &map;
  const Eigen::Index n = static_cast<Eigen::Index>(map.face_count());
  const int threads = options.threads > 0 ? options.threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  model.clean = map.wear.size() == n ? Eigen::VectorXd(map.wear.cwiseMax(0.0)) : Eigen::VectorXd::Zero(n);
  model.intensity = model.clean;
  model.intensity_sd = Eigen::VectorXd::Zero(n);
  model.intensity_noise_sd = Eigen::VectorXd::Zero(n);
  if (map.has_normal_stress() && map.normal_stress.size() == n) model.normal_stress = map.normal_stress;
  if (n == 0) return model;
  const Eigen::VectorXd* nrm = model.normal_stress.size() ? &map.normal_stress : nullptr;

  std::vector<double> sizes(static_cast<size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) sizes[static_cast<size_t>(i)] = std::sqrt(2.0 * std::max(map.areas[i], 0.0));
  model.face_size_m = std::max(UpperMedian(sizes), 1e-4);

  const Pilot pilot = PilotEstimate(map, model, threads);
  FitNoiseLaw(map, pilot, model);
  CapOutliers(pilot.value, options, model);
  const std::vector<std::pair<double, double>> candidates = BandwidthCandidates(map, options, model);
  if (candidates.empty()) {
    WithoutSmoothing(pilot.value, model);
    return model;
  }
  ChooseBandwidth(map, candidates, pilot.value, options, threads, model);
  SmoothField(map, nrm, options, threads, model);

  std::vector<double> cv;
  for (Eigen::Index i = 0; i < n; ++i)
    if (model.intensity[i] > 0) cv.push_back(std::sqrt(model.FaceVariance(model.intensity[i])) / model.intensity[i]);
  model.face_cv = UpperMedian(cv);
  return model;
}

}  // namespace lw::core
