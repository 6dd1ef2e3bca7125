#include "core/forecast.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <cstdio>
#include <map>

namespace lw::core {
namespace {

constexpr double kQuantisationSd = 0.28867513459481287;  // 1/sqrt(12): uniform over [n, n+1)

Eigen::Vector3d Basis(double s) {
  return {1.0, s, s * s};
}

/// First time (days) in (t0, t0 + horizon] where f(t) >= limit; daily steps, then bisection.
std::optional<double> FirstReach(const std::function<double(double)>& f, double t0, double horizon, double limit) {
  if (f(t0) >= limit) return t0;
  double prev = t0;
  for (double t = t0 + 1.0; t <= t0 + horizon + 1e-9; t += 1.0) {
    if (f(t) >= limit) {
      double lo = prev, hi = t;
      for (int i = 0; i < 30; ++i) {
        const double mid = 0.5 * (lo + hi);
        (f(mid) >= limit ? hi : lo) = mid;
      }
      return hi;
    }
    prev = t;
  }
  return std::nullopt;
}

std::optional<TimePoint> ToTime(const CrusherConfig& crusher, std::optional<double> days) {
  if (!days) return std::nullopt;
  return AddDays(crusher.installed_at, *days);
}

}  // namespace

double WearCurve::Wear(double t_days) const {
  return Basis(t_days - t_ref_days).dot(c);
}

double WearCurve::RateMmPerDay(double t_days) const {
  return c[1] + 2.0 * c[2] * (t_days - t_ref_days);
}

double WearCurve::Sd(double t_days) const {
  const Eigen::Vector3d x = Basis(t_days - t_ref_days);
  const double param_var = std::max(0.0, x.dot(cov * x));
  const double s = std::max(0.0, t_days - t_ref_days);
  const double rate_sd = rate_uncertainty * std::max(0.0, RateMmPerDay(t_days)) * s;
  return std::sqrt(param_var + rate_sd * rate_sd);
}

SensorForecast ForecastSensor(const CrusherConfig& crusher, const SensorInfo& sensor, const std::vector<Reading>& readings,
                              const ForecastOptions& options) {
  SensorForecast out;
  out.sensor_id = sensor.id;
  std::vector<std::pair<double, double>> pts;  // (days since installation, wear mm at interval centre)
  for (const Reading& r : readings) {
    if (r.sensor_id != sensor.id || !crusher.OfThisLiner(r.sensor_id, r.time, r.thickness_mm)) continue;
    pts.emplace_back(DaysBetween(crusher.installed_at, r.time), sensor.thickness_new_mm - (r.thickness_mm + 0.5));
    if (r.time >= out.last_time) {
      if (r.time > out.last_time || out.readings_used == 0)
        out.last_reading_mm = r.thickness_mm;
      else
        out.last_reading_mm = std::min(out.last_reading_mm, r.thickness_mm);
      out.last_time = r.time;
    }
    ++out.readings_used;
  }
  if (pts.empty()) {
    out.note = "no readings";
    return out;
  }
  std::sort(pts.begin(), pts.end());
  const double t_last = pts.back().first;
  const double window = std::max(options.window_min_days, options.window_fraction * std::max(0.0, t_last));
  std::vector<std::pair<double, double>> fit;
  for (const auto& p : pts) {
    if (p.first >= t_last - window) fit.push_back(p);
  }
  // The installation itself is a data point (wear 0 at day 0, the thickness known exactly) when
  // the window reaches back to it.
  if (t_last - window <= 0.0) fit.emplace_back(0.0, 0.0);
  const double span = fit.empty() ? 0.0 : t_last - std::min_element(fit.begin(), fit.end())->first;

  WearCurve curve;
  curve.t_ref_days = t_last;
  curve.rate_uncertainty = options.rate_uncertainty;
  if (span < 2.0 || fit.size() < 3) {
    // Too little history in the window: straight line from the installation.
    if (t_last < 1.0) {
      out.note = "less than a day of readings";
      return out;
    }
    const double rate = std::max(0.0, pts.back().second) / t_last;
    curve.c = {pts.back().second, rate, 0.0};
    curve.sigma_mm = kQuantisationSd;
    curve.cov(0, 0) = kQuantisationSd * kQuantisationSd;
    curve.cov(1, 1) = std::pow(kQuantisationSd / t_last, 2);
    out.note = "few recent readings: rate from the installation";
  } else {
    const auto solve = [&](int cols) {
      Eigen::MatrixXd X(static_cast<Eigen::Index>(fit.size()), cols);
      Eigen::VectorXd y(static_cast<Eigen::Index>(fit.size()));
      for (size_t i = 0; i < fit.size(); ++i) {
        const Eigen::Vector3d b = Basis(fit[i].first - t_last);
        X.row(static_cast<Eigen::Index>(i)) = b.head(cols).transpose();
        y[static_cast<Eigen::Index>(i)] = fit[i].second;
      }
      const Eigen::MatrixXd xtx = X.transpose() * X;
      const Eigen::VectorXd coef = xtx.ldlt().solve(X.transpose() * y);
      const double rss = (X * coef - y).squaredNorm();
      const double dof = std::max<double>(1.0, static_cast<double>(fit.size()) - cols);
      const double sigma = std::max(kQuantisationSd, std::sqrt(rss / dof));
      Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
      cov.topLeftCorner(cols, cols) = sigma * sigma * xtx.inverse();
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      c.head(cols) = coef;
      return std::make_tuple(c, cov, sigma);
    };
    auto [c, cov, sigma] = solve(3);
    // Acceleration is allowed, deceleration is not extrapolated (work hardening flattens the
    // early curve; a liner does not wear slower the thinner it gets): refit a straight line.
    // Nor is an acceleration the fit cannot tell from zero: extrapolated over months, a c2 of noise
    // moves the date by more than the whole band of the straight line.
    if (c[2] < 0.0 || span < 7.0 || c[2] < options.band_sigmas * std::sqrt(std::max(0.0, cov(2, 2))))
      std::tie(c, cov, sigma) = solve(2);
    if (c[1] < 0.0) {
      c[1] = 0.0;
      out.note = "no measurable wear in the fit window";
    }
    // Quantised readings scatter about the line as a staircase, not independently, so the fit's own
    // covariance understates the rate's error when few loops broke in the window: the wear over the
    // window is known to a loop's quantisation at each end (sd sqrt(2/12) mm over the span).
    cov(1, 1) = std::max(cov(1, 1), std::pow(std::sqrt(2.0) * kQuantisationSd / span, 2));
    curve.c = c;
    curve.cov = cov;
    curve.sigma_mm = sigma;
  }
  out.curve = curve;
  out.ok = true;
  out.thickness_mm = sensor.thickness_new_mm - curve.Wear(t_last);
  out.rate_mm_per_day = curve.RateMmPerDay(t_last);

  const double limit = sensor.thickness_new_mm - crusher.thickness_min_mm;
  const double k = options.band_sigmas;
  const auto central = [&](double t) { return curve.Wear(t); };
  const auto high = [&](double t) { return curve.Wear(t) + k * curve.Sd(t); };
  const auto low = [&](double t) { return curve.Wear(t) - k * curve.Sd(t); };
  const auto reach = FirstReach(central, t_last, options.horizon_days, limit);
  const auto earliest = FirstReach(high, t_last, options.horizon_days, limit);
  const auto latest = FirstReach(low, t_last, options.horizon_days, limit);
  out.reach = ToTime(crusher, reach);
  out.reach_earliest = ToTime(crusher, earliest);
  out.reach_latest = ToTime(crusher, latest);

  const double end = latest ? *latest : (reach ? *reach : t_last + std::min(options.horizon_days, 365.0));
  for (double t = t_last; t <= end + 1e-9; t += options.curve_step_days) {
    CurvePoint p;
    p.time = AddDays(crusher.installed_at, t);
    p.thickness_mm = sensor.thickness_new_mm - central(t);
    p.lo_mm = sensor.thickness_new_mm - high(t);
    p.hi_mm = sensor.thickness_new_mm - low(t);
    out.points.push_back(p);
    if (out.points.size() > 5000) break;
  }
  return out;
}

namespace {

/// The row's members: sensors of `row` with a forecast and a current wear; their mean wear now.
std::vector<const SensorForecast*> RowMembers(const CrusherConfig& crusher, const std::string& row,
                                              const std::map<std::string, double>& wear_now,
                                              const std::map<std::string, const SensorForecast*>& by_id, double* mean_wear) {
  std::vector<const SensorForecast*> members;
  *mean_wear = 0;
  for (const SensorInfo& s : crusher.sensors) {
    if (s.row != row) continue;
    const auto f = by_id.find(s.id);
    const auto w = wear_now.find(s.id);
    if (f == by_id.end() || !f->second->ok || w == wear_now.end()) continue;
    members.push_back(f->second);
    *mean_wear += w->second;
  }
  if (!members.empty()) *mean_wear /= static_cast<double>(members.size());
  return members;
}

std::string Fixed(double v, int digits) {
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}

/// The dates of a row from its thinnest area: the area wears `ratio` times the row's mean sensor
/// wear (`members`, their mean wear now `mean_wear`); `rf` holds the area's thickness and band.
void AreaForecast(const CrusherConfig& crusher, const ThinnestArea& area, const std::vector<const SensorForecast*>& members,
                  double mean_wear, double t_now, const ForecastOptions& options, RowForecast* rf) {
  // At the band's thin edge the area has worn (new - lo) and wears proportionally faster, at the
  // thick edge (new - hi).
  const auto ratio_for = [&](double remaining) { return (crusher.thickness_new_mm - remaining) / mean_wear; };
  const double ratio = ratio_for(area.thickness_mm);
  const double n = static_cast<double>(members.size());
  // Each sensor's curve is anchored at its own last reading; the row curve is the mean of the
  // sensors' wear increments after `now`, scaled by the ratio of the area.
  const auto increment = [&](double t, double sigmas, double r) {
    double inc = 0, sd = 0;
    for (const SensorForecast* f : members) {
      inc += f->curve.Wear(t) - f->curve.Wear(f->curve.t_ref_days);  // wear after its last reading
      sd += f->curve.Sd(t);
    }
    return r * (inc + sigmas * sd) / n;
  };
  double rate = 0, rate_sd = 0;  // sd summed: the sensors' rates move together (throughput, ore)
  for (const SensorForecast* f : members) {
    const double r = f->curve.RateMmPerDay(t_now);
    rate += r;
    rate_sd += std::sqrt(std::max(0.0, f->curve.cov(1, 1)) + std::pow(f->curve.rate_uncertainty * std::max(0.0, r), 2));
  }
  rf->rate_mm_per_day = ratio * rate / n;
  rf->rate_sd_mm_per_day = ratio * rate_sd / n;
  rf->ok = true;
  const double k = options.band_sigmas;
  const double lim = crusher.thickness_min_mm;
  if (area.thickness_mm <= lim) {
    // Past the minimum: since when, from the row's curves back in time.
    const auto worn = [&](double t) {
      double w = 0;
      for (const SensorForecast* f : members) w += f->curve.Wear(t);
      return ratio * w / n;
    };
    const auto since = FirstReach(worn, 0.0, std::max(0.0, t_now), crusher.thickness_new_mm - lim);
    rf->below_minimum_since = AddDays(crusher.installed_at, std::min(t_now, since.value_or(t_now)));
    rf->reach_note = "below minimum since " + FormatIsoTime(*rf->below_minimum_since).substr(0, 10);
    return;
  }
  const double lo = std::min(area.lo_mm, area.thickness_mm);
  const double hi = std::max(area.hi_mm, area.thickness_mm);
  rf->reach_earliest = ToTime(
      crusher, FirstReach([&](double t) { return increment(t, k, ratio_for(lo)); }, t_now, options.horizon_days, lo - lim));
  if (rf->rate_mm_per_day - k * rf->rate_sd_mm_per_day <= 0.0) {
    // A rate whose band reaches zero puts the date anywhere from the earliest to never: a central
    // date would jump by months with every loop a slow row loses.
    rf->reach_note = "thinning rate " + Fixed(rf->rate_mm_per_day, 3) + " +/- " + Fixed(k * rf->rate_sd_mm_per_day, 3) +
                     " mm/day is not distinguishable from zero: beyond forecast (only the earliest date is given)";
    return;
  }
  rf->reach = ToTime(crusher, FirstReach([&](double t) { return increment(t, 0.0, ratio); }, t_now, options.horizon_days,
                                         area.thickness_mm - lim));
  rf->reach_latest = ToTime(
      crusher, FirstReach([&](double t) { return increment(t, -k, ratio_for(hi)); }, t_now, options.horizon_days, hi - lim));
  if (!rf->reach || !rf->reach_latest)
    rf->reach_note = "beyond forecast: more than " + Fixed(options.horizon_days, 0) + " days after the latest reading";
}

std::optional<TimePoint> Earlier(std::optional<TimePoint> a, std::optional<TimePoint> b) {
  if (!a) return b;
  if (!b) return a;
  return std::min(*a, *b);
}

/// A row's thinnest area is no thicker than any point of it, its sensors included: a sensor whose
/// own readings reach the minimum before the area's date sets the row's date. Where the map's band
/// is too wide to place the area (the whole row, a band reaching 0), this is the date the data do
/// support; a sensor already past the minimum puts the row below it.
void BoundBySensors(const CrusherConfig& crusher, const std::vector<const SensorForecast*>& members, double t_now,
                    RowForecast* rf) {
  if (rf->below_minimum_since) return;
  const SensorForecast* first = nullptr;
  for (const SensorForecast* f : members)
    if (f->reach && (!first || *f->reach < *first->reach)) first = f;
  if (!first) return;
  const SensorInfo* info = crusher.FindSensor(first->sensor_id);
  const double t_last = DaysBetween(crusher.installed_at, first->last_time);
  char b[200];
  if (info && *first->reach <= first->last_time) {
    const double limit = info->thickness_new_mm - crusher.thickness_min_mm;
    const auto since = FirstReach([&](double t) { return first->curve.Wear(t); }, 0.0, std::max(0.0, t_last), limit);
    rf->below_minimum_since = AddDays(crusher.installed_at, std::min(t_now, since.value_or(t_last)));
    rf->reach = rf->reach_earliest = rf->reach_latest = std::nullopt;
    rf->reach_set_by = first->sensor_id;
    std::snprintf(b, sizeof b, "below minimum since %s (sensor %s reads %.0f mm)",
                  FormatIsoTime(*rf->below_minimum_since).substr(0, 10).c_str(), first->sensor_id.c_str(),
                  first->last_reading_mm);
    rf->reach_note = b;
    return;
  }
  // Within a day plus one loop's wear at the sensor's rate the two dates are the same estimate (an
  // area at the sensor itself differs from the sensor's curve by its quantisation): the area's stands.
  const double tolerance_days = 1.0 + 1.0 / std::max(first->rate_mm_per_day, 1e-3);
  if (rf->reach && DaysBetween(*first->reach, *rf->reach) <= tolerance_days) return;
  rf->reach = first->reach;
  rf->reach_set_by = first->sensor_id;
  for (const SensorForecast* f : members) {
    rf->reach_earliest = Earlier(rf->reach_earliest, f->reach_earliest);
    rf->reach_latest = Earlier(rf->reach_latest, f->reach_latest);
  }
  std::snprintf(b, sizeof b, "set by sensor %s, whose own readings (%.0f mm now) reach the minimum before the area's estimate",
                first->sensor_id.c_str(), first->last_reading_mm);
  rf->reach_note = b;
}

}  // namespace

std::vector<RowForecast> ForecastRows(const CrusherConfig& crusher, const std::vector<ThinnestArea>& areas,
                                      const std::vector<SensorWear>& sensor_wear, const std::vector<SensorForecast>& sensors,
                                      TimePoint now, const ForecastOptions& options) {
  std::map<std::string, double> wear_now;
  for (const auto& w : sensor_wear) wear_now[w.sensor_id] = w.wear_mm;
  std::map<std::string, const SensorForecast*> by_id;
  for (const auto& f : sensors) by_id[f.sensor_id] = &f;

  std::vector<RowForecast> out;
  const double t_now = DaysBetween(crusher.installed_at, now);
  for (const ThinnestArea& area : areas) {
    RowForecast rf;
    rf.row = area.row;
    rf.min_thickness_mm = area.thickness_mm;
    rf.min_thickness_lo_mm = area.lo_mm;
    rf.min_thickness_hi_mm = area.hi_mm;
    double mean_wear = 0;
    const std::vector<const SensorForecast*> members = RowMembers(crusher, area.row, wear_now, by_id, &mean_wear);
    if (!std::isfinite(area.thickness_mm))
      rf.note = "no wear estimate for this row (no row scale)";
    else if (members.empty())
      rf.note = "no sensor with a forecast in this row";
    else if (mean_wear <= 0.0)
      rf.note = "no measurable wear yet";
    else {
      AreaForecast(crusher, area, members, mean_wear, t_now, options, &rf);
      BoundBySensors(crusher, members, t_now, &rf);
    }
    out.push_back(rf);
  }
  return out;
}

void HoldRowForecasts(const std::vector<RowForecast>& previous, std::vector<RowForecast>* current) {
  for (RowForecast& cur : *current) {
    const auto prev = std::find_if(previous.begin(), previous.end(), [&](const RowForecast& p) { return p.row == cur.row; });
    if (prev == previous.end()) continue;
    if (cur.below_minimum_since && prev->below_minimum_since) {
      cur.below_minimum_since = prev->below_minimum_since;
      cur.reach_note = "below minimum since " + FormatIsoTime(*cur.below_minimum_since).substr(0, 10);
      continue;
    }
    if (!cur.reach || !prev->reach) continue;
    const auto inside = [](TimePoint t, const RowForecast& f) {
      return (!f.reach_earliest || t >= *f.reach_earliest) && (!f.reach_latest || t <= *f.reach_latest);
    };
    if (inside(*cur.reach, *prev) && inside(*prev->reach, cur)) {
      cur.reach_estimate = cur.reach;
      cur.reach = prev->reach;
      cur.reach_held = true;
    }
  }
}

}  // namespace lw::core
