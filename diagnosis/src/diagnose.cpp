// Orchestration of the diagnosis: data quality, observations, baseline, mismatch test, hypothesis
// fits, ranking, explanation, prediction.
#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <limits>
#include <numeric>
#include <optional>
#include <set>
#include <stdexcept>

#include "diagnosis/diagnose.hpp"
#include "fields.hpp"
#include "levenberg_marquardt.hpp"
#include "report_maps.hpp"
#include "sensor_quality.hpp"
#include "wear_model.hpp"

namespace lw::diagnosis {
namespace {

using detail::Effect;
using detail::ModelPoint;
using detail::ModelSpec;
using detail::PointField;

constexpr double kPi = 3.14159265358979323846;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Decision thresholds (chi-square units). Calibrated on bench/diagnosis null cases.
struct Thresholds {
  double mismatch_z = 4.0;        ///< chi-square excess of the refit baseline, in sigmas, to call a mismatch real
  double min_delta_bic = 10.0;    ///< information-criterion gain over the baseline for a finding
  double min_holdout_gain = 4.0;  ///< held-out chi-square gain over the baseline
  double min_holdout_rel = 0.03;  ///< ... and as a share of the baseline's held-out chi-square
  double pair_delta_bic = 10.0;   ///< gain of a pair over its best single effect
  double min_significance = 2.0;  ///< effect size in standard errors
  double sensor_floor_mm = 0.1;   ///< loop-position tolerance of the ladder
  double scan_floor_mm = 0.2;     ///< scan registration / surface roughness floor
  double model_floor_rel =
      0.02;  ///< relative model error floor: DEM maps carry patchy, correlated error that cell averaging does not remove
  double u_floor_rel = 0.02;  ///< per-sensor intensity error floor (placement, local geometry)
};

__attribute__((format(printf, 1, 2))) std::string Fmt(const char* format, ...) {
  char buffer[512];
  va_list args;
  va_start(args, format);
  std::vsnprintf(buffer, sizeof buffer, format, args);
  va_end(args);
  return buffer;
}

double Round(double v, double digits = 4) {
  const double f = std::pow(10.0, digits);
  return std::round(v * f) / f;
}

struct SensorData {
  size_t config_index = 0;
  std::string id;
  std::string row;
  double z = 0, theta = 0, thickness = 0;
  detail::SensorAnalysis analysis;
  PointField field;
  bool usable = false;
  int usable_index = -1;  ///< index among usable sensors
  double sigma_u = 0;
};

struct Obs {
  size_t point = 0;
  double t = 0;
  double wear = 0;  ///< wear minus material lost before (what the wear model explains)
  double raw = 0;   ///< wear as the sensor/scan saw it
  double sigma = 1;
  int sensor = -1;  ///< usable-sensor index, -1 for scan cells
  int scan = -1;
  int cell = -1;
  size_t j = 0;
  double frac = 0;
};

struct Problem {
  std::vector<ModelPoint> points;
  detail::TimeGrid grid;
  std::vector<Obs> obs;
  std::vector<std::vector<size_t>> sensor_obs;  ///< per usable sensor
  std::vector<size_t> scan_obs;
  std::vector<double> sigma_u;  ///< per usable sensor
  size_t rows = 1;
};

using Mask = std::vector<bool>;

struct FitResult {
  ModelSpec spec;
  Eigen::VectorXd x;
  double chi2 = 0;
  std::vector<double> u;  ///< per usable sensor
  Eigen::VectorXd stderr_x;
  size_t n_train = 0;
};

double Interp(const Eigen::MatrixXd& w, const Obs& o) {
  const auto r = static_cast<Eigen::Index>(o.point);
  const auto j = static_cast<Eigen::Index>(o.j);
  if (j + 1 >= w.cols()) return w(r, w.cols() - 1);
  return w(r, j) * (1.0 - o.frac) + w(r, j + 1) * o.frac;
}

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

struct EvalOptions {
  bool use_u = true;
  bool raw = false;  ///< fit the raw wear (the baseline does not know about material loss)
};

// Whitened residuals over the training observations; per-sensor random intensity error u_s is
// profiled out analytically (prior N(0, sigma_u^2)).
void Residuals(const Problem& p, const ModelSpec& spec, const Eigen::VectorXd& x, const Mask& train, const EvalOptions& opt,
               Eigen::VectorXd& r, std::vector<double>* u_out, Eigen::MatrixXd& w) {
  detail::Simulate(spec, x, p.points, p.grid, w);
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
    r[k++] = (Interp(w, o) - (opt.raw ? o.raw : o.wear)) / o.sigma;
  }
}

FitResult Fit(const Problem& p, const ModelSpec& spec, const Mask& train, const EvalOptions& opt,
              const std::vector<Eigen::VectorXd>& starts, int max_iterations, double k_scale) {
  Eigen::VectorXd lower, upper, scale, initial;
  spec.Bounds(lower, upper, scale, initial, k_scale);
  Eigen::MatrixXd w;
  auto fn = [&](const Eigen::VectorXd& x, Eigen::VectorXd& r) { Residuals(p, spec, x, train, opt, r, nullptr, w); };
  FitResult best;
  best.chi2 = std::numeric_limits<double>::max();
  for (const Eigen::VectorXd& start : starts) {
    detail::LmResult lm = detail::MinimiseLeastSquares(fn, start, lower, upper, scale, max_iterations);
    if (lm.cost < best.chi2) {
      best.chi2 = lm.cost;
      best.x = lm.x;
      Eigen::MatrixXd jtj = lm.jtj;
      for (Eigen::Index d = 0; d < jtj.rows(); ++d) jtj(d, d) += 1e-12;
      const Eigen::MatrixXd cov = jtj.ldlt().solve(Eigen::MatrixXd::Identity(jtj.rows(), jtj.cols()));
      best.stderr_x = cov.diagonal().cwiseAbs().cwiseSqrt();
    }
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

struct TestScore {
  double chi2 = 0;
  double sq_mm = 0;
  size_t n = 0;
};

// Scores a fit on held-out observations. A sensor that had training data keeps its fitted
// intensity error u; a sensor left out entirely has its u marginalised under its prior N(0, sigma_u^2)
// (the predictive chi-square of the noise model: the map's error at an unseen sensor is noise, not
// something a physical effect can be expected to predict). The mm error uses u = 0 there.
TestScore Score(const Problem& p, const FitResult& f, const Mask& test, const Mask& train, bool raw) {
  Eigen::MatrixXd w;
  detail::Simulate(f.spec, f.x, p.points, p.grid, w);
  TestScore s;
  std::vector<bool> seen(p.sensor_obs.size(), false);
  for (size_t k = 0; k < p.sensor_obs.size(); ++k)
    for (size_t i : p.sensor_obs[k])
      if (train[i]) seen[k] = true;
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
  for (size_t i = 0; i < p.obs.size(); ++i) {
    if (!test[i]) continue;
    const Obs& o = p.obs[i];
    if (o.sensor >= 0 && !seen[static_cast<size_t>(o.sensor)]) continue;
    double pred = Interp(w, o);
    if (o.sensor >= 0) pred *= 1.0 + f.u[static_cast<size_t>(o.sensor)];
    const double e = pred - (raw ? o.raw : o.wear);
    s.chi2 += e * e / (o.sigma * o.sigma);
    s.sq_mm += e * e;
    s.n += 1;
  }
  return s;
}

struct Fold {
  std::string name;
  Mask train;
  Mask test;
};

struct ModelEval {
  FitResult full;
  std::vector<FitResult> fold_fits;
  double delta_bic = 0;
  double ho_chi2 = 0;
  double ho_sq_mm = 0;
  size_t ho_n = 0;
  double ho_gain = 0;
  double ho_rel = 0;
  bool accepted = false;
  double score = 0;
  double significance = 0;  ///< smallest |effect size| / standard error over the model's effects
};

// |effect size| / standard error of an effect's main parameter in a fit (feed segregation: the
// amplitude of its cosine). A finding needs its effect size determined by the data, not just a
// better chi-square (two sensors can always be "explained" by a two-parameter angle pattern).
double Significance(const FitResult& f, Effect e, double dispersion) {
  const int o = f.spec.Offset(e);
  if (o < 0 || f.stderr_x.size() != f.x.size()) return 0;
  // An effect size pinned at the limit of its physical range: the data want something this effect
  // cannot be, so it is not the explanation.
  const detail::ParamSpec main = detail::EffectParams(e).front();
  if (e != Effect::kFeedSegregation) {
    const double span = main.upper - main.lower;
    if (f.x[o] <= main.lower + 1e-3 * span && main.lower < 0) return 0;
    if (f.x[o] >= main.upper - 1e-3 * span) return 0;
  } else if (std::max(std::fabs(f.x[o]), std::fabs(f.x[o + 1])) >= 0.999 * main.upper) {
    return 0;
  }
  const double inflate = std::sqrt(std::max(1.0, dispersion));
  if (e == Effect::kFeedSegregation) {
    const double amp = std::hypot(f.x[o], f.x[o + 1]);
    const double se = std::hypot(f.stderr_x[o], f.stderr_x[o + 1]) / std::sqrt(2.0) * inflate;
    return se > 0 ? amp / se : 0;
  }
  const double se = f.stderr_x[o] * inflate;
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
      const auto n = static_cast<Eigen::Index>(detail::EffectParams(e).size());
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
      for (double d0 : {0.02, 0.7}) {
        Eigen::VectorXd s = seeded;
        s[hg + 1] = d0;
        starts.push_back(s);
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

struct Interpolator {
  std::vector<double> centres;  ///< z of anchor rows (sorted)
  std::vector<int> params;      ///< parameter index of each centre
  void Weights(double z, int& a, int& b, double& wa) const {
    if (centres.size() == 1 || z <= centres.front()) {
      a = b = params.front();
      wa = 1;
      return;
    }
    if (z >= centres.back()) {
      a = b = params.back();
      wa = 1;
      return;
    }
    size_t k = 0;
    while (k + 1 < centres.size() && centres[k + 1] < z) ++k;
    const double f = (z - centres[k]) / (centres[k + 1] - centres[k]);
    a = params[k];
    b = params[k + 1];
    wa = 1.0 - f;
  }
};

}  // namespace

DiagnosisResult Diagnose(const core::Bundle& bundle, const DiagnoseOptions& options) {
  const Thresholds th;
  DiagnosisResult result;
  // Benchmarks' oracle: checked before any work.
  std::optional<Effect> oracle_effect;
  if (options.oracle) {
    // A form's name ("profile_evolution:shift"), or an effect's (its first form: profile_evolution is the tilt).
    for (int e = detail::kEffectCount - 1; e >= 0; --e)
      if (options.oracle->effect == detail::EffectName(static_cast<Effect>(e))) oracle_effect = static_cast<Effect>(e);
    for (int e = 0; e < detail::kEffectCount; ++e)
      if (options.oracle->effect == detail::FormName(static_cast<Effect>(e))) oracle_effect = static_cast<Effect>(e);
    if (!oracle_effect) throw std::invalid_argument("oracle: unknown effect '" + options.oracle->effect + "'");
    for (const detail::ParamSpec& ps : detail::EffectParams(*oracle_effect))
      if (!options.oracle->parameters.count(ps.name))
        throw std::invalid_argument("oracle: " + options.oracle->effect + " needs parameter '" + ps.name + "'");
  }
  const core::CrusherConfig& crusher = bundle.crusher;
  result.crusher_id = crusher.crusher_id;
  result.installed_at = crusher.installed_at;
  const core::TimePoint t0 = crusher.installed_at;
  auto to_time = [&](double days) { return core::AddDays(t0, days); };
  auto days = [&](core::TimePoint t) { return core::DaysBetween(t0, t); };

  // --- Map fields -----------------------------------------------------------------------------
  const detail::MapFields fields = detail::ComputeMapFields(bundle);
  result.noise["map_face_relative_noise"] = Round(fields.face_rel_noise);
  if (!fields.has_normal) {
    result.notes.push_back(
        "the map has no normal_stress_average: squeeze_wear skipped; work_hardening fitted as a uniform time "
        "effect (no impact weighting)");
  }

  for (const std::string& w : bundle.map_validation.warnings) result.notes.push_back("map: " + w);
  if (!fields.noise_estimated) {
    result.notes.push_back(Fmt("map has too few faces (%zu) to estimate its own noise: %.0f %% per face assumed",
                               bundle.map.face_count(), 100.0 * fields.face_rel_noise));
  }
  {
    const core::MapModel& m = fields.model;
    result.noise["map_model"] = {{"bandwidth_m", Round(m.bandwidth_m, 4)},
                                 {"bandwidth_arc_m", Round(m.bandwidth_arc_m, 4)},
                                 {"local_linear", m.local_linear},
                                 {"bandwidth_method", m.bandwidth_method},
                                 {"noise_source", m.noise_source},
                                 {"face_relative_noise", Round(m.face_cv, 3)},
                                 {"smoothing_error_relative", Round(m.smoothing_error_rel, 3)},
                                 {"outlier_faces_capped", m.outlier_faces},
                                 {"windows", bundle.map.windows}};
    if (fields.noise_estimated) {
      result.notes.push_back(
          Fmt("map model: per-face noise %.0f %% (%s), smoothed over %.3f m along z (%.3f m around, %s), smoothing error "
              "%.1f %%, %zu outlier faces capped; every intensity (sensors, scan cells, faces) is "
              "the smoothed one with its standard error",
              100.0 * m.face_cv, m.noise_source.c_str(), m.bandwidth_m, m.bandwidth_arc_m, m.bandwidth_method.c_str(),
              100.0 * m.smoothing_error_rel, m.outlier_faces));
    }
  }

  // --- Sensors: data quality and crossing events ---------------------------------------------
  std::vector<SensorData> sensors;
  for (size_t i = 0; i < crusher.sensors.size(); ++i) {
    const core::SensorInfo& info = crusher.sensors[i];
    SensorData s;
    s.config_index = i;
    s.id = info.id;
    s.row = info.row;
    s.z = info.z_m;
    s.theta = info.theta_deg;
    s.thickness = info.thickness_new_mm > 0 ? info.thickness_new_mm : crusher.thickness_new_mm;
    std::vector<detail::RawReading> raw;
    for (const core::Reading& r : bundle.readings)
      if (r.sensor_id == info.id) raw.push_back({days(r.time), r.thickness_mm});
    s.analysis = detail::AnalyseSensor(std::move(raw), s.thickness);
    for (const auto& q : s.analysis.issues)
      result.data_quality.push_back({s.id, q.issue, to_time(q.from_days), to_time(q.to_days), q.detail});
    if (s.analysis.readings.empty()) result.data_quality.push_back({s.id, "no_readings", t0, t0, "the sensor never reported"});
    s.field = detail::FieldAt(bundle.map, fields, s.z, s.theta);
    s.usable = s.analysis.events.size() >= 2 && s.field.intensity > 1e-6;
    s.sigma_u = std::sqrt(s.field.rel_noise * s.field.rel_noise + th.u_floor_rel * th.u_floor_rel);
    sensors.push_back(std::move(s));
  }

  // Rows anchored by at least one usable sensor.
  Interpolator interp;
  std::vector<std::string> anchor_rows;
  {
    std::vector<std::pair<double, std::string>> centres;
    for (const core::Row& row : crusher.rows) {
      bool has = false;
      for (const SensorData& s : sensors)
        if (s.usable && s.row == row.name) has = true;
      if (has) centres.push_back({0.5 * (row.z_min_m + row.z_max_m), row.name});
    }
    std::sort(centres.begin(), centres.end());
    for (size_t k = 0; k < centres.size(); ++k) {
      interp.centres.push_back(centres[k].first);
      interp.params.push_back(static_cast<int>(k));
      anchor_rows.push_back(centres[k].second);
    }
  }
  if (interp.centres.empty()) {
    result.notes.push_back("no usable sensor readings: nothing to diagnose");
    return result;
  }

  // --- Problem: model points and observations --------------------------------------------------
  Problem prob;
  prob.rows = interp.centres.size();
  const double z_mid = 0.5 * (fields.z_bottom + fields.z_top);
  const double height = std::max(fields.z_top - fields.z_bottom, 1e-3);
  auto make_point = [&](const PointField& f, double half_thickness) {
    ModelPoint mp;
    mp.intensity = f.intensity;
    mp.normal_tilde = f.normal_tilde;
    mp.normal_i = f.normal_i;
    mp.zn = (f.z - z_mid) / height;
    mp.shift_rel = detail::ProfileShiftRel(fields, f.z);
    mp.cos_t = std::cos(f.theta_deg * kPi / 180.0);
    mp.sin_t = std::sin(f.theta_deg * kPi / 180.0);
    mp.half_thickness_mm = half_thickness;
    interp.Weights(f.z, mp.row_a, mp.row_b, mp.weight_a);
    return mp;
  };

  // Time extent.
  double t_max = 1.0;
  for (const SensorData& s : sensors)
    if (!s.analysis.readings.empty()) t_max = std::max(t_max, s.analysis.readings.back().t_days);
  for (const core::Scan& scan : bundle.scans) t_max = std::max(t_max, days(scan.date));
  if (options.predict_at) t_max = std::max(t_max, days(*options.predict_at));
  prob.grid.dt = std::max(t_max / 150.0, 0.05);
  prob.grid.steps = static_cast<size_t>(std::ceil(t_max / prob.grid.dt)) + 1;

  // Throughput x abrasiveness per step.
  double t_obs_end = 0;
  for (const SensorData& s : sensors) t_obs_end = std::max(t_obs_end, s.analysis.last_time_days);
  bool throughput_available = false;
  double throughput_cv = 0;
  prob.grid.throughput.assign(prob.grid.steps, 1.0);
  if (!bundle.operations.empty()) {
    double ai_mean = 0;
    size_t ai_n = 0;
    for (const auto& o : bundle.operations)
      if (o.ore_ai) {
        ai_mean += *o.ore_ai;
        ++ai_n;
      }
    if (ai_n) ai_mean /= static_cast<double>(ai_n);
    std::vector<std::pair<double, double>> series;
    for (const auto& o : bundle.operations) {
      const double ai = o.ore_ai ? *o.ore_ai : ai_mean;
      series.push_back({days(o.time), std::max(0.0, o.throughput_tph) * (ai_n ? ai + 0.22 : 1.0)});
    }
    size_t k = 0;
    for (size_t j = 0; j < prob.grid.steps; ++j) {
      const double tm = (static_cast<double>(j) + 0.5) * prob.grid.dt;
      while (k + 1 < series.size() && series[k + 1].first <= tm) ++k;
      prob.grid.throughput[j] = series[k].second;
    }
    double sum = 0, sum2 = 0;
    size_t n = 0;
    for (size_t j = 0; j < prob.grid.steps; ++j) {
      if ((static_cast<double>(j) + 0.5) * prob.grid.dt > std::max(t_obs_end, 1.0)) break;
      sum += prob.grid.throughput[j];
      sum2 += prob.grid.throughput[j] * prob.grid.throughput[j];
      ++n;
    }
    const double mean = n ? sum / static_cast<double>(n) : 0;
    if (mean > 0) {
      for (double& q : prob.grid.throughput) q /= mean;
      throughput_cv = std::sqrt(std::max(0.0, sum2 / static_cast<double>(n) - mean * mean)) / mean;
      throughput_available = throughput_cv > 0.03;
    }
    if (!throughput_available) {
      for (double& q : prob.grid.throughput) q = 1.0;
      result.notes.push_back(
          Fmt("operations.csv shows almost constant throughput (variation %.1f %%): "
              "throughput_variation not identifiable, skipped",
              100.0 * throughput_cv));
    }
  } else {
    result.notes.push_back("no operations.csv: throughput_variation skipped");
  }

  auto add_obs = [&](Obs o) {
    const double x = std::clamp(o.t / prob.grid.dt, 0.0, static_cast<double>(prob.grid.steps));
    o.j = static_cast<size_t>(std::floor(x));
    o.frac = x - static_cast<double>(o.j);
    prob.obs.push_back(o);
    return prob.obs.size() - 1;
  };

  int usable_count = 0;
  for (SensorData& s : sensors) {
    if (!s.usable) continue;
    s.usable_index = usable_count++;
    const size_t point = prob.points.size();
    prob.points.push_back(make_point(s.field, 0.5 * s.thickness));
    prob.sensor_obs.emplace_back();
    prob.sigma_u.push_back(s.sigma_u);
    const double rho = s.analysis.rate_mm_per_day;
    for (const auto& e : s.analysis.events) {
      Obs o;
      o.point = point;
      o.t = e.t_days;
      o.raw = e.wear_mm;
      o.wear = e.wear_mm - e.offset_mm;
      const double st = rho * e.sigma_t_days;
      o.sigma = std::sqrt(st * st + th.sensor_floor_mm * th.sensor_floor_mm + std::pow(th.model_floor_rel * o.wear, 2));
      o.sensor = s.usable_index;
      prob.sensor_obs.back().push_back(add_obs(o));
    }
  }
  // The events' scatter beyond their modelled noise (the time inside the report interval, the loop
  // position, the relative model floor), measured from the events themselves: each interior event
  // against the straight line through its two neighbours (a smooth change of the wear rate, slower
  // than the events' spacing, cancels; noise does not), the excess variance (trimmed mean, top 2 %
  // dropped: a step left over) added to every event. The relative floor stays: it stands for the
  // smooth deviations of a real wear rate from any model in time, which this cannot see (without
  // it, an independent generator's nulls gave work_hardening findings).
  {
    std::vector<double> excess;
    for (const auto& list : prob.sensor_obs)
      for (size_t k = 1; k + 1 < list.size(); ++k) {
        const Obs &a = prob.obs[list[k - 1]], &b = prob.obs[list[k]], &c = prob.obs[list[k + 1]];
        if (!(c.t > a.t)) continue;
        const double f = std::clamp((b.t - a.t) / (c.t - a.t), 0.0, 1.0);
        const double d = b.wear - (a.wear + f * (c.wear - a.wear));
        const double expected = b.sigma * b.sigma + (1 - f) * (1 - f) * a.sigma * a.sigma + f * f * c.sigma * c.sigma;
        excess.push_back((d * d - expected) / (1.0 + (1 - f) * (1 - f) + f * f));
      }
    double x = 0;
    if (excess.size() >= 10) {
      std::sort(excess.begin(), excess.end());
      const size_t keep = excess.size() - excess.size() / 50;
      for (size_t k = 0; k < keep; ++k) x += excess[k];
      x = std::max(0.0, x / static_cast<double>(keep));
    }
    result.noise["sensor_event_excess_sd_mm"] = Round(std::sqrt(x), 3);
    for (const auto& list : prob.sensor_obs)
      for (size_t i : list) prob.obs[i].sigma = std::sqrt(prob.obs[i].sigma * prob.obs[i].sigma + x);
  }

  // Scans.
  const detail::CellGrid grid = detail::BuildCellGrid(bundle.map, fields, 240);
  std::vector<detail::ScanCells> scans;
  for (const core::Scan& scan : bundle.scans) {
    detail::ScanCells sc = detail::ProjectScan(bundle.map, fields, grid, scan, days(scan.date), crusher.thickness_new_mm);
    result.noise["scan_point_noise_mm:" + scan.file] = Round(sc.point_noise_mm, 3);
    if (sc.points_used < sc.points_total / 2) {
      result.notes.push_back("scan " + scan.file + ": only " + std::to_string(sc.points_used) + " of " +
                             std::to_string(sc.points_total) + " points lie on the mapped surface");
    }
    const int scan_index = static_cast<int>(scans.size());
    for (size_t c = 0; c < grid.cells.size(); ++c) {
      if (!std::isfinite(sc.wear_mm[c]) || sc.points[c] < 3 || sc.fields[c].intensity <= 0) continue;
      const size_t point = prob.points.size();
      prob.points.push_back(make_point(sc.fields[c], 0.5 * crusher.thickness_new_mm));
      Obs o;
      o.point = point;
      o.t = sc.t_days;
      o.raw = o.wear = sc.wear_mm[c];
      o.sigma = 0;  // set once a baseline prediction exists
      o.scan = scan_index;
      o.cell = static_cast<int>(c);
      prob.scan_obs.push_back(add_obs(o));
    }
    scans.push_back(std::move(sc));
  }

  // --- Baseline: Eq. 9 row scales, wear linear in time, fitted to the sensors only ----------------
  const size_t n_obs = prob.obs.size();
  Mask all(n_obs, true), sensors_only(n_obs, false);
  for (const auto& list : prob.sensor_obs)
    for (size_t i : list) sensors_only[i] = true;
  double k_scale = 0;
  {
    std::vector<double> ks;
    for (const Obs& o : prob.obs)
      if (o.sensor >= 0 && o.t > 0 && prob.points[o.point].intensity > 0)
        ks.push_back(o.raw / (prob.points[o.point].intensity * o.t));
    std::sort(ks.begin(), ks.end());
    k_scale = ks.empty() ? 1.0 : ks[ks.size() / 2];
    if (!(k_scale > 0)) k_scale = 1.0;
  }
  ModelSpec base_spec;
  base_spec.rows = prob.rows;
  Eigen::VectorXd k_init = Eigen::VectorXd::Constant(static_cast<Eigen::Index>(prob.rows), k_scale);
  const EvalOptions eq9_opt{false, true};
  const FitResult eq9 = Fit(prob, base_spec, sensors_only, eq9_opt, {k_init}, 30, k_scale);

  // Scan-cell noise: points + map noise on the predicted wear + floors. The smoothed map's error is
  // correlated over the kernel (about (2 h)^2 pi): cells closer than that share it and are not
  // independent evidence, so the map-noise term counts once per correlation area, not per cell.
  double corr_cells = 1.0;
  {
    const double cell_area = grid.dz * grid.dt_deg * kPi / 180.0 * fields.mean_radius_m;
    const double h = fields.model.bandwidth_m, ha = fields.model.bandwidth_arc_m;
    if (cell_area > 0 && h > 0) corr_cells = std::max(1.0, kPi * 4.0 * h * std::max(h, ha) / cell_area);
    result.noise["scan_cells_per_map_error_area"] = Round(corr_cells, 2);
  }
  // The map's pattern error, measured: the smoothed map differs from the liner's wear beyond its
  // sampling noise (the smoothing's own bias, where real DEM maps change faster than any scale
  // follows; the DEM's physics; the chamber). Its relative size map_tau is what the observations'
  // differences from the baseline (Eq. 9 fitted to the sensors) hold beyond the map's sampling noise
  // and the measurements' own: from the scan's cells when there is a scan (dense ground truth),
  // else from the sensors' spread around their rows' scales; and the map's cross-validated
  // smoothing error (the map alone cannot tell its pattern error from its structure finer than the
  // smoothing: on real DEM maps that estimate ranged 0.14-1.0 where scans measured 0.11-0.23).
  double map_tau = fields.model.smoothing_error_rel;
  std::string tau_source = "map cross-validation";
  {
    Eigen::MatrixXd w;
    detail::Simulate(base_spec, eq9.x, prob.points, prob.grid, w);
    auto trimmed_mean = [](std::vector<double> v) {
      std::sort(v.begin(), v.end());
      const size_t keep = v.size() - v.size() / 50;
      double sum = 0;
      for (size_t k = 0; k < keep; ++k) sum += v[k];
      return keep ? sum / static_cast<double>(keep) : 0.0;
    };
    std::vector<double> scan_excess;
    for (size_t i : prob.scan_obs) {
      const Obs& o = prob.obs[i];
      const detail::ScanCells& sc = scans[static_cast<size_t>(o.scan)];
      const double pred = Interp(w, o);
      const double sd = sc.sigma_mm[static_cast<size_t>(o.cell)];
      if (!(pred > 2.0 * sd + th.scan_floor_mm)) continue;  // wear too small to measure a relative error
      const double rs = sc.fields[static_cast<size_t>(o.cell)].rel_sampling;
      scan_excess.push_back(std::pow((o.wear - pred) / pred, 2) - std::pow(sd / pred, 2) - rs * rs);
    }
    // Sensors: each one's latest event (the most wear: the least relative quantisation), against
    // its row's fitted scale; the fitted scales take one degree of freedom per row.
    std::vector<double> sensor_excess;
    std::set<size_t> sensor_rows;
    for (const SensorData& sd : sensors) {
      if (!sd.usable) continue;
      const auto& list = prob.sensor_obs[static_cast<size_t>(sd.usable_index)];
      if (list.empty()) continue;
      const Obs& o = prob.obs[list.back()];
      const double pred = Interp(w, o);
      if (!(pred > 2.0 * o.sigma)) continue;
      const double rs = sd.field.rel_sampling;
      sensor_excess.push_back(std::pow(o.raw / pred - 1.0, 2) - std::pow(o.sigma / pred, 2) - rs * rs);
      sensor_rows.insert(static_cast<size_t>(std::find(anchor_rows.begin(), anchor_rows.end(), sd.row) - anchor_rows.begin()));
    }
    // Each estimate is the pattern error plus something else (the map's own structure finer than
    // any smoothing follows; a concealed effect): both are upper bounds, the smaller is used.
    double measured = kNaN;
    std::string measured_source;
    if (scan_excess.size() >= 20) {
      measured = std::sqrt(std::max(0.0, trimmed_mean(scan_excess)));
      measured_source = "scan";
    } else if (sensor_excess.size() >= sensor_rows.size() + 3) {
      double sum = 0;
      for (double e : sensor_excess) sum += e;
      measured = std::sqrt(std::max(0.0, sum / static_cast<double>(sensor_excess.size() - sensor_rows.size())));
      measured_source = "sensors";
    }
    if (std::isfinite(measured) && measured < map_tau) {
      map_tau = measured;
      tau_source = measured_source;
    }
    result.noise["map_pattern_error_relative"] = Round(map_tau, 3);
    result.noise["map_pattern_error_source"] = tau_source;
    // Each sensor's intensity error: the map's sampling noise at it and the pattern error.
    for (const SensorData& sd : sensors)
      if (sd.usable)
        prob.sigma_u[static_cast<size_t>(sd.usable_index)] =
            std::sqrt(sd.field.rel_sampling * sd.field.rel_sampling + map_tau * map_tau + th.u_floor_rel * th.u_floor_rel);
    // How many scan cells share one error: the map's error is correlated over the kernel (at most
    // the kernel's support, corr_cells above), the pattern error over whatever scale it has. From
    // the scan's own residuals: b cells averaged have b times the variance of one cell's mean when
    // they share their error, 1 time when independent. The largest ratio over block sizes (rows x
    // columns of cells), bounded by the kernel's support; a concealed effect's pattern is broad and
    // raises it (cautious).
    if (!prob.scan_obs.empty()) {
      double corr_data = 1.0;
      for (size_t k = 0; k < scans.size(); ++k) {
        std::vector<double> zres(grid.cells.size(), kNaN);
        double v1 = 0;
        size_t n1 = 0;
        for (size_t i : prob.scan_obs) {
          const Obs& o = prob.obs[i];
          if (static_cast<size_t>(o.scan) != k) continue;
          const double pred = std::max(Interp(w, o), 0.0);
          const double rel = std::hypot(scans[k].fields[static_cast<size_t>(o.cell)].rel_sampling, map_tau);
          const double sd = std::sqrt(std::pow(scans[k].sigma_mm[static_cast<size_t>(o.cell)], 2) + std::pow(rel * pred, 2) +
                                      th.scan_floor_mm * th.scan_floor_mm);
          const double zr = (o.wear - pred) / sd;
          zres[static_cast<size_t>(o.cell)] = zr;
          v1 += zr * zr;
          ++n1;
        }
        if (n1 < 20) continue;
        v1 /= static_cast<double>(n1);
        for (size_t bz = 1; bz <= std::max<size_t>(1, grid.nz / 2); bz *= 2)
          for (size_t bt = 1; bt <= std::max<size_t>(1, grid.nt / 4); bt *= 2) {
            if (bz * bt < 2) continue;
            double sum = 0;
            size_t blocks = 0;
            for (size_t bz0 = 0; bz0 + bz <= grid.nz; bz0 += bz)
              for (size_t bt0 = 0; bt0 + bt <= grid.nt; bt0 += bt) {
                double m = 0;
                size_t c = 0;
                for (size_t iz = bz0; iz < bz0 + bz; ++iz)
                  for (size_t it = bt0; it < bt0 + bt; ++it)
                    if (std::isfinite(zres[iz * grid.nt + it])) {
                      m += zres[iz * grid.nt + it];
                      ++c;
                    }
                if (2 * c < bz * bt) continue;
                sum += m * m / static_cast<double>(c);
                ++blocks;
              }
            if (blocks >= 4 && v1 > 0) corr_data = std::max(corr_data, sum / static_cast<double>(blocks) / v1);
          }
      }
      result.noise["scan_cells_per_map_error_area_kernel"] = Round(corr_cells, 2);
      corr_cells = std::min(corr_cells, corr_data);
      result.noise["scan_cells_per_map_error_area"] = Round(corr_cells, 2);
    }
    for (size_t i : prob.scan_obs) {
      Obs& o = prob.obs[i];
      const detail::ScanCells& sc = scans[static_cast<size_t>(o.scan)];
      const double pred = std::max(Interp(w, o), 0.0);
      const double rel = std::hypot(sc.fields[static_cast<size_t>(o.cell)].rel_sampling, map_tau);
      o.sigma = std::sqrt(std::pow(sc.sigma_mm[static_cast<size_t>(o.cell)], 2) + corr_cells * std::pow(rel * pred, 2) +
                          th.scan_floor_mm * th.scan_floor_mm + std::pow(th.model_floor_rel * pred, 2));
    }
  }

  // --- Holdout folds ----------------------------------------------------------------------------
  std::vector<Fold> folds;
  {
    double lo = std::numeric_limits<double>::max(), hi = 0;
    for (const Obs& o : prob.obs)
      if (o.sensor >= 0) {
        lo = std::min(lo, o.t);
        hi = std::max(hi, o.t);
      }
    const double cut = lo + (1.0 - options.holdout_fraction) * (hi - lo);
    Fold time{"later_readings", Mask(n_obs, false), Mask(n_obs, false)};
    size_t n_test = 0;
    // Later sensor readings are held out; scans stay in training (a scan is a spatial snapshot, tested
    // by the scan-sector fold; without it a spatial effect could not be identified in this fold).
    for (size_t i = 0; i < n_obs; ++i) {
      const bool later = prob.obs[i].sensor >= 0 && prob.obs[i].t > cut;
      (later ? time.test : time.train)[i] = true;
      if (later) ++n_test;
    }
    if (n_test >= 3) folds.push_back(std::move(time));

    Fold loso{"left_out_sensors", all, Mask(n_obs, false)};
    size_t left = 0;
    for (const std::string& row : anchor_rows) {
      std::vector<const SensorData*> in_row;
      for (const SensorData& s : sensors)
        if (s.usable && s.row == row) in_row.push_back(&s);
      if (in_row.size() < 2) continue;
      for (size_t k = 1; k < in_row.size(); k += 2) {
        for (size_t i : prob.sensor_obs[static_cast<size_t>(in_row[k]->usable_index)]) {
          loso.train[i] = false;
          loso.test[i] = true;
        }
        ++left;
      }
    }
    if (left > 0) folds.push_back(std::move(loso));

    if (!prob.scan_obs.empty()) {
      Fold sectors{"scan_sectors", all, Mask(n_obs, false)};
      const size_t per = std::max<size_t>(1, grid.nt / 6);
      for (size_t i : prob.scan_obs) {
        const size_t it = static_cast<size_t>(prob.obs[i].cell) % grid.nt;
        const size_t iz = static_cast<size_t>(prob.obs[i].cell) / grid.nt;
        if (((it / per) + (iz * 2 / std::max<size_t>(grid.nz, 1))) % 2 == 1) {
          sectors.train[i] = false;
          sectors.test[i] = true;
        }
      }
      folds.push_back(std::move(sectors));
    }
  }

  // --- Null (baseline refit on all data, with the noise model) and the mismatch test -------------
  const EvalOptions joint{true, false};
  const FitResult null_fit = Fit(prob, base_spec, all, joint, {eq9.x}, 30, k_scale);
  Eigen::MatrixXd w_null_fit;
  detail::Simulate(base_spec, null_fit.x, prob.points, prob.grid, w_null_fit);
  const double dof = std::max(1.0, static_cast<double>(null_fit.n_train) - static_cast<double>(prob.rows));
  result.mismatch_z_score = (null_fit.chi2 - dof) / std::sqrt(2.0 * dof);
  const double log_n = std::log(std::max<double>(static_cast<double>(n_obs), 2.0));

  // Chi-square of a model split by data kind (sensor events with their per-sensor priors; scan cells).
  struct KindChi2 {
    double sensors = 0, scan = 0;
    size_t n_sensors = 0, n_scan = 0;
    double sensors_events_only = 0;
    double u_prior = 0;  ///< sum of u^2 / sigma_u^2 over the sensors
    size_t n_u = 0;
  };
  auto chi2_by_kind = [&](const ModelSpec& spec, const Eigen::VectorXd& x) {
    Eigen::VectorXd r;
    Eigen::MatrixXd w;
    std::vector<double> u;
    Residuals(prob, spec, x, all, joint, r, &u, w);
    KindChi2 k;
    for (const Obs& o : prob.obs) {
      double pred = Interp(w, o);
      if (o.sensor >= 0) pred *= 1.0 + u[static_cast<size_t>(o.sensor)];
      const double z = (pred - o.wear) / o.sigma;
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
      k.u_prior += u[s] * u[s] / (prob.sigma_u[s] * prob.sigma_u[s]);
      ++k.n_u;
    }
    k.sensors = k.sensors_events_only + k.u_prior;
    return k;
  };

  // Benchmarks: the true effect with its true parameters, only the row scales fitted.
  if (oracle_effect) {
    ModelSpec spec = base_spec;
    spec.effects = {*oracle_effect};
    Eigen::VectorXd lower, upper, scale, initial;
    spec.Bounds(lower, upper, scale, initial, k_scale);
    const std::vector<detail::ParamSpec> ps = detail::EffectParams(*oracle_effect);
    for (size_t k = 0; k < ps.size(); ++k)
      initial[static_cast<Eigen::Index>(prob.rows + k)] = options.oracle->parameters.at(ps[k].name);
    const auto rows = static_cast<Eigen::Index>(prob.rows);
    Eigen::MatrixXd w;
    auto fn = [&](const Eigen::VectorXd& k, Eigen::VectorXd& r) {
      Eigen::VectorXd x = initial;
      x.head(rows) = k;
      Residuals(prob, spec, x, all, joint, r, nullptr, w);
    };
    const detail::LmResult lm =
        detail::MinimiseLeastSquares(fn, null_fit.x.head(rows), lower.head(rows), upper.head(rows), scale.head(rows), 40);
    Eigen::VectorXd x = initial;
    x.head(rows) = lm.x;
    const KindChi2 base = chi2_by_kind(base_spec, null_fit.x), truth = chi2_by_kind(spec, x);
    OracleResult o;
    o.model = spec.Name();
    o.effect_params = ps.size();
    o.log_n = log_n;
    o.min_delta_bic = th.min_delta_bic;
    o.chi2_baseline = base.sensors + base.scan;
    o.chi2_true = truth.sensors + truth.scan;
    o.delta_chi2_sensors = base.sensors - truth.sensors;
    o.delta_chi2_scan = base.scan - truth.scan;
    o.spread_sensors = truth.n_sensors ? truth.sensors_events_only / static_cast<double>(truth.n_sensors) : 1.0;
    o.spread_sensor_priors = truth.n_u ? truth.u_prior / static_cast<double>(truth.n_u) : 1.0;
    o.spread_scan = truth.n_scan ? truth.scan / static_cast<double>(truth.n_scan) : 1.0;
    const double charge = static_cast<double>(o.effect_params) * log_n;
    o.delta_bic_model = o.delta_chi2_sensors + o.delta_chi2_scan - charge;
    // Each part divided by the spread the true model shows in it (a spread of 0 would make any gain
    // infinite: at least a hundredth).
    o.delta_bic_empirical = (base.sensors_events_only - truth.sensors_events_only) / std::max(o.spread_sensors, 0.01) +
                            (base.u_prior - truth.u_prior) / std::max(o.spread_sensor_priors, 0.01) +
                            (truth.n_scan ? o.delta_chi2_scan / std::max(o.spread_scan, 0.01) : 0.0) - charge;
    result.oracle = o;
  }

  auto evaluate = [&](const ModelSpec& spec, const std::vector<const FitResult*>& seeds) {
    ModelEval ev;
    ev.full = Fit(prob, spec, all, joint, Starts(spec, null_fit.x.head(static_cast<Eigen::Index>(prob.rows)), seeds, k_scale), 40,
                  k_scale);
    for (const Fold& fold : folds) {
      FitResult ff = Fit(prob, spec, fold.train, joint, {ev.full.x}, 15, k_scale);
      const TestScore sc = Score(prob, ff, fold.test, fold.train, false);
      ev.ho_chi2 += sc.chi2;
      ev.ho_sq_mm += sc.sq_mm;
      ev.ho_n += sc.n;
      ev.fold_fits.push_back(std::move(ff));
    }
    return ev;
  };
  ModelEval null_eval = evaluate(base_spec, {});

  // Baseline (Eq. 9, sensors only) metrics, in mm.
  {
    Eigen::MatrixXd w;
    detail::Simulate(base_spec, eq9.x, prob.points, prob.grid, w);
    double sq = 0, mx = 0;
    for (const Obs& o : prob.obs) {
      const double e = Interp(w, o) - o.raw;
      sq += e * e;
      mx = std::max(mx, std::fabs(e));
    }
    result.baseline.rmse_mm = n_obs ? std::sqrt(sq / static_cast<double>(n_obs)) : 0;
    result.baseline.max_abs_mm = mx;
    result.baseline.observations = n_obs;
    double ho_sq = 0;
    size_t ho_n = 0;
    for (const Fold& fold : folds) {
      Mask train(n_obs, false);
      for (size_t i = 0; i < n_obs; ++i) train[i] = fold.train[i] && sensors_only[i];
      const FitResult ff = Fit(prob, base_spec, train, eq9_opt, {eq9.x}, 15, k_scale);
      const TestScore sc = Score(prob, ff, fold.test, train, true);
      ho_sq += sc.sq_mm;
      ho_n += sc.n;
    }
    result.baseline.holdout_rmse_mm = ho_n ? std::sqrt(ho_sq / static_cast<double>(ho_n)) : 0;
    result.baseline.holdout_observations = ho_n;
  }

  // --- Hypotheses ---------------------------------------------------------------------------------
  std::vector<Effect> available;
  for (int e = 0; e < detail::kEffectCount; ++e) {
    const auto effect = static_cast<Effect>(e);
    if (effect == Effect::kSqueezeWear && !fields.has_normal) continue;
    if (effect == Effect::kThroughputVariation && !throughput_available) continue;
    available.push_back(effect);
  }
  std::vector<ModelEval> evals;
  // Over-dispersion (quasi-likelihood): when even the best model leaves chi2/dof > 1, the noise model
  // is too optimistic for this data, and every chi-square gain is divided by that factor.
  double dispersion = 1.0;
  auto judge = [&](ModelEval& ev) {
    const double p_extra = static_cast<double>(ev.full.spec.ParamCount() - prob.rows);
    ev.delta_bic = (null_eval.full.chi2 - ev.full.chi2) / dispersion - p_extra * log_n;
    ev.ho_gain = (null_eval.ho_chi2 - ev.ho_chi2) / dispersion;
    ev.ho_rel = null_eval.ho_chi2 > 0 ? ev.ho_gain / null_eval.ho_chi2 : 0;
    ev.significance = std::numeric_limits<double>::max();
    for (Effect e : ev.full.spec.effects) ev.significance = std::min(ev.significance, Significance(ev.full, e, dispersion));
    ev.accepted = ev.delta_bic > th.min_delta_bic && ev.ho_gain > th.min_holdout_gain && ev.ho_rel > th.min_holdout_rel &&
                  ev.significance > th.min_significance;
    ev.score = ev.delta_bic + ev.ho_gain;
  };
  for (Effect e : available) {
    ModelSpec spec = base_spec;
    spec.effects = {e};
    ModelEval ev = evaluate(spec, {});
    judge(ev);
    evals.push_back(std::move(ev));
  }
  std::vector<size_t> order(evals.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return evals[a].score > evals[b].score; });

  // Pairs among the most promising single effects.
  const size_t singles = evals.size();
  std::vector<std::pair<size_t, size_t>> pair_parts;
  if (options.try_pairs) {
    std::vector<size_t> top;
    for (size_t k : order) {
      bool same_effect = false;  // the weaker form of an effect already in the list
      for (size_t t : top)
        if (std::string(detail::EffectName(evals[t].full.spec.effects[0])) == detail::EffectName(evals[k].full.spec.effects[0]))
          same_effect = true;
      if (evals[k].delta_bic > 0 && top.size() < 3 && !same_effect) top.push_back(k);
    }
    for (size_t a = 0; a < top.size(); ++a) {
      for (size_t b = a + 1; b < top.size(); ++b) {
        // Two forms of the same effect are alternatives, not a pair.
        if (std::string(detail::EffectName(evals[top[a]].full.spec.effects[0])) ==
            detail::EffectName(evals[top[b]].full.spec.effects[0]))
          continue;
        ModelSpec spec = base_spec;
        spec.effects = {evals[top[a]].full.spec.effects[0], evals[top[b]].full.spec.effects[0]};
        ModelEval ev = evaluate(spec, {&evals[top[a]].full, &evals[top[b]].full});
        judge(ev);
        pair_parts.push_back({top[a], top[b]});
        evals.push_back(std::move(ev));
      }
    }
  }
  {
    double best_reduced =
        null_eval.full.chi2 / std::max(1.0, static_cast<double>(null_eval.full.n_train) - static_cast<double>(prob.rows));
    for (const ModelEval& ev : evals) {
      const double dof_m = std::max(1.0, static_cast<double>(ev.full.n_train) - static_cast<double>(ev.full.spec.ParamCount()));
      best_reduced = std::min(best_reduced, ev.full.chi2 / dof_m);
    }
    dispersion = std::max(1.0, best_reduced);
    result.noise["dispersion"] = Round(dispersion, 3);
    for (ModelEval& ev : evals) judge(ev);
    // A pair must beat both of its single effects on both criteria.
    for (size_t k = singles; k < evals.size(); ++k) {
      ModelEval& ev = evals[k];
      for (size_t part : {pair_parts[k - singles].first, pair_parts[k - singles].second}) {
        const double gain = (evals[part].full.chi2 - ev.full.chi2) / dispersion -
                            static_cast<double>(ev.full.spec.ParamCount() - evals[part].full.spec.ParamCount()) * log_n;
        if (gain < th.pair_delta_bic || ev.ho_chi2 > evals[part].ho_chi2) ev.accepted = false;
      }
      // Parsimony: a pair that predicts held-out data worse than an accepted single effect is not
      // preferred to it (two effects can mimic a third one in-sample: hardening + squeeze wear
      // together look like a moving profile).
      for (size_t m = 0; m < singles; ++m)
        if (evals[m].accepted && ev.ho_chi2 > evals[m].ho_chi2) ev.accepted = false;
    }
  }

  // Best accepted model: a pair when accepted, else the best single.
  int best = -1;
  for (size_t k = 0; k < evals.size(); ++k) {
    if (!evals[k].accepted) continue;
    if (best < 0 || evals[k].score > evals[static_cast<size_t>(best)].score) best = static_cast<int>(k);
  }
  const ModelEval* chosen = best >= 0 ? &evals[static_cast<size_t>(best)] : nullptr;
  const FitResult& improved_fit = chosen ? chosen->full : null_fit;

  // Evidence shared by the explanations: how the baseline residual relates to the fields.
  std::vector<double> res_null, f_normal, f_depth, f_cos, f_time;
  {
    Eigen::MatrixXd w;
    detail::Simulate(base_spec, null_fit.x, prob.points, prob.grid, w);
    for (const Obs& o : prob.obs) {
      double pred = Interp(w, o);
      if (o.sensor >= 0) pred *= 1.0 + null_fit.u[static_cast<size_t>(o.sensor)];
      if (pred <= 0.5) continue;
      res_null.push_back((pred - o.wear) / pred);
      f_normal.push_back(prob.points[o.point].normal_tilde);
      f_depth.push_back(o.wear);
      f_cos.push_back(prob.points[o.point].cos_t);
      f_time.push_back(o.t);
    }
  }
  const double corr_normal = Correlation(res_null, f_normal);
  const double corr_depth = Correlation(res_null, f_depth);

  // --- Findings --------------------------------------------------------------------------------
  auto param = [&](const FitResult& f, Effect e, size_t k) { return f.x[f.spec.Offset(e) + static_cast<Eigen::Index>(k)]; };
  auto param_se = [&](const FitResult& f, Effect e, size_t k) {
    return f.stderr_x[f.spec.Offset(e) + static_cast<Eigen::Index>(k)];
  };
  double span_days = 0;
  for (const Obs& o : prob.obs) span_days = std::max(span_days, o.t);
  auto describe = [&](const FitResult& f, Effect e, Finding& out) {
    switch (e) {
      case Effect::kWorkHardening: {
        const double h = param(f, e, 0), tau = std::exp(param(f, e, 1));
        out.parameters["h"] = Round(h, 3);
        out.parameters["h_stderr"] = Round(param_se(f, e, 0), 3);
        out.parameters["tau_days"] = Round(tau, 2);
        out.parameters["tau_days_stderr"] = Round(tau * param_se(f, e, 1), 2);
        out.parameters["saturation_days"] = Round(3.0 * tau, 1);
        out.parameters["weighted_by"] = fields.has_normal ? "normal_stress_average" : "uniform (map has no normal stress)";
        out.explanation = std::string("The liner wore less than the DEM predicts as the campaign went on") +
                          (fields.has_normal ? " where normal stress (impact) is high" : "") +
                          Fmt(": the wear rate fell by %.0f %% where impact is strongest, saturating in about %.0f "
                              "days (time constant %.1f days), as impact hardening of manganese steel does "
                              "(wear ~ 1/hardness).",
                              100.0 * h, 3.0 * tau, tau);
        if (fields.has_normal) {
          out.explanation += Fmt(" The baseline residual follows normal stress (correlation %.2f) ", corr_normal) +
                             (std::fabs(corr_normal) >= std::fabs(corr_depth) ? "more than" : "less than") +
                             Fmt(" worn depth (%.2f).", corr_depth);
        }
        break;
      }
      case Effect::kHardnessGradient: {
        const double g = param(f, e, 0), d0 = param(f, e, 1);
        const double half = 0.5 * crusher.thickness_new_mm;
        out.parameters["g"] = Round(g, 3);
        out.parameters["g_stderr"] = Round(param_se(f, e, 0), 3);
        out.parameters["onset_depth_mm"] = Round(d0 * half, 1);
        out.parameters["onset_depth_mm_stderr"] = Round(param_se(f, e, 1) * half, 1);
        out.parameters["full_depth_mm"] = Round(std::max(half, d0 * half + 3.0), 1);
        out.explanation =
            Fmt("Wear accelerated once the surface reached about %.0f mm of worn depth, at every sensor alike, so the "
                "high-wear rows accelerated earlier in time: the wear rate is %.0f %% higher by %.0f mm depth. This is a "
                "softer casting core (hardness falling with depth), not a change in time.",
                d0 * half, 100.0 * g, std::max(half, d0 * half + 3.0));
        out.explanation += Fmt(" Baseline residual vs worn depth: correlation %.2f.", corr_depth);
        break;
      }
      case Effect::kSqueezeWear: {
        const double beta = param(f, e, 0);
        out.parameters["beta"] = Round(beta, 3);
        out.parameters["beta_stderr"] = Round(param_se(f, e, 0), 3);
        out.explanation =
            Fmt("Extra wear where normal stress is high, in a fixed ratio from day 0: squeezing/compression wear that "
                "Finnie's angle law misses. Rate = k (I + %.2f n), n = normal stress in map-intensity units. The "
                "baseline residual follows normal stress (correlation %.2f), not depth (%.2f).",
                beta, corr_normal, corr_depth);
        break;
      }
      case Effect::kProfileEvolution: {
        const double p = param(f, e, 0);
        out.parameters["form"] = "tilt";
        out.parameters["p_per_100_days"] = Round(p, 3);
        out.parameters["p_stderr"] = Round(param_se(f, e, 0), 3);
        out.parameters["top_vs_bottom_change_over_campaign"] = Round(p * span_days / 100.0, 3);
        out.explanation =
            Fmt("The relative wear rates along the concave drifted during the campaign: the rate at the top relative to "
                "the bottom changed by %+.0f %% over %.0f days, so the wear peak moved %%s as the chamber wore (the "
                "DEM of the new chamber cannot show this).",
                100.0 * p * span_days / 100.0, span_days);
        const size_t pos = out.explanation.find("moved %s");
        if (pos != std::string::npos) out.explanation.replace(pos, 8, p > 0 ? "moved up" : "moved down");
        break;
      }
      case Effect::kProfileShift: {
        const double v = param(f, e, 0);
        const double height_m = fields.z_top - fields.z_bottom;
        out.parameters["form"] = "shift";
        out.parameters["shift_per_100_days"] = Round(v, 4);
        out.parameters["shift_stderr"] = Round(param_se(f, e, 0), 4);
        out.parameters["shift_over_campaign_m"] = Round(v * height_m * span_days / 100.0, 3);
        out.explanation =
            Fmt("The wear rates along the concave changed during the campaign the way the DEM's own wear profile "
                "would if it slid %s the liner: by about %.0f mm over %.0f days, with the same total wear. The "
                "worn chamber's geometry moves the crushing zone (the DEM of the new chamber cannot show this); "
                "rows change rate at the same time, not at the same worn depth.",
                v > 0 ? "up" : "down", 1000.0 * std::fabs(v) * height_m * span_days / 100.0, span_days);
        break;
      }
      case Effect::kFeedSegregation: {
        const double a = param(f, e, 0), b = param(f, e, 1);
        const double amp = std::hypot(a, b);
        double theta_f = std::atan2(b, a) * 180.0 / kPi;
        if (theta_f < 0) theta_f += 360.0;
        out.parameters["amplitude"] = Round(amp, 3);
        out.parameters["amplitude_stderr"] = Round(std::hypot(param_se(f, e, 0), param_se(f, e, 1)) / std::sqrt(2.0), 3);
        out.parameters["theta_f_deg"] = Round(theta_f, 1);
        out.explanation =
            Fmt("Wear varies around the circumference as 1 + %.2f cos(theta - %.0f deg), from day 0 and in a fixed ratio: "
                "one-sided feed (segregation) puts more coarse rock on the side at %.0f deg. The pattern follows the "
                "angle, not the segment joints.",
                amp, theta_f, theta_f);
        break;
      }
      case Effect::kThroughputVariation: {
        const double phi = param(f, e, 0);
        out.parameters["phi"] = Round(phi, 3);
        out.parameters["phi_stderr"] = Round(param_se(f, e, 0), 3);
        out.parameters["throughput_variation_cv"] = Round(throughput_cv, 3);
        bool with_ai = false;
        for (const auto& o : bundle.operations)
          if (o.ore_ai) with_ai = true;
        out.explanation =
            Fmt("All wear rates changed together with the tonnage log: %.0f %% of the wear rate follows throughput%%s "
                "rather than calendar time (throughput varied by %.0f %%).",
                100.0 * phi, 100.0 * throughput_cv);
        const size_t pos = out.explanation.find("throughput%s");
        if (pos != std::string::npos)
          out.explanation.replace(pos, 12, with_ai ? "throughput x abrasiveness (Bond: Ai + 0.22)" : "throughput");
        break;
      }
    }
  };

  auto confidence = [&](const ModelEval& ev, double runner_up_score) {
    const double s1 = 1.0 / (1.0 + std::exp(-(ev.delta_bic - th.min_delta_bic) / 8.0));
    const double s2 = 1.0 / (1.0 + std::exp(-(ev.ho_rel - th.min_holdout_rel) / 0.05));
    const double share = ev.score > 0 ? ev.score / (ev.score + std::max(0.0, runner_up_score)) : 0.5;
    return std::clamp(s1 * s2 * (0.5 + 0.5 * share) * 1.2, 0.0, 0.99);
  };

  if (chosen) {
    double runner_up = 0;
    for (size_t k = 0; k < singles; ++k) {
      const ModelEval& ev = evals[k];
      bool part = false;
      for (Effect e : chosen->full.spec.effects)
        if (std::string(detail::EffectName(ev.full.spec.effects[0])) == detail::EffectName(e)) part = true;
      if (!part) runner_up = std::max(runner_up, ev.score);
    }
    // Order the chosen model's effects by their own contribution (drop-one chi-square).
    std::vector<std::pair<double, Effect>> parts;
    for (Effect e : chosen->full.spec.effects) {
      double contribution = chosen->delta_bic;
      if (chosen->full.spec.effects.size() > 1) {
        for (size_t k = 0; k < singles; ++k) {
          const Effect other = evals[k].full.spec.effects[0];
          if (other != e && std::find(chosen->full.spec.effects.begin(), chosen->full.spec.effects.end(), other) !=
                                chosen->full.spec.effects.end())
            contribution = evals[k].full.chi2 - chosen->full.chi2;
        }
      }
      parts.push_back({contribution, e});
    }
    std::sort(parts.begin(), parts.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
    const double conf = confidence(*chosen, runner_up);
    for (size_t k = 0; k < parts.size(); ++k) {
      Finding f;
      f.effect = detail::EffectName(parts[k].second);
      f.confidence = Round(k == 0 ? conf : conf * 0.9, 3);
      describe(chosen->full, parts[k].second, f);
      f.evidence["model"] = chosen->full.spec.Name();
      f.evidence["delta_bic"] = Round(chosen->delta_bic, 2);
      f.evidence["chi2_baseline"] = Round(null_eval.full.chi2, 2);
      f.evidence["chi2_model"] = Round(chosen->full.chi2, 2);
      f.evidence["observations"] = n_obs;
      f.evidence["holdout_chi2_baseline"] = Round(null_eval.ho_chi2, 2);
      f.evidence["holdout_chi2_model"] = Round(chosen->ho_chi2, 2);
      f.evidence["holdout_improvement"] = Round(chosen->ho_rel, 3);
      f.evidence["contribution_chi2"] = Round(parts[k].first, 2);
      f.evidence["residual_corr_normal_stress"] = Round(corr_normal, 3);
      f.evidence["residual_corr_depth"] = Round(corr_depth, 3);
      nlohmann::ordered_json alternatives = nlohmann::ordered_json::object();
      for (size_t m = 0; m < singles; ++m) alternatives[evals[m].full.spec.Name()] = Round(evals[m].delta_bic, 2);
      f.evidence["alternatives_delta_bic"] = alternatives;
      result.findings.push_back(std::move(f));
    }
  }

  // Material loss seen by sensors.
  for (const SensorData& s : sensors) {
    for (const auto& loss : s.analysis.losses) {
      Finding f;
      f.effect = kMaterialLoss;
      f.confidence = Round(std::clamp(0.5 + 0.08 * loss.depth_mm, 0.5, 0.95), 3);
      f.parameters["sensor_id"] = s.id;
      f.parameters["time"] = core::FormatIsoTime(to_time(loss.t_days));
      f.parameters["depth_mm"] = Round(loss.depth_mm, 1);
      f.parameters["z_m"] = Round(s.z, 3);
      f.parameters["theta_deg"] = Round(s.theta, 1);
      f.explanation =
          Fmt("Sensor lost %.0f mm at once on day %.1f, then kept wearing at its normal rate (%.2f mm/day) from the "
              "lower level: material broke out of the liner (spall), which a DEM wear law does not model. Not a sensor "
              "fault: a crack would stay flat until the wear caught up.",
              loss.depth_mm, loss.t_days, s.analysis.rate_mm_per_day);
      f.explanation = "Sensor " + s.id + " " + f.explanation.substr(7);
      f.evidence["step_mm"] = loss.step_mm;
      f.evidence["rate_mm_per_day"] = Round(s.analysis.rate_mm_per_day, 3);
      result.findings.push_back(std::move(f));
    }
  }
  std::stable_sort(result.findings.begin(), result.findings.end(),
                   [](const Finding& a, const Finding& b) { return a.confidence > b.confidence; });

  const bool real_mismatch = result.mismatch_z_score > th.mismatch_z;
  if (real_mismatch && result.findings.empty()) {
    Finding f;
    f.effect = kUnexplained;
    f.confidence = Round(std::clamp(1.0 - std::exp(-(result.mismatch_z_score - th.mismatch_z) / 4.0), 0.3, 0.95), 3);
    f.explanation =
        Fmt("The recordings disagree with the DEM-based reconstruction by more than sensor quantisation, map noise and "
            "scan noise allow (chi-square excess %.1f sigma), but none of the modelled effects explains it on held-out "
            "data. See the mismatch regions.",
            result.mismatch_z_score);
    f.evidence["mismatch_z_score"] = Round(result.mismatch_z_score, 2);
    nlohmann::ordered_json alternatives = nlohmann::ordered_json::object();
    for (const ModelEval& ev : evals) alternatives[ev.full.spec.Name()] = Round(ev.delta_bic, 2);
    f.evidence["alternatives_delta_bic"] = alternatives;
    result.findings.push_back(std::move(f));
  }
  result.mismatch_detected = real_mismatch || !result.findings.empty();

  for (const ModelEval& ev : evals) {
    nlohmann::ordered_json h;
    h["model"] = ev.full.spec.Name();
    h["delta_bic"] = Round(ev.delta_bic, 2);
    h["holdout_chi2"] = Round(ev.ho_chi2, 2);
    h["holdout_improvement"] = Round(ev.ho_rel, 3);
    h["significance"] = Round(std::min(ev.significance, 1e6), 2);
    h["accepted"] = ev.accepted;
    nlohmann::ordered_json params = nlohmann::ordered_json::object();
    size_t idx = prob.rows;
    for (Effect e : ev.full.spec.effects)
      for (const auto& ps : detail::EffectParams(e)) params[ps.name] = Round(ev.full.x[static_cast<Eigen::Index>(idx++)], 4);
    h["parameters"] = params;
    result.hypotheses.push_back(h);
  }
  {
    // Chi-square of the refit baseline split by data kind: checks the noise model.
    double cs = 0, cc = 0;
    size_t ns = 0, nc = 0;
    for (const Obs& o : prob.obs) {
      double pred = Interp(w_null_fit, o);
      if (o.sensor >= 0) pred *= 1.0 + null_fit.u[static_cast<size_t>(o.sensor)];
      const double z = (pred - o.wear) / o.sigma;
      (o.sensor >= 0 ? cs : cc) += z * z;
      ++(o.sensor >= 0 ? ns : nc);
    }
    result.noise["baseline_chi2_per_sensor_event"] = Round(ns ? cs / static_cast<double>(ns) : 0.0, 3);
    result.noise["baseline_chi2_per_scan_cell"] = Round(nc ? cc / static_cast<double>(nc) : 0.0, 3);
    result.noise["sensor_events"] = ns;
    result.noise["scan_cells"] = nc;
  }
  result.noise["baseline_chi2_per_observation"] =
      Round(null_fit.chi2 / std::max<double>(1.0, static_cast<double>(null_fit.n_train)), 3);
  result.noise["mismatch_z_score"] = Round(result.mismatch_z_score, 2);
  {
    nlohmann::ordered_json f = nlohmann::ordered_json::array();
    for (const Fold& fold : folds) f.push_back(fold.name);
    result.noise["holdout_folds"] = f;
  }

  // --- Improved metrics ---------------------------------------------------------------------------
  if (chosen || !result.findings.empty()) {
    const ModelEval& ev = chosen ? *chosen : null_eval;
    Eigen::MatrixXd w;
    detail::Simulate(ev.full.spec, ev.full.x, prob.points, prob.grid, w);
    double sq = 0, mx = 0;
    for (const Obs& o : prob.obs) {
      double pred = Interp(w, o);
      if (o.sensor >= 0) pred *= 1.0 + ev.full.u[static_cast<size_t>(o.sensor)];
      const double e = pred - o.wear;
      sq += e * e;
      mx = std::max(mx, std::fabs(e));
    }
    result.improved.rmse_mm = n_obs ? std::sqrt(sq / static_cast<double>(n_obs)) : 0;
    result.improved.max_abs_mm = mx;
    result.improved.observations = n_obs;
    result.improved.holdout_rmse_mm = ev.ho_n ? std::sqrt(ev.ho_sq_mm / static_cast<double>(ev.ho_n)) : 0;
    result.improved.holdout_observations = ev.ho_n;
  } else {
    result.improved = result.baseline;
  }
  const bool use_improved = chosen != nullptr || !result.findings.empty();
  const FitResult& model_fit = use_improved ? improved_fit : eq9;

  // --- Regions: where the (refit) baseline misses, beyond the noise ------------------------------
  Eigen::MatrixXd w_null, w_best;
  detail::Simulate(base_spec, null_fit.x, prob.points, prob.grid, w_null);
  detail::Simulate(model_fit.spec, model_fit.x, prob.points, prob.grid, w_best);
  if (result.mismatch_detected) {
    // Scan regions: connected cells of one sign beyond 3 sigma.
    for (size_t si = 0; si < scans.size(); ++si) {
      std::vector<double> zres(grid.cells.size(), 0.0), mm(grid.cells.size(), 0.0);
      std::vector<bool> has(grid.cells.size(), false);
      for (size_t i : prob.scan_obs) {
        const Obs& o = prob.obs[i];
        if (o.scan != static_cast<int>(si)) continue;
        const double e = Interp(w_null, o) - o.wear;
        zres[static_cast<size_t>(o.cell)] = e / o.sigma;
        mm[static_cast<size_t>(o.cell)] = e;
        has[static_cast<size_t>(o.cell)] = true;
      }
      std::vector<int> label(grid.cells.size(), -1);
      const bool wrap = fields.theta_span_deg >= 359.0;
      for (size_t c = 0; c < grid.cells.size(); ++c) {
        if (!has[c] || std::fabs(zres[c]) < 3.0 || label[c] >= 0) continue;
        const double sign = zres[c] > 0 ? 1.0 : -1.0;
        std::vector<size_t> stack{c}, members;
        label[c] = static_cast<int>(c);
        while (!stack.empty()) {
          const size_t cur = stack.back();
          stack.pop_back();
          members.push_back(cur);
          const long iz = static_cast<long>(cur / grid.nt), it = static_cast<long>(cur % grid.nt);
          const long nz = static_cast<long>(grid.nz), nt = static_cast<long>(grid.nt);
          const long nbr[4][2] = {{iz - 1, it}, {iz + 1, it}, {iz, it - 1}, {iz, it + 1}};
          for (const auto& nb : nbr) {
            long z = nb[0], t = nb[1];
            if (z < 0 || z >= nz) continue;
            if (t < 0 || t >= nt) {
              if (!wrap) continue;
              t = (t + nt) % nt;
            }
            const auto n = static_cast<size_t>(z * nt + t);
            if (!has[n] || label[n] >= 0 || zres[n] * sign < 3.0) continue;
            label[n] = static_cast<int>(c);
            stack.push_back(n);
          }
        }
        double peak = 0;
        for (size_t m : members) peak = std::max(peak, std::fabs(zres[m]));
        if (members.size() < 2 && peak < 5.0) continue;
        Region r;
        r.z_min_m = std::numeric_limits<double>::max();
        r.z_max_m = std::numeric_limits<double>::lowest();
        long it_min = std::numeric_limits<long>::max(), it_max = -1;
        double size = 0;
        for (size_t m : members) {
          const auto iz = static_cast<double>(m / grid.nt);
          r.z_min_m = std::min(r.z_min_m, grid.z0 + iz * grid.dz);
          r.z_max_m = std::max(r.z_max_m, grid.z0 + (iz + 1) * grid.dz);
          it_min = std::min(it_min, static_cast<long>(m % grid.nt));
          it_max = std::max(it_max, static_cast<long>(m % grid.nt));
          size += std::fabs(mm[m]);
        }
        r.theta_min_deg = std::fmod(grid.t0_deg + static_cast<double>(it_min) * grid.dt_deg, 360.0);
        r.theta_max_deg = std::fmod(grid.t0_deg + static_cast<double>(it_max + 1) * grid.dt_deg, 360.0);
        r.from = t0;
        r.to = bundle.scans[si].date;
        r.sign = sign > 0 ? "over" : "under";
        r.size_mm = Round(size / static_cast<double>(members.size()), 2);
        r.source = "scan:" + scans[si].file;
        result.regions.push_back(r);
      }
    }
    // Sensor regions: runs in time of one sign beyond 3 sigma.
    for (const SensorData& s : sensors) {
      if (!s.usable) continue;
      const auto& list = prob.sensor_obs[static_cast<size_t>(s.usable_index)];
      const double u = null_fit.u[static_cast<size_t>(s.usable_index)];
      size_t k = 0;
      while (k < list.size()) {
        const Obs& o = prob.obs[list[k]];
        const double e = Interp(w_null, o) * (1.0 + u) - o.wear;
        if (std::fabs(e / o.sigma) < 3.0) {
          ++k;
          continue;
        }
        const double sign = e > 0 ? 1.0 : -1.0;
        size_t end = k;
        double size = 0;
        while (end < list.size()) {
          const Obs& oe = prob.obs[list[end]];
          const double ee = Interp(w_null, oe) * (1.0 + u) - oe.wear;
          if (ee * sign / oe.sigma < 3.0) break;
          size += std::fabs(ee);
          ++end;
        }
        if (end - k >= 3) {
          Region r;
          r.z_min_m = s.z - 0.02;
          r.z_max_m = s.z + 0.02;
          r.theta_min_deg = std::fmod(s.theta - 1.0 + 360.0, 360.0);
          r.theta_max_deg = std::fmod(s.theta + 1.0, 360.0);
          r.from = to_time(prob.obs[list[k]].t);
          r.to = to_time(prob.obs[list[end - 1]].t);
          r.sign = sign > 0 ? "over" : "under";
          r.size_mm = Round(size / static_cast<double>(end - k), 2);
          r.source = "sensor:" + s.id;
          result.regions.push_back(r);
        }
        k = std::max(end, k + 1);
      }
    }
    std::stable_sort(result.regions.begin(), result.regions.end(),
                     [](const Region& a, const Region& b) { return a.size_mm > b.size_mm; });
    if (result.regions.size() > 30) result.regions.resize(30);
  }

  // --- Curves and residual grids for the report -------------------------------------------------
  std::vector<ModelPoint> all_sensor_points;
  for (const SensorData& s : sensors) all_sensor_points.push_back(make_point(s.field, 0.5 * s.thickness));
  Eigen::MatrixXd w_curves_base, w_curves_best;
  detail::Simulate(base_spec, eq9.x, all_sensor_points, prob.grid, w_curves_base);
  detail::Simulate(model_fit.spec, model_fit.x, all_sensor_points, prob.grid, w_curves_best);
  auto loss_offset = [&](const SensorData& s, double t) {
    double off = 0;
    for (const auto& l : s.analysis.losses)
      if (t >= l.t_days) off += l.depth_mm;
    return off;
  };
  auto sensor_u = [&](const SensorData& s) {
    return (use_improved && s.usable) ? model_fit.u[static_cast<size_t>(s.usable_index)] : 0.0;
  };
  for (size_t i = 0; i < sensors.size(); ++i) {
    const SensorData& s = sensors[i];
    SensorCurve c;
    c.sensor_id = s.id;
    c.row = s.row;
    c.thickness_new_mm = s.thickness;
    c.used = s.usable;
    for (size_t k = 0; k < s.analysis.readings.size(); ++k) {
      c.reading_days.push_back(s.analysis.readings[k].t_days);
      c.reading_mm.push_back(s.analysis.readings[k].value_mm);
      c.reading_used.push_back(s.analysis.used[k]);
    }
    const size_t stride = std::max<size_t>(1, prob.grid.steps / 120);
    const double t_end = std::max(t_obs_end, options.predict_at ? days(*options.predict_at) : 0.0);
    for (size_t j = 0; j <= prob.grid.steps; j += stride) {
      const double t = static_cast<double>(j) * prob.grid.dt;
      if (t > t_end + prob.grid.dt) break;
      c.model_days.push_back(t);
      const auto r = static_cast<Eigen::Index>(i);
      const auto jj = static_cast<Eigen::Index>(j);
      c.baseline_thickness_mm.push_back(s.thickness - w_curves_base(r, jj));
      c.improved_thickness_mm.push_back(s.thickness - w_curves_best(r, jj) * (1.0 + sensor_u(s)) -
                                        (use_improved ? loss_offset(s, t) : 0.0));
    }
    result.curves.push_back(std::move(c));
  }
  for (size_t si = 0; si < scans.size(); ++si) {
    ResidualGrid g;
    g.scan_file = scans[si].file;
    g.date = bundle.scans[si].date;
    g.nz = grid.nz;
    g.ntheta = grid.nt;
    g.z_min_m = grid.z0;
    g.z_max_m = grid.z0 + grid.dz * static_cast<double>(grid.nz);
    g.theta_min_deg = grid.t0_deg;
    g.theta_max_deg = grid.t0_deg + grid.dt_deg * static_cast<double>(grid.nt);
    g.measured_mm.assign(grid.cells.size(), kNaN);
    g.before_mm.assign(grid.cells.size(), kNaN);
    g.after_mm.assign(grid.cells.size(), kNaN);
    for (size_t i : prob.scan_obs) {
      const Obs& o = prob.obs[i];
      if (o.scan != static_cast<int>(si)) continue;
      const auto c = static_cast<size_t>(o.cell);
      g.measured_mm[c] = o.wear;
      g.before_mm[c] = Interp(w_null, o) - o.wear;
      g.after_mm[c] = Interp(w_best, o) - o.wear;
    }
    result.grids.push_back(std::move(g));
  }

  // Model points of every map face (the prediction and the report's liner maps).
  std::vector<ModelPoint> face_points;
  face_points.reserve(bundle.map.face_count());
  for (Eigen::Index f = 0; f < static_cast<Eigen::Index>(bundle.map.face_count()); ++f) {
    PointField pf;
    pf.z = bundle.map.z[f];
    pf.theta_deg = bundle.map.theta_deg[f];
    pf.intensity = fields.intensity[f];
    pf.normal_tilde = fields.normal_tilde[f];
    pf.normal_i = fields.normal_i[f];
    face_points.push_back(make_point(pf, 0.5 * crusher.thickness_new_mm));
  }

  // --- Prediction ---------------------------------------------------------------------------------
  if (options.predict_at) {
    Prediction pred;
    pred.time = *options.predict_at;
    const double t = days(*options.predict_at);
    const Eigen::VectorXd wb = detail::SimulateAt(base_spec, eq9.x, all_sensor_points, prob.grid, t);
    const Eigen::VectorXd wi = detail::SimulateAt(model_fit.spec, model_fit.x, all_sensor_points, prob.grid, t);
    for (size_t i = 0; i < sensors.size(); ++i) {
      const SensorData& s = sensors[i];
      const auto r = static_cast<Eigen::Index>(i);
      pred.sensors.push_back(
          {s.id, std::max(0.0, s.thickness - wb[r]),
           std::max(0.0, s.thickness - wi[r] * (1.0 + sensor_u(s)) - (use_improved ? loss_offset(s, t) : 0.0))});
    }
    // Physical: a face's wear is at most the as-new thickness (worn through).
    const Eigen::VectorXd fb =
        detail::SimulateAt(base_spec, eq9.x, face_points, prob.grid, t).cwiseMax(0.0).cwiseMin(crusher.thickness_new_mm);
    const Eigen::VectorXd fi = detail::SimulateAt(model_fit.spec, model_fit.x, face_points, prob.grid, t)
                                   .cwiseMax(0.0)
                                   .cwiseMin(crusher.thickness_new_mm);
    pred.face_wear_baseline_mm.assign(fb.data(), fb.data() + fb.size());
    pred.face_wear_improved_mm.assign(fi.data(), fi.data() + fi.size());
    result.prediction = std::move(pred);
  }

  // --- Unwrapped-liner maps and thinnest points for the HTML report (report_maps.cpp) -------------
  detail::FillLinerReport(
      bundle, fields, scans,
      [&](bool improved, double t) {
        const Eigen::VectorXd w = improved ? detail::SimulateAt(model_fit.spec, model_fit.x, face_points, prob.grid, t)
                                           : detail::SimulateAt(base_spec, eq9.x, face_points, prob.grid, t);
        return Eigen::VectorXd(w.cwiseMax(0.0).cwiseMin(crusher.thickness_new_mm));
      },
      result);

  std::stable_sort(result.data_quality.begin(), result.data_quality.end(),
                   [](const DataQualityIssue& a, const DataQualityIssue& b) {
                     return a.sensor_id != b.sensor_id ? a.sensor_id < b.sensor_id : a.from < b.from;
                   });
  return result;
}

}  // namespace lw::diagnosis
