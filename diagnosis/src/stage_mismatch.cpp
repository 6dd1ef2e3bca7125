// Diagnosis stage 4, mismatch test and the benchmarks' oracle (stage_mismatch.hpp).
#include "stage_mismatch.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>
#include <vector>
#include <stdexcept>

#include "levenberg_marquardt.hpp"

namespace lw::diagnosis::detail {
namespace {

// Chi-square of a model split by data kind (sensor events with their per-sensor priors; scan cells).
struct KindChi2 {
  double sensors = 0, scan = 0;
  size_t n_sensors = 0, n_scan = 0;
  double sensors_events_only = 0;
  double u_prior = 0;  ///< sum of u^2 / sigma_u^2 over the sensors
  size_t n_u = 0;
  // Per group (sensor, or scan x sector x half) and type: chi-square and count.
  std::map<std::pair<int, long>, std::pair<double, size_t>> groups;
};

// A scan cell's group: its scan, its sixth of the circumference and its half of the concave height.
long ScanGroup(const Problem& prob, const Obs& o) {
  const ModelPoint& p = prob.points[o.point];
  const double theta = std::atan2(p.sin_t, p.cos_t) + kPi;  // [0, 2 pi]
  const long sector = std::min(5L, static_cast<long>(theta / (2 * kPi / 6)));
  return (static_cast<long>(o.scan) * 6 + sector) * 2 + (p.zn < 0 ? 0 : 1);
}

KindChi2 Chi2ByKind(const Problem& prob, const ModelSpec& spec, const Eigen::VectorXd& x) {
  const Mask all(prob.obs.size(), true);
  const EvalOptions joint{true, false};
  Eigen::VectorXd r;
  Eigen::MatrixXd w;
  std::vector<double> u;
  Residuals(prob, spec, x, all, joint, r, &u, w);
  std::vector<bool> band_present;
  const std::vector<double> band = ProfiledBandOffsets(prob, w, all, false, band_present);
  KindChi2 k;
  for (size_t g = 0; g < band.size(); ++g)
    if (band_present[g]) k.scan += band[g] * band[g] / (prob.band_sd * prob.band_sd);
  for (const Obs& o : prob.obs) {
    double pred = Interp(w, o);
    if (o.sensor >= 0) pred *= 1.0 + u[static_cast<size_t>(o.sensor)];
    if (o.scan >= 0) pred *= 1.0 + band[static_cast<size_t>(BandIndex(prob, o))];
    const double z = (pred - o.wear) / o.sigma;
    auto& g = o.sensor >= 0 ? k.groups[{0, o.sensor}] : k.groups[{2, ScanGroup(prob, o)}];
    g.first += z * z;
    ++g.second;
    if (o.sensor >= 0) {
      k.sensors_events_only += z * z;
      ++k.n_sensors;
    } else {
      k.scan += z * z;
      ++k.n_scan;
    }
  }
  for (size_t s = 0; s < u.size(); ++s) {
    if (prob.sensor_obs[s].empty()) continue;
    const double c = u[s] * u[s] / (prob.sigma_u[s] * prob.sigma_u[s]);
    k.u_prior += c;
    ++k.n_u;
    k.groups[{1, static_cast<long>(s)}] = {c, 1};
  }
  k.sensors = k.sensors_events_only + k.u_prior;
  return k;
}

MismatchCalibration Calibrate(const KindChi2& k) {
  MismatchCalibration cal;
  double excess = 0, variance = 0;
  for (int t = 0; t < 3; ++t) {
    std::vector<std::pair<double, size_t>> g;
    double c_all = 0;
    size_t n_all = 0;
    for (const auto& [key, v] : k.groups)
      if (key.first == t && v.second > 0) {
        g.push_back(v);
        c_all += v.first;
        n_all += v.second;
      }
    const auto n = static_cast<double>(n_all);
    cal.n[t] = n_all;
    cal.groups[t] = g.size();
    if (n_all == 0) continue;
    cal.scale[t] = c_all / n;
    cal.learned[t] = g.size() >= 3 && c_all > 0;
    if (!cal.learned[t]) {
      // Too few groups to hold one out: the modelled noise, its observations independent.
      cal.scale[t] = 1;
      cal.chi2_calibrated[t] = c_all;
      excess += c_all - n;
      variance += 2 * n;
      continue;
    }
    double q_sum = 0;
    std::vector<double> spread;
    for (const auto& [c, m] : g) {
      const double others = (c_all - c) / (n - static_cast<double>(m));
      const double q = c / std::max(others, 1e-12 * cal.scale[t]);
      q_sum += q;
      const double x = q / static_cast<double>(m) - 1;
      spread.push_back(static_cast<double>(m) * x * x / 2);
    }
    // The largest group's spread is left out of b (from 4 groups on): with every group's in it, a
    // mismatch in one sensor widens the noise it is judged against so much that z stays near 1
    // however large the mismatch.
    std::sort(spread.begin(), spread.end());
    if (spread.size() >= 4) spread.pop_back();
    double b = 0;
    for (double v : spread) b += v;
    cal.correlation[t] = std::max(1.0, b / static_cast<double>(spread.size()));
    cal.chi2_calibrated[t] = q_sum;
    excess += q_sum - n;
    variance += 2 * cal.correlation[t] * n;
  }
  cal.z = variance > 0 ? excess / std::sqrt(variance) : 0;
  return cal;
}

}  // namespace

void ApplyLearnedNoise(Problem& prob, const MismatchCalibration& cal) {
  auto factor = [&](int t) { return cal.learned[t] ? std::sqrt(cal.scale[t] * cal.correlation[t]) : 1.0; };
  for (Obs& o : prob.obs) o.sigma *= factor(o.sensor >= 0 ? 0 : 2);
  for (double& s : prob.sigma_u) s *= factor(1);
}

bool RefitUsable(const NullModel& null) {
  return null.fit.x.size() > 0 && null.fit.x.allFinite() &&
         std::all_of(null.fit.u.begin(), null.fit.u.end(), [](double u) { return std::isfinite(u); });
}

NullModel TestMismatch(const Problem& prob, const Baseline& base, const std::vector<Fold>& folds) {
  const EvalOptions joint{true, false};
  NullModel null;
  null.fit = Fit(prob, base.spec, base.all, joint, {base.eq9.x}, 30, base.k_scale);
  Simulate(base.spec, null.fit.x, prob.points, prob.grid, null.w);
  const double dof = std::max(1.0, static_cast<double>(null.fit.n_train) - static_cast<double>(prob.rows));
  null.mismatch_z_modelled = (null.fit.chi2 - dof) / std::sqrt(2.0 * dof);
  null.log_n = std::log(std::max<double>(static_cast<double>(prob.obs.size()), 2.0));
  null.eval = Evaluate(prob, base.spec, {}, null.fit, folds, base.k_scale);
  const KindChi2 k = Chi2ByKind(prob, base.spec, null.fit.x);
  null.parts = {k.sensors_events_only, k.u_prior, k.scan, k.n_sensors, k.n_u, k.n_scan};
  null.calibration = Calibrate(k);
  null.mismatch_z = null.calibration.z;
  return null;
}

std::optional<Effect> ParseOracle(const std::optional<OracleEffect>& oracle) {
  std::optional<Effect> oracle_effect;
  if (!oracle) return oracle_effect;
  // A form's name ("profile_evolution:shift"), or an effect's (its first form: profile_evolution is the tilt).
  for (int e = kEffectCount - 1; e >= 0; --e)
    if (oracle->effect == EffectName(static_cast<Effect>(e))) oracle_effect = static_cast<Effect>(e);
  for (int e = 0; e < kEffectCount; ++e)
    if (oracle->effect == FormName(static_cast<Effect>(e))) oracle_effect = static_cast<Effect>(e);
  if (!oracle_effect) throw std::invalid_argument("oracle: unknown effect '" + oracle->effect + "'");
  for (const ParamSpec& ps : EffectParams(*oracle_effect))
    if (!oracle->parameters.count(ps.name))
      throw std::invalid_argument("oracle: " + oracle->effect + " needs parameter '" + ps.name + "'");
  return oracle_effect;
}

OracleResult MeasureOracle(const Problem& prob, const Baseline& base, const NullModel& null, Effect effect,
                           const OracleEffect& oracle) {
  const Thresholds th;
  const Mask& all = base.all;
  const EvalOptions joint{true, false};
  const double log_n = null.log_n;
  ModelSpec spec = base.spec;
  spec.effects = {effect};
  Eigen::VectorXd lower, upper, scale, initial;
  spec.Bounds(lower, upper, scale, initial, base.k_scale);
  const std::vector<ParamSpec> ps = EffectParams(effect);
  for (size_t k = 0; k < ps.size(); ++k) initial[static_cast<Eigen::Index>(prob.rows + k)] = oracle.parameters.at(ps[k].name);
  const auto rows = static_cast<Eigen::Index>(prob.rows);
  Eigen::MatrixXd w;
  auto fn = [&](const Eigen::VectorXd& k, Eigen::VectorXd& r) {
    Eigen::VectorXd x = initial;
    x.head(rows) = k;
    Residuals(prob, spec, x, all, joint, r, nullptr, w);
  };
  const LmResult lm = MinimiseLeastSquares(fn, null.fit.x.head(rows), lower.head(rows), upper.head(rows), scale.head(rows), 40);
  Eigen::VectorXd x = initial;
  x.head(rows) = lm.x;
  const KindChi2 baseline = Chi2ByKind(prob, base.spec, null.fit.x), truth = Chi2ByKind(prob, spec, x);
  OracleResult o;
  o.model = spec.Name();
  o.effect_params = ps.size();
  o.log_n = log_n;
  o.min_delta_bic = th.min_delta_bic;
  o.chi2_baseline = baseline.sensors + baseline.scan;
  o.chi2_true = truth.sensors + truth.scan;
  o.delta_chi2_sensors = baseline.sensors - truth.sensors;
  o.delta_chi2_scan = baseline.scan - truth.scan;
  o.spread_sensors = truth.n_sensors ? truth.sensors_events_only / static_cast<double>(truth.n_sensors) : 1.0;
  o.spread_sensor_priors = truth.n_u ? truth.u_prior / static_cast<double>(truth.n_u) : 1.0;
  o.spread_scan = truth.n_scan ? truth.scan / static_cast<double>(truth.n_scan) : 1.0;
  const double charge = static_cast<double>(o.effect_params) * log_n;
  o.delta_bic_model = o.delta_chi2_sensors + o.delta_chi2_scan - charge;
  // Each part divided by the spread the true model shows in it (a spread of 0 would make any gain
  // infinite: at least a hundredth).
  o.delta_bic_empirical = (baseline.sensors_events_only - truth.sensors_events_only) / std::max(o.spread_sensors, 0.01) +
                          (baseline.u_prior - truth.u_prior) / std::max(o.spread_sensor_priors, 0.01) +
                          (truth.n_scan ? o.delta_chi2_scan / std::max(o.spread_scan, 0.01) : 0.0) - charge;
  return o;
}

}  // namespace lw::diagnosis::detail
