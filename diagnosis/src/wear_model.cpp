#include "wear_model.hpp"

#include <algorithm>
#include <cmath>

namespace lw::diagnosis::detail {

const char* EffectName(Effect effect) {
  switch (effect) {
    case Effect::kWorkHardening:
      return "work_hardening";
    case Effect::kHardnessGradient:
      return "hardness_gradient";
    case Effect::kSqueezeWear:
      return "squeeze_wear";
    case Effect::kProfileEvolution:
      return "profile_evolution";
    case Effect::kFeedSegregation:
      return "feed_segregation";
    case Effect::kThroughputVariation:
      return "throughput_variation";
    case Effect::kProfileShift:
      return "profile_evolution";
  }
  return "unknown";
}

const char* FormName(Effect effect) {
  switch (effect) {
    case Effect::kProfileEvolution:
      return "profile_evolution:tilt";
    case Effect::kProfileShift:
      return "profile_evolution:shift";
    default:
      return EffectName(effect);
  }
}

std::vector<ParamSpec> EffectParams(Effect effect) {
  switch (effect) {
    case Effect::kWorkHardening:
      // h: wear-rate reduction where normal stress is at its robust maximum, once saturated;
      // log_tau: log of the saturation time constant in days.
      return {{"h", 0.0, 0.95, 0.2, 0.3}, {"log_tau", std::log(0.5), std::log(300.0), std::log(8.0), 1.0, true}};
    case Effect::kHardnessGradient:
      // g: wear-rate increase once the ramp is complete (softer core); d0: depth where softening
      // starts, as a share of half the thickness; w: the ramp's width as a share of the rest of the
      // way to mid-thickness (1: a gradual fall to mid-thickness; small: a step, a softer layer).
      return {{"g", 0.0, 2.0, 0.2, 0.3}, {"d0", 0.0, 0.9, 0.3, 0.3, true}, {"w", 0.03, 1.0, 1.0, 0.2, true}};
    case Effect::kSqueezeWear:
      // beta: squeeze (normal-stress) wear per unit of normal stress, relative to the map's wear.
      return {{"beta", 0.0, 5.0, 0.3, 0.3}};
    case Effect::kProfileEvolution:
      // p: change per 100 days of the rate at the top relative to the bottom of the concave.
      return {{"p", -3.0, 3.0, 0.0, 0.3}};
    case Effect::kFeedSegregation:
      // a, b: cosine and sine amplitudes of 1 + A cos(theta - theta_f).
      return {{"a", -0.8, 0.8, 0.0, 0.1}, {"b", -0.8, 0.8, 0.0, 0.1}};
    case Effect::kThroughputVariation:
      // phi: share of the wear rate that follows throughput x abrasiveness (1 = fully).
      return {{"phi", 0.0, 1.5, 0.5, 0.3}};
    case Effect::kProfileShift:
      // v: upward translation of the DEM wear profile, in concave heights per 100 days (negative: down).
      return {{"v", -1.0, 1.0, 0.0, 0.05}};
  }
  return {};
}

size_t ModelSpec::ParamCount() const {
  size_t n = rows;
  for (Effect e : effects) n += EffectParams(e).size();
  return n;
}

int ModelSpec::Offset(Effect effect) const {
  size_t offset = rows;
  for (Effect e : effects) {
    if (e == effect) return static_cast<int>(offset);
    offset += EffectParams(e).size();
  }
  return -1;
}

std::string ModelSpec::Name() const {
  if (effects.empty()) return "baseline";
  std::string name;
  for (Effect e : effects) {
    if (!name.empty()) name += "+";
    name += FormName(e);
  }
  return name;
}

void ModelSpec::Bounds(Eigen::VectorXd& lower, Eigen::VectorXd& upper, Eigen::VectorXd& scale, Eigen::VectorXd& initial,
                       double k_scale) const {
  const auto n = static_cast<Eigen::Index>(ParamCount());
  lower.resize(n);
  upper.resize(n);
  scale.resize(n);
  initial.resize(n);
  for (size_t r = 0; r < rows; ++r) {
    const auto i = static_cast<Eigen::Index>(r);
    lower[i] = 0;
    upper[i] = 1e6;
    scale[i] = std::max(k_scale, 1e-6);
    initial[i] = k_scale;
  }
  Eigen::Index i = static_cast<Eigen::Index>(rows);
  for (Effect e : effects) {
    for (const ParamSpec& p : EffectParams(e)) {
      lower[i] = p.lower;
      upper[i] = p.upper;
      scale[i] = p.scale;
      initial[i] = p.initial;
      ++i;
    }
  }
}

namespace {

struct Resolved {
  bool wh = false, hg = false, sq = false, pe = false, fs = false, tv = false, ps = false;
  double h = 0, tau = 1, g = 0, d0 = 0, wrel = 1, beta = 0, p = 0, a = 0, b = 0, phi = 0, v = 0;
};

Resolved Resolve(const ModelSpec& spec, const Eigen::VectorXd& x) {
  Resolved r;
  int o;
  if ((o = spec.Offset(Effect::kWorkHardening)) >= 0) {
    r.wh = true;
    r.h = x[o];
    r.tau = std::exp(x[o + 1]);
  }
  if ((o = spec.Offset(Effect::kHardnessGradient)) >= 0) {
    r.hg = true;
    r.g = x[o];
    r.d0 = x[o + 1];
    r.wrel = x[o + 2];
  }
  if ((o = spec.Offset(Effect::kSqueezeWear)) >= 0) {
    r.sq = true;
    r.beta = x[o];
  }
  if ((o = spec.Offset(Effect::kProfileEvolution)) >= 0) {
    r.pe = true;
    r.p = x[o];
  }
  if ((o = spec.Offset(Effect::kFeedSegregation)) >= 0) {
    r.fs = true;
    r.a = x[o];
    r.b = x[o + 1];
  }
  if ((o = spec.Offset(Effect::kThroughputVariation)) >= 0) {
    r.tv = true;
    r.phi = x[o];
  }
  if ((o = spec.Offset(Effect::kProfileShift)) >= 0) {
    r.ps = true;
    r.v = x[o];
  }
  return r;
}

// Smooth ramp from 0 (x <= 0) to 1 (x >= 1).
inline double Ramp(double x) {
  constexpr double s = 0.05;
  auto softplus = [](double v) { return v > 30 ? v : std::log1p(std::exp(v)); };
  return s * (softplus(x / s) - softplus((x - 1.0) / s));
}

// Integrates one point; calls sink(step, wear) after each step (step 1..n).
template <typename Sink>
void IntegratePoint(const Resolved& r, const Eigen::VectorXd& x, const ModelPoint& pt, const TimeGrid& grid,
                    const std::vector<double>& hard, size_t n_steps, Sink&& sink) {
  const double k = pt.weight_a * x[pt.row_a] + (1.0 - pt.weight_a) * x[pt.row_b];
  double base = k * (pt.intensity + (r.sq ? r.beta * pt.normal_i : 0.0));
  if (r.fs) base *= std::max(0.05, 1.0 + r.a * pt.cos_t + r.b * pt.sin_t);
  const double dt = grid.dt;
  const double onset = r.d0 * pt.half_thickness_mm;
  const double width = std::max(r.wrel * (pt.half_thickness_mm - onset), 1.0);
  double w = 0;
  for (size_t j = 0; j < n_steps; ++j) {
    double f = base;
    if (r.wh) f *= std::max(0.05, 1.0 - r.h * pt.normal_tilde * hard[j]);
    if (r.pe) f *= std::max(0.05, 1.0 + r.p * pt.zn * (static_cast<double>(j) + 0.5) * dt / 100.0);
    if (r.ps) f *= std::max(0.05, 1.0 + r.v * pt.shift_rel * (static_cast<double>(j) + 0.5) * dt / 100.0);
    if (r.tv) f *= std::max(0.0, 1.0 + r.phi * (grid.throughput[j] - 1.0));
    if (r.hg) {
      const double r1 = f * (1.0 + r.g * Ramp((w - onset) / width));
      const double wp = w + dt * r1;
      const double r2 = f * (1.0 + r.g * Ramp((wp - onset) / width));
      w += 0.5 * dt * (r1 + r2);
    } else {
      w += dt * f;
    }
    sink(j + 1, w);
  }
}

std::vector<double> HardeningCurve(const Resolved& r, const TimeGrid& grid, size_t n_steps) {
  std::vector<double> hard;
  if (!r.wh) return hard;
  hard.resize(n_steps);
  for (size_t j = 0; j < n_steps; ++j) {
    // Step average of 1 - exp(-t/tau), exact for the exponential.
    const double t0 = static_cast<double>(j) * grid.dt, t1 = t0 + grid.dt;
    hard[j] = 1.0 - r.tau * (std::exp(-t0 / r.tau) - std::exp(-t1 / r.tau)) / grid.dt;
  }
  return hard;
}

}  // namespace

void Simulate(const ModelSpec& spec, const Eigen::VectorXd& params, const std::vector<ModelPoint>& points, const TimeGrid& grid,
              Eigen::MatrixXd& wear) {
  const Resolved r = Resolve(spec, params);
  const std::vector<double> hard = HardeningCurve(r, grid, grid.steps);
  wear.resize(static_cast<Eigen::Index>(points.size()), static_cast<Eigen::Index>(grid.steps + 1));
  for (size_t i = 0; i < points.size(); ++i) {
    const auto row = static_cast<Eigen::Index>(i);
    wear(row, 0) = 0;
    IntegratePoint(r, params, points[i], grid, hard, grid.steps,
                   [&](size_t j, double w) { wear(row, static_cast<Eigen::Index>(j)) = w; });
  }
}

bool DepthDependent(const ModelSpec& spec) {
  return spec.Has(Effect::kHardnessGradient);
}

ModelPoint ScaledRate(ModelPoint point, double factor) {
  point.intensity *= factor;
  point.normal_i *= factor;
  point.broad_i *= factor;
  return point;
}

double OwnRateFactor(double u) {
  return std::max(0.05, 1.0 + u);
}

namespace {
std::vector<ModelPoint> OwnRatePoints(const ModelSpec& spec, std::vector<ModelPoint> points, const std::vector<double>& factors) {
  if (DepthDependent(spec))
    for (size_t i = 0; i < points.size() && i < factors.size(); ++i) points[i] = ScaledRate(points[i], factors[i]);
  return points;
}
}  // namespace

void SimulateOwnRates(const ModelSpec& spec, const Eigen::VectorXd& params, const std::vector<ModelPoint>& points,
                      const std::vector<double>& factors, const TimeGrid& grid, Eigen::MatrixXd& wear) {
  Simulate(spec, params, OwnRatePoints(spec, points, factors), grid, wear);
  if (DepthDependent(spec))
    for (size_t i = 0; i < points.size() && i < factors.size(); ++i) wear.row(static_cast<Eigen::Index>(i)) /= factors[i];
}

Eigen::VectorXd SimulateOwnRatesAt(const ModelSpec& spec, const Eigen::VectorXd& params, const std::vector<ModelPoint>& points,
                                   const std::vector<double>& factors, const TimeGrid& grid, double t_days) {
  Eigen::VectorXd w = SimulateAt(spec, params, OwnRatePoints(spec, points, factors), grid, t_days);
  if (DepthDependent(spec))
    for (size_t i = 0; i < points.size() && i < factors.size(); ++i) w[static_cast<Eigen::Index>(i)] /= factors[i];
  return w;
}

Eigen::VectorXd SimulateAt(const ModelSpec& spec, const Eigen::VectorXd& params, const std::vector<ModelPoint>& points,
                           const TimeGrid& grid, double t_days) {
  const Resolved r = Resolve(spec, params);
  const double x = std::clamp(t_days / grid.dt, 0.0, static_cast<double>(grid.steps));
  const auto j0 = static_cast<size_t>(std::floor(x));
  const double frac = x - static_cast<double>(j0);
  const size_t n_steps = std::min(grid.steps, j0 + 1);
  const std::vector<double> hard = HardeningCurve(r, grid, n_steps);
  Eigen::VectorXd out(static_cast<Eigen::Index>(points.size()));
  for (size_t i = 0; i < points.size(); ++i) {
    double w0 = 0, w1 = 0;
    IntegratePoint(r, params, points[i], grid, hard, n_steps, [&](size_t j, double w) {
      if (j == j0) w0 = w;
      if (j == j0 + 1) w1 = w;
    });
    if (j0 >= grid.steps) w1 = w0;
    out[static_cast<Eigen::Index>(i)] = w0 + frac * (w1 - w0);
  }
  return out;
}

}  // namespace lw::diagnosis::detail
