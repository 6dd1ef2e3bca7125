// The diagnosis' fitting primitives (model_fit.hpp).
#include "model_fit.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <optional>

#include "levenberg_marquardt.hpp"

namespace lw::diagnosis::detail {
namespace {

// The per-sensor intensity error u minimising sum((pred (1 + u) - target)^2 / sigma^2) + u^2 prior_inv_var
// over the sensor's observations in `mask`; nullopt when the mask holds none of them.
std::optional<double> ProfiledU(const Problem& p, const Eigen::MatrixXd& w, size_t sensor, const Mask& mask, bool raw,
                                double prior_inv_var) {
  double num = 0, den = prior_inv_var;
  bool any = false;
  for (size_t i : p.sensor_obs[sensor]) {
    if (!mask[i]) continue;
    any = true;
    const Obs& o = p.obs[i];
    const double pred = Interp(w, o);
    num += (pred - (raw ? o.raw : o.wear)) * pred / (o.sigma * o.sigma);
    den += pred * pred / (o.sigma * o.sigma);
  }
  if (!any) return std::nullopt;
  return den > 0 ? -num / den : 0.0;
}

}  // namespace

double Round(double v, double digits) {
  const double f = std::pow(10.0, digits);
  return std::round(v * f) / f;
}

namespace {

/// Standard errors from J'J: the square roots of the diagonal of the inverse of its rows and
/// columns `keep` (every parameter when empty); NaN for the others.
Eigen::VectorXd Stderr(const Eigen::MatrixXd& jtj, const std::vector<Eigen::Index>& keep) {
  if (keep.empty()) return jtj.ldlt().solve(Eigen::MatrixXd::Identity(jtj.rows(), jtj.cols())).diagonal().cwiseAbs().cwiseSqrt();
  const auto n = static_cast<Eigen::Index>(keep.size());
  Eigen::MatrixXd sub(n, n);
  for (Eigen::Index a = 0; a < n; ++a)
    for (Eigen::Index b = 0; b < n; ++b) sub(a, b) = jtj(keep[static_cast<size_t>(a)], keep[static_cast<size_t>(b)]);
  const Eigen::MatrixXd cov = sub.ldlt().solve(Eigen::MatrixXd::Identity(n, n));
  Eigen::VectorXd se = Eigen::VectorXd::Constant(jtj.rows(), kNaN);
  for (Eigen::Index a = 0; a < n; ++a) se[keep[static_cast<size_t>(a)]] = std::sqrt(std::fabs(cov(a, a)));
  return se;
}

/// The parameters that are not an effect's shape (spec.rows' scales and every effect size).
std::vector<Eigen::Index> NonShapeParams(const ModelSpec& spec) {
  std::vector<Eigen::Index> keep;
  for (Eigen::Index k = 0; k < static_cast<Eigen::Index>(spec.rows); ++k) keep.push_back(k);
  for (Effect e : spec.effects) {
    Eigen::Index k = spec.Offset(e);
    for (const ParamSpec& ps : EffectParams(e)) {
      if (!ps.shape) keep.push_back(k);
      ++k;
    }
  }
  return keep;
}

}  // namespace

Eigen::VectorXd StderrGivenShape(const ModelSpec& spec, const Eigen::MatrixXd& jtj) {
  return Stderr(jtj, NonShapeParams(spec));
}

double Interp(const Eigen::MatrixXd& w, const Obs& o) {
  const auto r = static_cast<Eigen::Index>(o.point);
  const auto j = static_cast<Eigen::Index>(o.j);
  if (j + 1 >= w.cols()) return w(r, w.cols() - 1);
  return w(r, j) * (1.0 - o.frac) + w(r, j + 1) * o.frac;
}

int BandIndex(const Problem& p, const Obs& o) {
  if (o.scan < 0) return -1;
  const int band = std::clamp(static_cast<int>(std::floor((p.points[o.point].zn + 0.5) * kScanBands)), 0, kScanBands - 1);
  return o.scan * kScanBands + band;
}

size_t BandCount(const Problem& p) {
  int scans = 0;
  for (size_t i : p.scan_obs) scans = std::max(scans, p.obs[i].scan + 1);
  return static_cast<size_t>(scans) * kScanBands;
}

BandSums SumBands(const Problem& p, const Eigen::MatrixXd& w, const Mask& mask, bool raw) {
  const size_t n = BandCount(p);
  BandSums s{std::vector<double>(n, 0.0), std::vector<double>(n, 0.0), std::vector<bool>(n, false)};
  for (size_t i : p.scan_obs) {
    if (!mask[i]) continue;
    const Obs& o = p.obs[i];
    const auto g = static_cast<size_t>(BandIndex(p, o));
    const double pred = Interp(w, o);
    s.num[g] += (pred - (raw ? o.raw : o.wear)) * pred / (o.sigma * o.sigma);
    s.den[g] += pred * pred / (o.sigma * o.sigma);
    s.present[g] = true;
  }
  return s;
}

std::vector<double> ProfiledBandOffsets(const Problem& p, const Eigen::MatrixXd& w, const Mask& mask, bool raw,
                                        std::vector<bool>& present) {
  const size_t n = BandCount(p);
  std::vector<double> b(n, 0.0);
  present.assign(n, false);
  if (!(p.band_sd > 0)) return b;
  BandSums s = SumBands(p, w, mask, raw);
  const double prior = 1.0 / (p.band_sd * p.band_sd);
  for (size_t g = 0; g < n; ++g) b[g] = s.present[g] ? -s.num[g] / (s.den[g] + prior) : 0.0;
  present = std::move(s.present);
  return b;
}

void SensorDepthRows(const Problem& p, const ModelSpec& spec, const Eigen::VectorXd& x, const std::vector<double>& u,
                     Eigen::MatrixXd& w) {
  if (!DepthDependent(spec)) return;
  std::vector<ModelPoint> points;
  std::vector<double> factors;
  std::vector<Eigen::Index> rows;
  for (size_t s = 0; s < p.sensor_obs.size() && s < u.size(); ++s) {
    if (p.sensor_obs[s].empty() || u[s] == 0) continue;
    const size_t point = p.obs[p.sensor_obs[s].front()].point;
    points.push_back(p.points[point]);
    factors.push_back(OwnRateFactor(u[s]));
    rows.push_back(static_cast<Eigen::Index>(point));
  }
  if (points.empty()) return;
  Eigen::MatrixXd ws;
  SimulateOwnRates(spec, x, points, factors, p.grid, ws);
  for (size_t k = 0; k < rows.size(); ++k) w.row(rows[k]) = ws.row(static_cast<Eigen::Index>(k));
}

// Whitened residuals over the training observations; per-sensor random intensity error u_s is
// profiled out analytically (prior N(0, sigma_u^2)).
void Residuals(const Problem& p, const ModelSpec& spec, const Eigen::VectorXd& x, const Mask& train, const EvalOptions& opt,
               Eigen::VectorXd& r, std::vector<double>* u_out, Eigen::MatrixXd& w) {
  Simulate(spec, x, p.points, p.grid, w);
  if (opt.use_u && DepthDependent(spec)) {
    // A sensor's intensity error changes when it reaches a depth, not only how much it wears: its
    // curve is simulated at its own rate (u profiled on the plain curves, then once more on its own).
    std::vector<double> u(p.sensor_obs.size(), 0.0);
    const Eigen::MatrixXd plain = w;
    for (int pass = 0; pass < 2; ++pass) {
      for (size_t s = 0; s < p.sensor_obs.size(); ++s) {
        const std::optional<double> pu = ProfiledU(p, w, s, train, opt.raw, 1.0 / (p.sigma_u[s] * p.sigma_u[s]));
        // Rows divided by their factor: the u profiled on them is again the whole intensity error.
        if (pu) u[s] = *pu;
      }
      w = plain;  // only the sensors' rows are simulated again
      SensorDepthRows(p, spec, x, u, w);
    }
  }
  size_t count = 0;
  for (size_t s = 0; s < p.sensor_obs.size(); ++s) {
    bool any = false;
    for (size_t i : p.sensor_obs[s]) {
      if (train[i]) {
        ++count;
        any = true;
      }
    }
    if (opt.use_u && any) ++count;
  }
  for (size_t i : p.scan_obs)
    if (train[i]) ++count;
  // The map's profile error: one relative offset per scan and height band, profiled out with its prior.
  std::vector<bool> band_present;
  const std::vector<double> band = ProfiledBandOffsets(p, w, train, opt.raw, band_present);
  count += static_cast<size_t>(std::count(band_present.begin(), band_present.end(), true));
  r.resize(static_cast<Eigen::Index>(count));
  if (u_out) u_out->assign(p.sensor_obs.size(), 0.0);
  Eigen::Index k = 0;
  for (size_t s = 0; s < p.sensor_obs.size(); ++s) {
    const std::optional<double> profiled =
        opt.use_u ? ProfiledU(p, w, s, train, opt.raw, 1.0 / (p.sigma_u[s] * p.sigma_u[s])) : std::nullopt;
    const bool any = profiled.has_value();
    const double u = profiled.value_or(0.0);
    if (u_out) (*u_out)[s] = u;
    for (size_t i : p.sensor_obs[s]) {
      if (!train[i]) continue;
      const Obs& o = p.obs[i];
      const double target = opt.raw ? o.raw : o.wear;
      r[k++] = (Interp(w, o) * (1.0 + u) - target) / o.sigma;
    }
    if (opt.use_u && any) r[k++] = u / p.sigma_u[s];
  }
  for (size_t i : p.scan_obs) {
    if (!train[i]) continue;
    const Obs& o = p.obs[i];
    const double b = band[static_cast<size_t>(BandIndex(p, o))];
    r[k++] = (Interp(w, o) * (1.0 + b) - (opt.raw ? o.raw : o.wear)) / o.sigma;
  }
  for (size_t g = 0; g < band.size(); ++g)
    if (band_present[g]) r[k++] = band[g] / p.band_sd;
}

FitResult Fit(const Problem& p, const ModelSpec& spec, const Mask& train, const EvalOptions& opt,
              const std::vector<Eigen::VectorXd>& starts, int max_iterations, double k_scale) {
  Eigen::VectorXd lower, upper, scale, initial;
  spec.Bounds(lower, upper, scale, initial, k_scale);
  Eigen::MatrixXd w;
  auto fn = [&](const Eigen::VectorXd& x, Eigen::VectorXd& r) { Residuals(p, spec, x, train, opt, r, nullptr, w); };
  FitResult best;
  best.chi2 = std::numeric_limits<double>::max();
  Eigen::MatrixXd jtj;  // the best start's
  for (const Eigen::VectorXd& start : starts) {
    LmResult lm = MinimiseLeastSquares(fn, start, lower, upper, scale, max_iterations);
    if (lm.cost < best.chi2) {
      best.chi2 = lm.cost;
      best.x = lm.x;
      jtj = std::move(lm.jtj);
    }
  }
  if (jtj.size() > 0) {
    for (Eigen::Index d = 0; d < jtj.rows(); ++d) jtj(d, d) += 1e-12;
    best.stderr_x = Stderr(jtj, {});
    // With an effect's shape held at its fitted value; the same when the model has no shape parameter.
    const std::vector<Eigen::Index> keep = NonShapeParams(spec);
    best.stderr_given_shape = keep.size() == static_cast<size_t>(jtj.rows()) ? best.stderr_x : Stderr(jtj, keep);
  }
  best.spec = spec;
  Eigen::VectorXd r;
  Residuals(p, spec, best.x, train, opt, r, &best.u, w);
  best.chi2 = r.squaredNorm();
  best.n_train = 0;
  for (size_t i = 0; i < p.obs.size(); ++i)
    if (train[i]) ++best.n_train;
  return best;
}

TestScore Score(const Problem& p, const FitResult& f, const Mask& test, const Mask& train, bool raw) {
  Eigen::MatrixXd w;
  Simulate(f.spec, f.x, p.points, p.grid, w);
  TestScore s;
  std::vector<bool> seen(p.sensor_obs.size(), false);
  for (size_t k = 0; k < p.sensor_obs.size(); ++k)
    for (size_t i : p.sensor_obs[k])
      if (train[i]) seen[k] = true;
  // Each sensor on its own depth curve (depth-dependent models): the fitted u where the sensor was
  // trained, else the u its held-out events imply (marginalised below), found on the plain curve.
  std::vector<double> u_all(f.u.begin(), f.u.end());
  u_all.resize(p.sensor_obs.size(), 0.0);
  if (DepthDependent(f.spec)) {
    for (size_t k = 0; k < p.sensor_obs.size(); ++k)
      if (!seen[k]) u_all[k] = ProfiledU(p, w, k, test, raw, 1.0 / (p.sigma_u[k] * p.sigma_u[k])).value_or(0.0);
    SensorDepthRows(p, f.spec, f.x, u_all, w);
  }
  for (size_t k = 0; k < p.sensor_obs.size(); ++k) {
    if (seen[k]) continue;
    const std::optional<double> profiled = ProfiledU(p, w, k, test, raw, 1.0 / (p.sigma_u[k] * p.sigma_u[k]));
    if (!profiled) continue;
    const double u = *profiled;
    s.chi2 += u * u / (p.sigma_u[k] * p.sigma_u[k]);
    for (size_t i : p.sensor_obs[k]) {
      if (!test[i]) continue;
      const Obs& o = p.obs[i];
      const double pred = Interp(w, o);
      const double e = pred * (1.0 + u) - (raw ? o.raw : o.wear);
      const double e0 = pred - (raw ? o.raw : o.wear);
      s.chi2 += e * e / (o.sigma * o.sigma);
      s.sq_mm += e0 * e0;
      s.n += 1;
    }
  }
  // The map's profile error at a scan's height band: the offset the band's training cells give (as
  // a trained sensor keeps its u); a band with none has its offset marginalised under its prior like an
  // unseen sensor's u (profiled on its test cells and charged), the mm error with 0 there.
  std::vector<bool> band_trained, band_tested;
  const std::vector<double> band_fit = ProfiledBandOffsets(p, w, train, raw, band_trained);
  const std::vector<double> band_test = ProfiledBandOffsets(p, w, test, raw, band_tested);
  for (size_t g = 0; g < band_fit.size(); ++g)
    if (band_tested[g] && !band_trained[g]) s.chi2 += band_test[g] * band_test[g] / (p.band_sd * p.band_sd);
  for (size_t i = 0; i < p.obs.size(); ++i) {
    if (!test[i]) continue;
    const Obs& o = p.obs[i];
    if (o.sensor >= 0 && !seen[static_cast<size_t>(o.sensor)]) continue;
    double pred = Interp(w, o);
    double e0 = kNaN;
    if (o.sensor >= 0) pred *= 1.0 + f.u[static_cast<size_t>(o.sensor)];
    if (o.scan >= 0) {
      const auto g = static_cast<size_t>(BandIndex(p, o));
      if (!band_trained[g]) e0 = pred - (raw ? o.raw : o.wear);
      pred *= 1.0 + (band_trained[g] ? band_fit[g] : band_test[g]);
    }
    const double e = pred - (raw ? o.raw : o.wear);
    if (std::isnan(e0)) e0 = e;
    s.chi2 += e * e / (o.sigma * o.sigma);
    s.sq_mm += e0 * e0;
    s.n += 1;
  }
  return s;
}

double RayleighToZ(double r) {
  if (!(r > 0)) return 0;
  const double log_p = -0.5 * r * r;  // P(R > r), as a log (tiny for large r)
  if (log_p < -700) return 37.5;      // beyond double precision: far past any threshold
  const double p = std::exp(log_p);
  // z with erfc(z / sqrt 2) = p, by bisection (erfc falls monotonically).
  double lo = 0, hi = 40;
  for (int it = 0; it < 200 && hi - lo > 1e-10; ++it) {
    const double mid = 0.5 * (lo + hi);
    (std::erfc(mid / std::sqrt(2.0)) > p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

bool AtLimit(const FitResult& f, Effect e, std::string* why) {
  const int o = f.spec.Offset(e);
  if (o < 0 || f.x.size() <= o) return false;
  const ParamSpec main = EffectParams(e).front();
  bool at = false;
  double value = f.x[o];
  if (e != Effect::kFeedSegregation) {
    const double span = main.upper - main.lower;
    at = (f.x[o] <= main.lower + 1e-3 * span && main.lower < 0) || f.x[o] >= main.upper - 1e-3 * span;
  } else if (f.x.size() > o + 1) {
    value = std::max(std::fabs(f.x[o]), std::fabs(f.x[o + 1]));
    at = value >= 0.999 * main.upper;
  }
  if (at && why)
    *why =
        Fmt("its size %s = %.3g sits at the limit of its physical range [%.3g, %.3g]: the data want more than this effect "
            "can be",
            main.name.c_str(), value, main.lower, main.upper);
  return at;
}

double Significance(const FitResult& f, Effect e, double dispersion, double map_harmonic1_sd) {
  const int o = f.spec.Offset(e);
  if (o < 0 || f.stderr_given_shape.size() != f.x.size()) return 0;
  // An effect size pinned at the limit of its physical range: the data want something this effect
  // cannot be, so it is not the explanation.
  if (AtLimit(f, e)) return 0;
  const double inflate = std::sqrt(std::max(1.0, dispersion));
  if (e == Effect::kFeedSegregation) {
    // The amplitude against the recordings' noise and the map's own first-harmonic error (a DEM
    // map's load sloshes around the chamber: its cosine and sine parts scatter from one time window
    // to the next far more than independent face noise allows), judged at the one-parameter level.
    const double amp = std::hypot(f.x[o], f.x[o + 1]);
    const double se_fit = std::hypot(f.stderr_given_shape[o], f.stderr_given_shape[o + 1]) / std::sqrt(2.0) * inflate;
    const double se = std::hypot(se_fit, std::max(0.0, map_harmonic1_sd));
    return se > 0 ? RayleighToZ(amp / se) : 0;
  }
  const double se = f.stderr_given_shape[o] * inflate;
  return se > 0 ? std::fabs(f.x[o]) / se : 0;
}

std::vector<Eigen::VectorXd> Starts(const ModelSpec& spec, const Eigen::VectorXd& k, const std::vector<const FitResult*>& seeds,
                                    double k_scale) {
  Eigen::VectorXd lower, upper, scale, initial;
  spec.Bounds(lower, upper, scale, initial, k_scale);
  initial.head(static_cast<Eigen::Index>(spec.rows)) = k;
  std::vector<Eigen::VectorXd> starts;
  // Seed effect parameters from earlier fits of the same effects.
  Eigen::VectorXd seeded = initial;
  for (const FitResult* seed : seeds) {
    for (Effect e : seed->spec.effects) {
      const int from = seed->spec.Offset(e), to = spec.Offset(e);
      if (from < 0 || to < 0) continue;
      const auto n = static_cast<Eigen::Index>(EffectParams(e).size());
      seeded.segment(to, n) = seed->x.segment(from, n);
    }
  }
  starts.push_back(seeded);
  if (seeds.empty()) {
    const int wh = spec.Offset(Effect::kWorkHardening);
    if (wh >= 0) {
      for (double tau : {2.0, 30.0}) {
        Eigen::VectorXd s = seeded;
        s[wh + 1] = std::log(tau);
        starts.push_back(s);
      }
    }
    const int hg = spec.Offset(Effect::kHardnessGradient);
    if (hg >= 0) {
      // Gradual (w = 1) and step-like (a softer layer: w = 0.1), each from a shallow and a deep onset.
      for (double w : {1.0, 0.1}) {
        for (double d0 : {0.02, 0.3, 0.7}) {
          if (w == 1.0 && d0 == 0.3) continue;  // the default start, already in
          Eigen::VectorXd s = seeded;
          s[hg + 1] = d0;
          s[hg + 2] = w;
          starts.push_back(s);
        }
      }
    }
    const int fs = spec.Offset(Effect::kFeedSegregation);
    if (fs >= 0) {
      for (double ang : {0.0, 90.0, 180.0, 270.0}) {
        Eigen::VectorXd s = seeded;
        s[fs] = 0.1 * std::cos(ang * kPi / 180.0);
        s[fs + 1] = 0.1 * std::sin(ang * kPi / 180.0);
        starts.push_back(s);
      }
    }
  }
  return starts;
}

double Correlation(const std::vector<double>& a, const std::vector<double>& b) {
  const size_t n = std::min(a.size(), b.size());
  if (n < 3) return 0;
  double ma = 0, mb = 0;
  for (size_t i = 0; i < n; ++i) {
    ma += a[i];
    mb += b[i];
  }
  ma /= static_cast<double>(n);
  mb /= static_cast<double>(n);
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < n; ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  return (saa > 0 && sbb > 0) ? sab / std::sqrt(saa * sbb) : 0.0;
}

ModelEval Evaluate(const Problem& p, const ModelSpec& spec, const std::vector<const FitResult*>& seeds, const FitResult& null_fit,
                   const std::vector<Fold>& folds, double k_scale) {
  const Mask all(p.obs.size(), true);
  const EvalOptions joint{true, false};
  ModelEval ev;
  ev.full =
      Fit(p, spec, all, joint, Starts(spec, null_fit.x.head(static_cast<Eigen::Index>(p.rows)), seeds, k_scale), 40, k_scale);
  for (const Fold& fold : folds) {
    FitResult ff = Fit(p, spec, fold.train, joint, {ev.full.x}, 15, k_scale);
    const TestScore sc = Score(p, ff, fold.test, fold.train, false);
    ev.ho_chi2 += sc.chi2;
    ev.ho_sq_mm += sc.sq_mm;
    ev.ho_n += sc.n;
    ev.fold_fits.push_back(std::move(ff));
  }
  return ev;
}

}  // namespace lw::diagnosis::detail
