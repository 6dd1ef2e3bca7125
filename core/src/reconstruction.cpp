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

#include "core/angles.hpp"

namespace lw::core {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

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
  double sum = 0;
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
      const double e = mj.w - k * mj.I;
      sum += std::max(0.0, e * e - q_var) / map_var;
      ++out.sensors;
    }
  }
  out.factor = std::min(4.0, std::sqrt((sum + prior_dof) / (static_cast<double>(out.sensors) + prior_dof)));
  return out;
}

// Weighted mean of `values` near (z, theta) on the surface; nearest face when none is within r.
double LocalMean(const WearMap& map, const Eigen::VectorXd& values, double z, double theta_deg, double r) {
  double sw = 0, swv = 0, best = std::numeric_limits<double>::max();
  Eigen::Index nearest = 0;
  for (Eigen::Index i = 0; i < map.z.size(); ++i) {
    const double dz = map.z[i] - z;
    if (std::abs(dz) > std::max(r, best)) continue;
    const double arc = map.radius[i] * AngleDiffDeg(map.theta_deg[i], theta_deg) * kDegToRad;
    const double d = std::hypot(dz, arc);
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

void ReconstructInto(const ReconstructionPlan& plan, const std::vector<SensorWear>& sensor_wear, Reconstruction* result) {
  const CrusherConfig& crusher = *plan.crusher;
  const WearMap& map = *plan.map;
  const size_t nrows = crusher.rows.size();
  constexpr double kQuantisationVar = 1.0 / 12.0;  // a reading n: thickness uniform in [n, n+1)
  constexpr double kUnmeasuredRowRel = 0.3;        // a row without sensors borrows its neighbours' scale
  // Eq. 9 per row: least-squares scale through the origin over the row's sensors,
  // s = sum(I_j w_j) / sum(I_j^2); with one sensor this is W_s0 / W_i0 exactly.
  std::vector<double> num(nrows, 0.0), den(nrows, 0.0);
  std::vector<size_t> used(nrows, 0);
  std::vector<size_t> without_intensity;
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
      break;
    }
  }
  const MapCalibration calibration = CalibrateAtSensors(members, nrows, kQuantisationVar, plan.options.calibration_prior_dof);
  for (ScaleMember& m : members) m.sd *= calibration.factor;
  std::vector<std::pair<double, double>> knots;  // (z centre, scale) of rows with sensors
  std::vector<double> knot_var;
  std::vector<double> row_scale(nrows, std::numeric_limits<double>::quiet_NaN()), row_var(nrows, 0.0);
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
    row_var[r] = v;
  }
  {
    std::vector<std::tuple<double, double, double>> k3;
    for (size_t r = 0; r < nrows; ++r)
      if (den[r] > 0) k3.emplace_back(0.5 * (crusher.rows[r].z_min_m + crusher.rows[r].z_max_m), row_scale[r], row_var[r]);
    std::sort(k3.begin(), k3.end());
    for (const auto& [z, k, v] : k3) {
      knots.emplace_back(z, k);
      knot_var.push_back(v);
    }
  }
  auto scale_at = [&](double z, int row) -> double {
    if (knots.empty()) return 0.0;
    if (!plan.options.interpolate_between_rows) {
      if (row >= 0 && !std::isnan(row_scale[static_cast<size_t>(row)])) return row_scale[static_cast<size_t>(row)];
      // A row without sensors takes the nearest row's scale.
      double best = std::numeric_limits<double>::max(), s = knots.front().second;
      for (const auto& [kz, ks] : knots) {
        if (std::abs(kz - z) < best) {
          best = std::abs(kz - z);
          s = ks;
        }
      }
      return s;
    }
    if (z <= knots.front().first) return knots.front().second;
    if (z >= knots.back().first) return knots.back().second;
    for (size_t k = 1; k < knots.size(); ++k) {
      if (z <= knots[k].first) {
        const double f = (z - knots[k - 1].first) / (knots[k].first - knots[k - 1].first);
        return knots[k - 1].second + f * (knots[k].second - knots[k - 1].second);
      }
    }
    return knots.back().second;
  };
  // Variance of the scale at z: interpolation weights on the knots' variances; beyond the rows with
  // sensors (or stepping into a row without them) the borrowed scale carries kUnmeasuredRowRel more.
  auto scale_var_at = [&](double z, int row, double scale) -> double {
    if (knots.empty()) return 0.0;
    double v;
    bool borrowed = row >= 0 && std::isnan(row_scale[static_cast<size_t>(row)]);
    if (!plan.options.interpolate_between_rows && row >= 0 && !borrowed) {
      v = row_var[static_cast<size_t>(row)];
    } else if (z <= knots.front().first) {
      v = knot_var.front();
    } else if (z >= knots.back().first) {
      v = knot_var.back();
    } else {
      size_t k = 1;
      while (k < knots.size() && z > knots[k].first) ++k;
      const double f = (z - knots[k - 1].first) / (knots[k].first - knots[k - 1].first);
      v = (1 - f) * (1 - f) * knot_var[k - 1] + f * f * knot_var[k];
    }
    if (borrowed) v += std::pow(kUnmeasuredRowRel * scale, 2);
    return v;
  };
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
    out.rows[r].scale_mm_per_unit = std::isnan(row_scale[r]) ? scale_at(zc, static_cast<int>(r)) : row_scale[r];
    out.rows[r].scale_sd = std::sqrt(scale_var_at(zc, static_cast<int>(r), out.rows[r].scale_mm_per_unit));
    out.rows[r].min_thickness_mm = std::numeric_limits<double>::max();
    out.rows[r].min_thickness_lo_mm = std::numeric_limits<double>::max();
    out.rows[r].min_thickness_hi_mm = std::numeric_limits<double>::max();
    out.rows[r].sensors_used = used[r];
    out.rows[r].worn_through_faces = 0;
  }
  const double new_mm = crusher.thickness_new_mm;
  if (knots.empty()) {
    // No row scale: the map alone says nothing in mm.
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
    out.status_detail = without_intensity.empty()
                            ? "no sensor reading in any row: the map's intensity cannot be scaled into mm"
                            : "the sensors that report sit where the map has no wear intensity: no row scale";
    return;
  }
  // Per face scale: constant per row when stepping; piecewise linear in z between row centres
  // otherwise (clamped outside the first and last knot).
  std::vector<double> kz, k0, kslope;
  if (plan.options.interpolate_between_rows) {
    for (size_t k = 0; k < knots.size(); ++k) {
      kz.push_back(knots[k].first);
      k0.push_back(knots[k].second);
      kslope.push_back(k + 1 < knots.size() && knots[k + 1].first > knots[k].first
                           ? (knots[k + 1].second - knots[k].second) / (knots[k + 1].first - knots[k].first)
                           : 0.0);
    }
  }
  std::vector<double> step_scale(nrows + 1, 0.0), step_var(nrows + 1, 0.0);  // by row index + 1
  if (!plan.options.interpolate_between_rows) {
    for (size_t r = 0; r < nrows; ++r) {
      step_scale[r + 1] = out.rows[r].scale_mm_per_unit;
      step_var[r + 1] = out.rows[r].scale_sd * out.rows[r].scale_sd;
    }
  }
  // Rows without sensors (their faces borrow a scale: extra variance).
  std::vector<char> borrowed(nrows + 1, 0);
  for (size_t r = 0; r < nrows; ++r) borrowed[r + 1] = std::isnan(row_scale[r]) ? 1 : 0;
  const double band = plan.options.band_sigmas;
  const double* intensity = plan.intensity.data();
  const double* rel_sd = plan.intensity_rel_sd.data();
  const double* z = map.z.data();
  const double* area = map.areas.data();
  const int* face_row = plan.face_row.data();
  double* wear_out = out.wear_mm.data();
  double* remaining_out = out.remaining_mm.data();
  double* sd_out = out.remaining_sd_mm.data();
  double* scale_sd_out = out.scale_sd_mm.data();
  double* estimate_out = out.wear_estimate_mm.data();
  const size_t nk = kz.size();
  double min_all = std::numeric_limits<double>::max(), lo_all = min_all, hi_all = min_all;
  size_t min_face = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    const int r = face_row[i];
    double scale, svar;
    if (nk == 0) {
      if (r >= 0) {
        scale = step_scale[static_cast<size_t>(r) + 1];
        svar = step_var[static_cast<size_t>(r) + 1];
      } else {
        scale = scale_at(z[i], r);
        svar = scale_var_at(z[i], r, scale);
      }
    } else if (z[i] <= kz[0]) {
      scale = k0[0];
      svar = knot_var[0];
    } else {
      size_t k = 0;
      while (k + 1 < nk && z[i] > kz[k + 1]) ++k;
      if (k + 1 < nk) {
        const double f = (z[i] - kz[k]) / (kz[k + 1] - kz[k]);
        scale = k0[k] + (z[i] - kz[k]) * kslope[k];
        svar = (1 - f) * (1 - f) * knot_var[k] + f * f * knot_var[k + 1];
      } else {
        scale = k0[nk - 1];
        svar = knot_var[nk - 1];
      }
    }
    if (nk != 0 && borrowed[static_cast<size_t>(r + 1)]) svar += kUnmeasuredRowRel * kUnmeasuredRowRel * scale * scale;
    const double w_est = std::max(0.0, intensity[i] * scale);
    const double map_rel = rel_sd[i] * calibration.factor;
    const double sd = std::sqrt(w_est * w_est * map_rel * map_rel + intensity[i] * intensity[i] * svar);
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

Reconstruction Reconstruct(const CrusherConfig& crusher, const WearMap& map, const std::vector<SensorWear>& sensor_wear,
                           const ReconstructionOptions& options) {
  return Reconstruct(PrepareReconstruction(crusher, map, options), sensor_wear);
}

}  // namespace lw::core
