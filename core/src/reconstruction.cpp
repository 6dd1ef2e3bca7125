#include "core/reconstruction.hpp"

#include <algorithm>
#include <cstdio>
#include <tuple>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <unordered_map>

namespace lw::core {
namespace {

/// One sensor in its row's least-squares scale: the map's intensity at it and its sd, its wear.
struct ScaleMember {
  size_t row;
  double I, sd, w;
};

/// How far off the map is at the sensors, measured: each sensor of a row with others is predicted
/// from them alone (the row scale without it, times the map at it) and its error set against the
/// model's sd for that prediction (the map at it and at the others; quantisation apart). The
/// factor c^2 pools the sensors' excess-error ratios with `prior_dof` pseudo-sensors at 1 (the
/// model itself), so a few sensors move it only part of the way. The model's map error comes from
/// the map alone (noise law, cross-validation) and, on real LIGGGHTS maps, is often several times
/// what the sensors show; the sensors are the one independent measurement of the pattern there is.
MapCalibration CalibrateAtSensors(const std::vector<ScaleMember>& members, size_t nrows, double q, double prior_dof) {
  MapCalibration out;
  if (!(prior_dof > 0)) return out;
  double sum = 0, excess_sum = 0, pred_sum = 0, model_sum = 0;
  size_t predicted = 0;  // predictions above 0
  for (size_t r = 0; r < nrows; ++r) {
    for (size_t j = 0; j < members.size(); ++j) {
      const ScaleMember& mj = members[j];
      if (mj.row != r) continue;
      double num = 0, den = 0;
      for (size_t i = 0; i < members.size(); ++i)
        if (i != j && members[i].row == r) num += members[i].I * members[i].w, den += members[i].I * members[i].I;
      if (!(den > 0)) continue;
      const double k = num / den;
      // Variance of the prediction k I_j, split into the map's part and quantisation's.
      double map_var = k * k * mj.sd * mj.sd, q_var = q;
      for (size_t i = 0; i < members.size(); ++i) {
        if (i == j || members[i].row != r) continue;
        const double f = mj.I * members[i].I / den;
        map_var += f * f * k * k * members[i].sd * members[i].sd;
        q_var += f * f * q;
      }
      if (!(map_var > 0)) continue;
      const double e = mj.w - k * mj.I, pred = k * mj.I, excess = std::max(0.0, e * e - q_var);
      sum += excess / map_var;
      if (pred > 0) excess_sum += excess, pred_sum += pred * pred, model_sum += map_var, ++predicted;
      ++out.sensors;
    }
  }
  out.factor = std::min(4.0, std::sqrt((sum + prior_dof) / (static_cast<double>(out.sensors) + prior_dof)));
  // The relative error of predicting a point from the other sensors of its row: what a point no
  // sensor checks (one sensor's row scale, a face beyond every sensor's reach) is off by. A ratio
  // of sums (squared excess errors over squared predictions), so that a sensor the map predicts
  // little wear at does not stand for the rest; pooled with prior_dof pseudo-sensors, each at the
  // mean squared prediction and the model's own calibrated relative error.
  if (predicted > 0) {
    const double mean_pred = pred_sum / static_cast<double>(predicted);
    const double prior = out.factor * out.factor * model_sum / pred_sum;
    out.point_rel_sd =
        std::min(1.0, std::sqrt((excess_sum + prior_dof * prior * mean_pred) / (pred_sum + prior_dof * mean_pred)));
    return out;
  }
  // Nothing predicted (no row with two reporting sensors): the prior alone, the model's relative
  // error of a sensor predicted from one row mate as uncertain as itself (both errors; with more
  // mates a prediction carries less of theirs), so that losing a row's second sensor never narrows
  // a band on a map whose error the model states. Over the sensors, a ratio of sums.
  double var_sum = 0, i_sum = 0;
  for (const ScaleMember& m : members) var_sum += 2.0 * m.sd * m.sd, i_sum += m.I * m.I;
  if (i_sum > 0) out.point_rel_sd = std::min(1.0, out.factor * std::sqrt(var_sum / i_sum));
  return out;
}

// Weighted mean of `values` near (z, theta) on the surface; nearest face when none is within r.
double LocalMean(const WearMap& map, const Eigen::VectorXd& values, double z, double theta_deg, double r) {
  double sw = 0, swv = 0, best = std::numeric_limits<double>::max();
  Eigen::Index nearest = 0;
  for (Eigen::Index i = 0; i < map.z.size(); ++i) {
    const double dz = map.z[i] - z;
    if (std::abs(dz) > std::max(r, best)) continue;
    const double d = SurfaceDistance(dz, map.radius[i], map.theta_deg[i], theta_deg);
    if (d < best) {
      best = d;
      nearest = i;
    }
    if (d <= r) {
      sw += map.areas[i];
      swv += map.areas[i] * values[i];
    }
  }
  return sw > 0 ? swv / sw : values[nearest];
}

}  // namespace

double NearestSensorDistance(const std::vector<const SensorInfo*>& sensors, const RadiusProfile& radius, double z_m,
                             double theta_deg, bool around, double within_m) {
  // Squared distances, one square root at the end: the per-face loop asks this of every face.
  const double inf = std::numeric_limits<double>::infinity();
  const double within2 = within_m < inf ? within_m * within_m : inf;
  double best2 = inf;
  for (const SensorInfo* s : sensors) {
    const double dz = s->z_m - z_m;
    if (dz * dz > std::min(best2, within2)) continue;  // the distance is at least |dz|
    double d2 = dz * dz;
    if (around) {
      const double arc = radius.At(0.5 * (s->z_m + z_m)) * AngleDiffDeg(s->theta_deg, theta_deg) * (M_PI / 180.0);
      d2 += arc * arc;
    }
    if (d2 <= within2) best2 = std::min(best2, d2);
  }
  return best2 < inf ? std::sqrt(best2) : inf;
}

Eigen::VectorXd SmoothOverSurface(const WearMap& map, const Eigen::VectorXd& values, double radius_m) {
  const Eigen::Index n = values.size();
  if (radius_m <= 0 || n == 0) return values;
  const SurfaceIndex index(map, radius_m);
  Eigen::VectorXd out(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    double sw = 0, swv = 0;
    index.ForEachWithin(map.z[i], map.theta_deg[i], map.radius[i], [&](uint32_t j, double) {
      sw += map.areas[static_cast<Eigen::Index>(j)];
      swv += map.areas[static_cast<Eigen::Index>(j)] * values[static_cast<Eigen::Index>(j)];
    });
    out[i] = sw > 0 ? swv / sw : values[i];
  }
  return out;
}

Eigen::VectorXd IntensityAtSensors(const CrusherConfig& crusher, const WearMap& map, double radius_m) {
  Eigen::VectorXd out(static_cast<Eigen::Index>(crusher.sensors.size()));
  for (size_t s = 0; s < crusher.sensors.size(); ++s) {
    out[static_cast<Eigen::Index>(s)] = LocalMean(map, map.wear, crusher.sensors[s].z_m, crusher.sensors[s].theta_deg, radius_m);
  }
  return out;
}

std::vector<size_t> LatestReadingIndices(const CrusherConfig& crusher, const std::vector<Reading>& readings, TimePoint at) {
  std::map<std::string, size_t> latest;
  for (size_t i = 0; i < readings.size(); ++i) {
    const Reading& r = readings[i];
    if (r.time > at || !crusher.OfThisLiner(r.sensor_id, r.time, r.thickness_mm)) continue;
    const auto [it, fresh] = latest.try_emplace(r.sensor_id, i);
    const Reading& l = readings[it->second];
    // Same time twice (a duplicate): the thinner reading, since wear only goes one way.
    if (!fresh && (r.time > l.time || (r.time == l.time && r.thickness_mm < l.thickness_mm))) it->second = i;
  }
  std::vector<size_t> out;
  for (const auto& s : crusher.sensors) {
    const auto it = latest.find(s.id);
    if (it != latest.end()) out.push_back(it->second);
  }
  return out;
}

std::vector<SensorWear> SensorWearFrom(const CrusherConfig& crusher, const std::vector<Reading>& readings,
                                       const std::vector<size_t>& indices, bool interval_centre) {
  std::vector<SensorWear> out;
  for (const size_t i : indices) {
    const Reading& r = readings[i];
    const SensorInfo& s = *crusher.FindSensor(r.sensor_id);
    const double thickness = r.thickness_mm + (interval_centre ? 0.5 : 0.0);
    out.push_back({s.id, std::max(0.0, s.thickness_new_mm - thickness)});
  }
  return out;
}

std::vector<SensorWear> SensorWearAt(const CrusherConfig& crusher, const std::vector<Reading>& readings, TimePoint at,
                                     bool interval_centre) {
  return SensorWearFrom(crusher, readings, LatestReadingIndices(crusher, readings, at), interval_centre);
}

std::vector<size_t> FreshReadingIndices(const CrusherConfig& crusher, const std::vector<Reading>& readings, TimePoint at,
                                        const Staleness& rule, std::vector<std::string>* stale) {
  std::vector<size_t> latest = LatestReadingIndices(crusher, readings, at);
  if (latest.empty()) return latest;
  TimePoint newest = readings[latest.front()].time;
  for (const size_t i : latest) newest = std::max(newest, readings[i].time);
  std::map<std::string, std::vector<TimePoint>> times;
  for (const Reading& r : readings)
    if (crusher.OfThisLiner(r.sensor_id, r.time, r.thickness_mm)) times[r.sensor_id].push_back(r.time);
  std::erase_if(latest, [&](size_t i) {
    std::vector<TimePoint>& t = times[readings[i].sensor_id];
    std::sort(t.begin(), t.end());
    const TimePoint from = AddDays(t.back(), -rule.history_days);
    std::vector<double> gaps;
    for (size_t k = 1; k < t.size(); ++k)
      if (t[k - 1] >= from && t[k] > t[k - 1]) gaps.push_back(DaysBetween(t[k - 1], t[k]));
    double typical = 0.0;
    if (!gaps.empty()) {
      std::nth_element(gaps.begin(), gaps.begin() + static_cast<std::ptrdiff_t>(gaps.size() / 2), gaps.end());
      typical = gaps[gaps.size() / 2];
    }
    const bool old = DaysBetween(readings[i].time, newest) > std::max(rule.min_days, rule.periods * typical);
    if (old && stale) stale->push_back(readings[i].sensor_id);
    return old;
  });
  return latest;
}

namespace {

// A sensor's (time, thickness) by time: its readings in its window up to its latest, at one time the
// thicker first (so that the last is the one LatestReadingIndices selects), after its record lows
// before the window.
using Series = std::vector<std::pair<TimePoint, double>>;

// The wear a series shows gradually between `from` and `to`: falls of its running minimum of at most
// max_step_mm, from its last point at or before `from` (else its first) to its last at or before `to`.
double GradualDrop(const Series& s, TimePoint from, TimePoint to, double max_step_mm) {
  size_t k = 0;
  for (size_t j = 0; j < s.size() && s[j].first <= from; ++j) k = j;
  if (s.empty() || s[k].first > to) return 0.0;
  double low = s[k].second, drop = 0.0;
  for (size_t j = k + 1; j < s.size() && s[j].first <= to; ++j) {
    if (s[j].second >= low) continue;
    if (low - s[j].second <= max_step_mm) drop += low - s[j].second;
    low = s[j].second;
  }
  return drop;
}

}  // namespace

std::vector<size_t> WithoutStuckSensors(const CrusherConfig& crusher, const std::vector<Reading>& readings,
                                        std::vector<size_t> indices, const StuckRule& rule, std::vector<std::string>* stuck) {
  std::map<std::string, size_t> selected;  // sensor -> its reading in `indices`
  for (const size_t i : indices) selected[readings[i].sensor_id] = i;
  // Each sensor's readings in its window, and before the window its record lows: each new lowest
  // whole-mm thickness (loop), when first read (the thinnest reading of that time). They give its
  // running minimum at any earlier time, to the loop, all the rule needs of those days (a run's start
  // and the step before it, a mate's wear then and its gradual wear since) and what the server keeps
  // of them (at most one per loop, whatever the readings).
  std::map<std::string, Series> series;
  std::map<std::string, std::map<TimePoint, double>> before;  // thinnest reading per time, before the window
  // Before the window, the time of the newest reading a loop above the sensor's latest value: a run
  // that reaches back before the window began after it (a loop read intact again since its record low).
  std::map<std::string, TimePoint> above;
  for (const Reading& r : readings) {
    const auto it = selected.find(r.sensor_id);
    if (it == selected.end()) continue;
    const TimePoint latest = readings[it->second].time;
    const double window =
        std::max(rule.history_days, rule.history_fraction * std::max(0.0, DaysBetween(crusher.installed_at, latest)));
    if (r.time > latest || !crusher.OfThisLiner(r.sensor_id, r.time, r.thickness_mm)) continue;
    if (r.time < AddDays(latest, -window)) {
      const auto [b, fresh] = before[r.sensor_id].try_emplace(r.time, r.thickness_mm);
      if (!fresh) b->second = std::min(b->second, r.thickness_mm);
      if (std::floor(r.thickness_mm) > std::floor(readings[it->second].thickness_mm)) {
        const auto [a, first] = above.try_emplace(r.sensor_id, r.time);
        if (!first) a->second = std::max(a->second, r.time);
      }
      continue;
    }
    series[r.sensor_id].emplace_back(r.time, r.thickness_mm);
  }
  for (auto& [id, s] : series)
    std::sort(s.begin(), s.end(),
              [](const auto& a, const auto& b) { return a.first < b.first || (a.first == b.first && a.second > b.second); });
  for (const auto& [id, by_time] : before) {
    Series lows;
    for (const auto& [t, mm] : by_time)
      if (lows.empty() || std::floor(mm) < std::floor(lows.back().second)) lows.emplace_back(t, mm);
    Series& s = series[id];
    s.insert(s.begin(), lows.begin(), lows.end());
  }
  // A sensor's thickness reading at its last point at or before t (else its first).
  auto reading_at = [&](const std::string& id, TimePoint t) {
    const Series& s = series[id];
    size_t k = 0;
    for (size_t j = 0; j < s.size() && s[j].first <= t; ++j) k = j;
    return s[k].second;
  };
  // The flat run each sensor ends with: its first time, or nothing when the sensor is not judged
  // (fewer than min_readings, consumed, or the run began with a step: a crack cut loops early and
  // the value waits for the wear to catch up, which the diagnosis names). A run that fills the
  // window reaches back to the record low of its value when there is one (the value froze before
  // the window), and its step is the one from the record low before; unless the sensor read above
  // its value after that (a loop read intact again): the run then began after its last such reading
  // (taken as the run's start; its first step is no crack's).
  std::map<std::string, TimePoint> flat_from;
  for (const size_t i : indices) {
    const Reading& r = readings[i];
    const Series& s = series[r.sensor_id];
    size_t flat = 0;
    while (flat < s.size() && s[s.size() - 1 - flat].second == r.thickness_mm) ++flat;
    if (r.thickness_mm < 1.0 || flat < rule.min_readings) continue;
    const TimePoint from = s[s.size() - flat].first;
    const auto a = above.find(r.sensor_id);
    if (a != above.end() && a->second > from) {  // read above its value since its record low: the run began after
      flat_from[r.sensor_id] = a->second;
      continue;
    }
    if (flat < s.size()) {
      // The fall into the run, less what the sensor's own mean rate (to the run's start) explains
      // over the time since the point before it (readings missing for days: a radio outage).
      const auto& [before_t, before_mm] = s[s.size() - 1 - flat];
      const double days = DaysBetween(crusher.installed_at, from);
      const double rate = days > 0 ? std::max(0.0, crusher.FindSensor(r.sensor_id)->thickness_new_mm - before_mm) / days : 0.0;
      if (before_mm - r.thickness_mm - rate * DaysBetween(before_t, from) > rule.max_step_mm) continue;
    }
    flat_from[r.sensor_id] = from;
  }
  // What the sensor should have lost over its flat run at each row mate's rate (mates in `skip` left
  // out): the mate's gradual wear over those days times the sensor's wear over the mate's when the
  // run began, the sensor's taken low (reading n: more than new - n - 1 mm, less the mounting
  // tolerance) and the mate's high (at most new - n), so that neither the quantisation nor where the
  // sensor's first loop sits makes a slow sensor look stuck.
  auto expected_losses = [&](size_t i, const std::set<std::string>& skip) {
    const Reading& r = readings[i];
    const TimePoint from = flat_from.at(r.sensor_id);
    const SensorInfo& me = *crusher.FindSensor(r.sensor_id);
    const double own = std::max(0.0, me.thickness_new_mm - (r.thickness_mm + 1.0 + rule.mounting_mm));
    std::vector<double> expected;
    for (const auto& [id, j] : selected) {
      const SensorInfo& mate = *crusher.FindSensor(id);
      if (id == r.sensor_id || mate.row != me.row || skip.contains(id)) continue;
      const double mate_wear = mate.thickness_new_mm - reading_at(id, from);
      if (mate_wear < rule.min_mate_wear_mm) continue;
      expected.push_back(own / mate_wear * GradualDrop(series[id], from, r.time, rule.max_step_mm));
    }
    std::sort(expected.begin(), expected.end());
    return expected;
  };
  // Suspects: by their largest expected loss. Then each suspect against the mates that are not
  // suspects themselves (two sensors stuck in a row of three must not vouch for each other): the
  // median (with two, the smaller).
  std::set<std::string> suspects;
  for (const size_t i : indices) {
    if (!flat_from.contains(readings[i].sensor_id)) continue;
    const std::vector<double> e = expected_losses(i, {});
    if (!e.empty() && e.back() >= rule.expected_mm) suspects.insert(readings[i].sensor_id);
  }
  std::erase_if(indices, [&](size_t i) {
    if (!suspects.contains(readings[i].sensor_id)) return false;
    const std::vector<double> e = expected_losses(i, suspects);
    const bool is_stuck = !e.empty() && e[(e.size() - 1) / 2] >= rule.expected_mm;
    if (is_stuck && stuck) stuck->push_back(readings[i].sensor_id);
    return is_stuck;
  });
  return indices;
}

std::vector<size_t> LiveReadingIndices(const CrusherConfig& crusher, const std::vector<Reading>& readings, TimePoint at,
                                       std::vector<std::string>* stale, std::vector<std::string>* stuck) {
  return WithoutStuckSensors(crusher, readings, FreshReadingIndices(crusher, readings, at, {}, stale), {}, stuck);
}

std::vector<SensorWear> FreshSensorWearAt(const CrusherConfig& crusher, const std::vector<Reading>& readings, TimePoint at,
                                          const Staleness& rule, std::vector<std::string>* stale, bool interval_centre) {
  return SensorWearFrom(crusher, readings, FreshReadingIndices(crusher, readings, at, rule, stale), interval_centre);
}

std::vector<SensorWear> ScanSensorWear(const CrusherConfig& crusher, const std::vector<Reading>& readings, TimePoint scan_date,
                                       const std::vector<std::string>& stuck, TimePoint now, bool interval_centre) {
  std::vector<size_t> at_scan = FreshReadingIndices(crusher, readings, scan_date);
  if (!stuck.empty()) {
    std::map<std::string, double> frozen;  // stuck sensor -> its value now
    for (const size_t i : LatestReadingIndices(crusher, readings, now))
      if (std::find(stuck.begin(), stuck.end(), readings[i].sensor_id) != stuck.end())
        frozen[readings[i].sensor_id] = readings[i].thickness_mm;
    std::erase_if(at_scan, [&](size_t i) {
      const auto it = frozen.find(readings[i].sensor_id);
      return it != frozen.end() && it->second == readings[i].thickness_mm;
    });
  }
  return SensorWearFrom(crusher, readings, at_scan, interval_centre);
}

ReconstructionPlan PrepareReconstruction(const CrusherConfig& crusher, const WearMap& map, const ReconstructionOptions& options) {
  return PrepareReconstruction(crusher, map, BuildMapModel(map, options.map_model), options);
}

ReconstructionPlan PrepareReconstruction(const CrusherConfig& crusher, const WearMap& map, MapModel model,
                                         const ReconstructionOptions& options) {
  ReconstructionPlan p;
  p.crusher = &crusher;
  p.map = &map;
  p.options = options;
  p.model = std::move(model);
  p.model.map = &map;
  p.intensity = p.model.intensity;
  p.intensity_rel_sd.resize(p.intensity.size());
  for (Eigen::Index i = 0; i < p.intensity.size(); ++i) p.intensity_rel_sd[i] = p.model.RelSd(i);
  p.sensor_intensity.resize(static_cast<Eigen::Index>(crusher.sensors.size()));
  p.sensor_intensity_sd.resize(static_cast<Eigen::Index>(crusher.sensors.size()));
  for (size_t s = 0; s < crusher.sensors.size(); ++s) {
    // The same kernel as the faces: Eq. 9's W_i0 is the intensity the faces around the sensor get.
    const MapModel::Point at = p.model.At(crusher.sensors[s].z_m, crusher.sensors[s].theta_deg);
    p.sensor_intensity[static_cast<Eigen::Index>(s)] = at.intensity;
    p.sensor_intensity_sd[static_cast<Eigen::Index>(s)] = at.sd;
  }
  p.radius = RadiusProfile(map);
  const double reach = crusher.thinnest_area.sensor_reach_m;
  p.within_reach_m = reach;
  p.within_reach.assign(crusher.sensors.size(), std::vector<uint8_t>(map.face_count(), 0));
  for (size_t s = 0; s < crusher.sensors.size(); ++s) {
    const std::vector<const SensorInfo*> one = {&crusher.sensors[s]};
    for (Eigen::Index i = 0; i < map.z.size(); ++i)
      p.within_reach[s][static_cast<size_t>(i)] =
          NearestSensorDistance(one, p.radius, map.z[i], map.theta_deg[i], true, reach) <= reach;
  }
  p.face_row.assign(map.face_count(), -1);
  for (Eigen::Index i = 0; i < map.z.size(); ++i) {
    for (size_t r2 = 0; r2 < crusher.rows.size(); ++r2) {
      const auto& row = crusher.rows[r2];
      if (map.z[i] >= row.z_min_m && map.z[i] <= row.z_max_m) {
        p.face_row[static_cast<size_t>(i)] = static_cast<int>(r2);
        break;
      }
    }
  }
  return p;
}

Reconstruction Reconstruct(const ReconstructionPlan& plan, const std::vector<SensorWear>& sensor_wear) {
  Reconstruction out;
  ReconstructInto(plan, sensor_wear, &out);
  return out;
}

namespace {

/// Whether a face lies beyond the reach of every sensor that sets a row scale: from the plan's
/// masks, or measured when the crusher's reach is not the one they were made for.
class ReachCheck {
 public:
  ReachCheck(const ReconstructionPlan& plan, const std::vector<size_t>& setting) : plan_(plan), setting_(setting) {
    const CrusherConfig& c = *plan.crusher;
    reach_ = c.thinnest_area.sensor_reach_m;
    masks_ = plan.within_reach_m == reach_ && plan.within_reach.size() == c.sensors.size();
    if (!masks_)
      for (size_t s : setting) sensors_.push_back(&c.sensors[s]);
  }
  bool Beyond(Eigen::Index i) const {
    if (!masks_) {
      const WearMap& m = *plan_.map;
      return !(NearestSensorDistance(sensors_, plan_.radius, m.z[i], m.theta_deg[i], true, reach_) <= reach_);
    }
    for (size_t s : setting_)
      if (plan_.within_reach[s][static_cast<size_t>(i)]) return false;
    return true;
  }

 private:
  const ReconstructionPlan& plan_;
  const std::vector<size_t>& setting_;
  double reach_ = 0;
  bool masks_ = false;
  std::vector<const SensorInfo*> sensors_;  // the measured path's
};

/// Eq. 9 per row, as fitted at the sensors.
struct RowScales {
  std::vector<double> scale;              ///< mm per intensity unit; NaN: a row without sensors
  std::vector<double> var;                ///< its variance
  std::vector<size_t> used;               ///< sensors that count in each row
  std::vector<size_t> without_intensity;  ///< sensors (index) in a row where the map has no intensity
  std::vector<size_t> setting;            ///< the sensors (index) that set a row scale
  MapCalibration calibration;
};

constexpr double kQuantisationVar = 1.0 / 12.0;  // a reading n: thickness uniform in [n, n+1)
constexpr double kUnmeasuredRowRel = 0.3;        // a row without sensors borrows its neighbours' scale

RowScales FitRowScales(const ReconstructionPlan& plan, const std::vector<SensorWear>& sensor_wear) {
  const CrusherConfig& crusher = *plan.crusher;
  const size_t nrows = crusher.rows.size();
  RowScales out;
  std::vector<double> num(nrows, 0.0), den(nrows, 0.0);
  std::vector<size_t>& used = out.used;
  used.assign(nrows, 0);
  std::vector<size_t>& without_intensity = out.without_intensity;
  std::vector<ScaleMember> members;
  for (const auto& sw : sensor_wear) {
    for (size_t s = 0; s < crusher.sensors.size(); ++s) {
      if (crusher.sensors[s].id != sw.sensor_id) continue;
      const int row = crusher.RowIndex(crusher.sensors[s].row);
      const double I = plan.sensor_intensity[static_cast<Eigen::Index>(s)];
      if (row >= 0 && !(I > 0)) without_intensity.push_back(s);
      if (row < 0 || !(I > 0)) break;
      num[static_cast<size_t>(row)] += I * sw.wear_mm;
      den[static_cast<size_t>(row)] += I * I;
      ++used[static_cast<size_t>(row)];
      members.push_back({static_cast<size_t>(row), I, plan.sensor_intensity_sd[static_cast<Eigen::Index>(s)], sw.wear_mm});
      out.setting.push_back(s);
      break;
    }
  }
  out.calibration = CalibrateAtSensors(members, nrows, kQuantisationVar, plan.options.calibration_prior_dof);
  for (ScaleMember& m : members) m.sd *= out.calibration.factor;
  std::vector<double>& row_scale = out.scale;
  std::vector<double>& row_var = out.var;
  row_scale.assign(nrows, std::numeric_limits<double>::quiet_NaN());
  row_var.assign(nrows, 0.0);
  for (size_t r = 0; r < nrows; ++r) {
    if (den[r] > 0) row_scale[r] = num[r] / den[r];
  }
  // Scale variance: quantisation of each reading and the map's error at each sensor, or the
  // sensors' own scatter about the row's line when that is larger (>= 2 sensors).
  for (size_t r = 0; r < nrows; ++r) {
    if (!(den[r] > 0)) continue;
    const double k = row_scale[r];
    double v = 0, rss = 0;
    for (const ScaleMember& m : members) {
      if (m.row != r) continue;
      v += m.I * m.I * (kQuantisationVar + k * k * m.sd * m.sd);
      rss += std::pow(m.w - k * m.I, 2);
    }
    v /= den[r] * den[r];
    if (used[r] >= 2) v = std::max(v, rss / static_cast<double>(used[r] - 1) / den[r]);
    // One sensor has no scatter of its own to show how wrong the map's pattern along its row is:
    // its scale carries the error of a point predicted from its row mates (point_rel_sd, as the
    // other rows' sensors measure it, or the model's own when no row has two), not none.
    if (used[r] == 1) v = std::max(v, std::pow(k * out.calibration.point_rel_sd, 2));
    row_var[r] = v;
  }
  return out;
}

/// The scale (mm per intensity unit) and its variance at any height, from the rows with sensors
/// (the knots, at their rows' centres): stepping, a row's own scale (a row without sensors takes
/// the nearest knot's); or piecewise linear in z between the knots, clamped beyond the first and
/// last. The variance: the interpolation weights on the knots' variances; a borrowed scale (a row
/// without sensors) carries kUnmeasuredRowRel more. The rows' summaries and every face use it.
class ScaleProfile {
 public:
  ScaleProfile(const CrusherConfig& crusher, const RowScales& rows, bool interpolate)
      : row_scale_(rows.scale), row_var_(rows.var), borrowed_(rows.scale.size() + 1, 0), interpolate_(interpolate) {
    const size_t nrows = crusher.rows.size();
    for (size_t r = 0; r < nrows; ++r) borrowed_[r + 1] = std::isnan(rows.scale[r]) ? 1 : 0;
    std::vector<std::tuple<double, double, double>> k3;
    for (size_t r = 0; r < nrows; ++r)
      if (rows.used[r] > 0)
        k3.emplace_back(0.5 * (crusher.rows[r].z_min_m + crusher.rows[r].z_max_m), rows.scale[r], rows.var[r]);
    std::sort(k3.begin(), k3.end());
    for (const auto& [z, k, v] : k3) {
      kz_.push_back(z);
      k0_.push_back(k);
      kvar_.push_back(v);
    }
    for (size_t k = 0; k < kz_.size(); ++k)
      slope_.push_back(k + 1 < kz_.size() && kz_[k + 1] > kz_[k] ? (k0_[k + 1] - k0_[k]) / (kz_[k + 1] - kz_[k]) : 0.0);
  }

  bool empty() const { return kz_.empty(); }

  /// {scale, variance} at height `z` in row `row` (-1: in no row); {0, 0} when empty().
  // Inlined, on the rows' data held here: it is the per-face loop's body (lw_bench_reconstruction:
  // about 15 ms a million faces instead of 9 without either).
  [[gnu::always_inline]] std::pair<double, double> At(double z, int row) const {
    if (kz_.empty()) return {0.0, 0.0};
    const bool borrowed = borrowed_[static_cast<size_t>(row + 1)];
    double scale, var;
    if (!interpolate_ && row >= 0 && !borrowed) return {row_scale_[static_cast<size_t>(row)], row_var_[static_cast<size_t>(row)]};
    const size_t nk = kz_.size();
    size_t k = 0;  // z in (kz_[k], kz_[k + 1]], or beyond the ends
    while (k + 1 < nk && z > kz_[k + 1]) ++k;
    if (z <= kz_[0]) {
      var = kvar_[0];
      scale = k0_[0];
    } else if (k + 1 < nk) {
      const double f = (z - kz_[k]) / (kz_[k + 1] - kz_[k]);
      var = (1 - f) * (1 - f) * kvar_[k] + f * f * kvar_[k + 1];
      scale = k0_[k] + (z - kz_[k]) * slope_[k];
    } else {
      var = kvar_[nk - 1];
      scale = k0_[nk - 1];
    }
    if (!interpolate_) scale = Nearest(z);
    if (borrowed) var += kUnmeasuredRowRel * kUnmeasuredRowRel * scale * scale;
    return {scale, var};
  }

 private:
  double Nearest(double z) const {
    double best = std::numeric_limits<double>::max(), s = k0_.front();
    for (size_t k = 0; k < kz_.size(); ++k) {
      if (std::abs(kz_[k] - z) < best) {
        best = std::abs(kz_[k] - z);
        s = k0_[k];
      }
    }
    return s;
  }

  std::vector<double> row_scale_, row_var_;  // per row, as RowScales
  std::vector<char> borrowed_;               // by row index + 1: a row without sensors
  bool interpolate_;
  std::vector<double> kz_, k0_, kvar_, slope_;  // per knot: z, scale, variance, slope to the next
};

/// No row scale (no sensor reading in any row, or none where the map has intensity): the map alone
/// says nothing in mm, so every figure is NaN and the status says why.
void WithoutScale(const RowScales& fit, Reconstruction& out) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  out.wear_mm.setConstant(nan);
  out.remaining_mm.setConstant(nan);
  out.remaining_sd_mm.setConstant(nan);
  out.scale_sd_mm.setConstant(nan);
  out.wear_estimate_mm.setConstant(nan);
  out.min_thickness_mm = out.min_thickness_lo_mm = out.min_thickness_hi_mm = nan;
  out.min_face = 0;
  for (auto& r : out.rows) r.min_thickness_mm = r.min_thickness_lo_mm = r.min_thickness_hi_mm = r.mean_wear_mm = nan;
  out.status = kStatusNoSensors;
  out.status_detail = fit.without_intensity.empty()
                          ? "no sensor reading in any row: the map's intensity cannot be scaled into mm"
                          : "the sensors that report sit where the map has no wear intensity: no row scale";
}

/// The rows' thinnest points and mean wear from the faces' sums, and whether the thinnest point's
/// number is supported (its standard error within max_rel_sd of its wear).
void FinishSummary(const ReconstructionPlan& plan, const std::vector<double>& wear_sum, const std::vector<double>& area_sum,
                   Reconstruction& out) {
  const CrusherConfig& crusher = *plan.crusher;
  const WearMap& map = *plan.map;
  const size_t nrows = crusher.rows.size();
  const Eigen::Index n = static_cast<Eigen::Index>(map.face_count());
  const double new_mm = crusher.thickness_new_mm;
  const double min_all = out.min_thickness_mm;
  const size_t min_face = out.min_face;
  for (size_t r = 0; r < nrows; ++r) {
    const size_t f = out.rows[r].min_face;
    if (area_sum[r] > 0) {
      out.rows[r].min_z_m = map.z[static_cast<Eigen::Index>(f)];
      out.rows[r].min_theta_deg = map.theta_deg[static_cast<Eigen::Index>(f)];
    }
  }
  for (size_t r = 0; r < nrows; ++r) {
    out.rows[r].mean_wear_mm = area_sum[r] > 0 ? wear_sum[r] / area_sum[r] : 0.0;
    if (area_sum[r] == 0)
      out.rows[r].min_thickness_mm = out.rows[r].min_thickness_lo_mm = out.rows[r].min_thickness_hi_mm = crusher.thickness_new_mm;
  }
  // Can the map and sensors support the thinnest-point number?
  if (n > 0) {
    const double wear_min = new_mm - min_all;
    const double sd_min = out.remaining_sd_mm[static_cast<Eigen::Index>(min_face)];
    if (wear_min > 0 && sd_min / wear_min > plan.options.max_rel_sd) {
      out.status = kStatusUnsupported;
      char b[200];
      std::snprintf(
          b, sizeof b,
          "the thinnest point's wear has a %.0f %% standard error (map noise, sensor quantisation, row scale): band only",
          100.0 * sd_min / wear_min);
      out.status_detail = b;
    }
  }
}

}  // namespace

void ReconstructInto(const ReconstructionPlan& plan, const std::vector<SensorWear>& sensor_wear, Reconstruction* result) {
  const CrusherConfig& crusher = *plan.crusher;
  const WearMap& map = *plan.map;
  const size_t nrows = crusher.rows.size();
  const RowScales fit = FitRowScales(plan, sensor_wear);
  const ScaleProfile profile(crusher, fit, plan.options.interpolate_between_rows);
  const std::vector<double>& row_scale = fit.scale;
  const MapCalibration& calibration = fit.calibration;
  Reconstruction& out = *result;
  out.calibration = calibration;
  const Eigen::Index n = static_cast<Eigen::Index>(map.face_count());
  out.wear_mm.resize(n);  // no reallocation when `result` already holds arrays of this size
  out.remaining_mm.resize(n);
  out.remaining_sd_mm.resize(n);
  out.scale_sd_mm.resize(n);
  out.wear_estimate_mm.resize(n);
  out.min_thickness_mm = std::numeric_limits<double>::max();
  out.rows.resize(nrows);
  out.status = kStatusOk;
  out.status_detail.clear();
  out.worn_through_faces = 0;
  out.maybe_worn_through_faces = 0;
  std::vector<double> wear_sum(nrows, 0.0), area_sum(nrows, 0.0);
  for (size_t r = 0; r < nrows; ++r) {
    const double zc = 0.5 * (crusher.rows[r].z_min_m + crusher.rows[r].z_max_m);
    out.rows[r].row = crusher.rows[r].name;
    const auto [scale, var] = profile.At(zc, static_cast<int>(r));
    out.rows[r].scale_mm_per_unit = std::isnan(row_scale[r]) ? scale : row_scale[r];
    out.rows[r].scale_sd = std::sqrt(var);
    out.rows[r].min_thickness_mm = std::numeric_limits<double>::max();
    out.rows[r].min_thickness_lo_mm = std::numeric_limits<double>::max();
    out.rows[r].min_thickness_hi_mm = std::numeric_limits<double>::max();
    out.rows[r].sensors_used = fit.used[r];
    out.rows[r].worn_through_faces = 0;
  }
  const double new_mm = crusher.thickness_new_mm;
  if (profile.empty()) {
    WithoutScale(fit, out);
    return;
  }
  // Per face scale: when stepping, a face in a row takes the row's (as its summary reports it);
  // otherwise, and outside the rows, the profile's at the face's height.
  std::vector<double> step_scale(nrows + 1, 0.0), step_var(nrows + 1, 0.0);  // by row index + 1
  if (!plan.options.interpolate_between_rows) {
    for (size_t r = 0; r < nrows; ++r) {
      step_scale[r + 1] = out.rows[r].scale_mm_per_unit;
      step_var[r + 1] = out.rows[r].scale_sd * out.rows[r].scale_sd;
    }
  }
  const double band = plan.options.band_sigmas;
  const double point_rel = calibration.point_rel_sd;
  const ReachCheck reach(plan, fit.setting);
  const double* intensity = plan.intensity.data();
  const double* z = map.z.data();
  const double* area = map.areas.data();
  const int* face_row = plan.face_row.data();
  double* wear_out = out.wear_mm.data();
  double* remaining_out = out.remaining_mm.data();
  double* sd_out = out.remaining_sd_mm.data();
  double* scale_sd_out = out.scale_sd_mm.data();
  double* estimate_out = out.wear_estimate_mm.data();
  const bool stepping = !plan.options.interpolate_between_rows;
  double min_all = std::numeric_limits<double>::max(), lo_all = min_all, hi_all = min_all;
  size_t min_face = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    const int r = face_row[i];
    double scale, svar;
    if (stepping && r >= 0) {
      scale = step_scale[static_cast<size_t>(r) + 1];
      svar = step_var[static_cast<size_t>(r) + 1];
    } else {
      std::tie(scale, svar) = profile.At(z[i], r);
    }
    const double w_est = std::max(0.0, intensity[i] * scale);
    double map_sd = ModelMapSd(plan, calibration, i, w_est);
    // Beyond every scale-setting sensor's reach nothing checks the map's pattern: its error there is
    // at least what the sensors show when each is predicted from its row mates (the window spread of
    // a finite DEM run can call an edge hot spot precise that the sensors' residuals say is not).
    if (w_est * point_rel > map_sd && reach.Beyond(i)) map_sd = w_est * point_rel;
    const double sd = std::sqrt(map_sd * map_sd + intensity[i] * intensity[i] * svar);
    // Physical: wear within [0, new]; a face whose estimate reaches the as-new thickness is worn through.
    const double w = std::min(w_est, new_mm);
    const double rem = new_mm - w;
    wear_out[i] = w;
    remaining_out[i] = rem;
    sd_out[i] = sd;
    scale_sd_out[i] = intensity[i] * std::sqrt(svar);
    estimate_out[i] = w_est;
    const double lo = std::max(0.0, rem - band * sd), hi = std::min(new_mm, rem + band * sd);
    if (w_est >= new_mm) ++out.worn_through_faces;
    if (lo <= 0.0) ++out.maybe_worn_through_faces;
    if (rem < min_all) {
      min_all = rem;
      min_face = static_cast<size_t>(i);
    }
    lo_all = std::min(lo_all, lo);
    hi_all = std::min(hi_all, hi);
    if (r < 0) continue;
    const size_t ru = static_cast<size_t>(r);
    wear_sum[ru] += area[i] * w;
    area_sum[ru] += area[i];
    RowSummary& row = out.rows[ru];
    if (w_est >= new_mm) ++row.worn_through_faces;
    if (rem < row.min_thickness_mm) {
      row.min_thickness_mm = rem;
      row.min_face = static_cast<size_t>(i);
    }
    row.min_thickness_lo_mm = std::min(row.min_thickness_lo_mm, lo);
    row.min_thickness_hi_mm = std::min(row.min_thickness_hi_mm, hi);
  }
  out.min_thickness_mm = min_all;
  out.min_face = min_face;
  out.min_thickness_lo_mm = lo_all;
  out.min_thickness_hi_mm = hi_all;
  FinishSummary(plan, wear_sum, area_sum, out);
}

Reconstruction Reconstruct(const CrusherConfig& crusher, const WearMap& map, const std::vector<SensorWear>& sensor_wear,
                           const ReconstructionOptions& options) {
  return Reconstruct(PrepareReconstruction(crusher, map, options), sensor_wear);
}

}  // namespace lw::core
