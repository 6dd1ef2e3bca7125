#include "core/reconstruction.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>
#include <unordered_map>

namespace lw::core {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

double AngleDiffDeg(double a, double b) {
  double d = std::fmod(a - b, 360.0);
  if (d > 180.0) d -= 360.0;
  if (d < -180.0) d += 360.0;
  return d;
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
  // Buckets of size radius in z and, in arc length, at least radius everywhere: sized at the
  // smallest radius, so neighbours within `radius_m` are always in the adjacent buckets (sized at
  // the mean radius, faces nearer the axis than the mean missed some of theirs).
  const double min_r = std::max(1e-6, map.radius.minCoeff());
  const double zmin = map.z.minCoeff();
  const double circumference = 2 * M_PI * min_r;
  const auto n_arc = std::max<long>(1, static_cast<long>(circumference / radius_m));
  std::unordered_map<long long, std::vector<Eigen::Index>> grid;
  auto key = [&](long iz, long ia) { return (static_cast<long long>(iz) << 32) ^ static_cast<long long>((ia % n_arc + n_arc) % n_arc); };
  std::vector<long> cz(static_cast<size_t>(n)), ca(static_cast<size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) {
    cz[static_cast<size_t>(i)] = static_cast<long>((map.z[i] - zmin) / radius_m);
    ca[static_cast<size_t>(i)] = static_cast<long>(map.theta_deg[i] / 360.0 * static_cast<double>(n_arc));
    grid[key(cz[static_cast<size_t>(i)], ca[static_cast<size_t>(i)])].push_back(i);
  }
  Eigen::VectorXd out(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    double sw = 0, swv = 0;
    const long iz = cz[static_cast<size_t>(i)], ia = ca[static_cast<size_t>(i)];
    for (long dz = -1; dz <= 1; ++dz) {
      for (long da = -1; da <= 1; ++da) {
        if (n_arc < 3 && da != 0) continue;
        auto it = grid.find(key(iz + dz, ia + da));
        if (it == grid.end()) continue;
        for (Eigen::Index j : it->second) {
          const double ddz = map.z[j] - map.z[i];
          const double arc = 0.5 * (map.radius[i] + map.radius[j]) * AngleDiffDeg(map.theta_deg[j], map.theta_deg[i]) * kDegToRad;
          if (ddz * ddz + arc * arc <= radius_m * radius_m) {
            sw += map.areas[j];
            swv += map.areas[j] * values[j];
          }
        }
      }
    }
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
    if (r.time > at) continue;
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

std::vector<SensorWear> SensorWearAt(const CrusherConfig& crusher, const std::vector<Reading>& readings, TimePoint at,
                                     bool interval_centre) {
  std::vector<SensorWear> out;
  for (const size_t i : LatestReadingIndices(crusher, readings, at)) {
    const Reading& r = readings[i];
    const SensorInfo& s = *crusher.FindSensor(r.sensor_id);
    const double thickness = r.thickness_mm + (interval_centre ? 0.5 : 0.0);
    out.push_back({s.id, std::max(0.0, s.thickness_new_mm - thickness)});
  }
  return out;
}

ReconstructionPlan PrepareReconstruction(const CrusherConfig& crusher, const WearMap& map, const ReconstructionOptions& options) {
  ReconstructionPlan p;
  p.crusher = &crusher;
  p.map = &map;
  p.options = options;
  p.intensity = SmoothOverSurface(map, map.wear, options.smoothing_radius_m);
  p.sensor_intensity.resize(static_cast<Eigen::Index>(crusher.sensors.size()));
  const double r = std::max(0.05, options.smoothing_radius_m);
  for (size_t s = 0; s < crusher.sensors.size(); ++s) {
    p.sensor_intensity[static_cast<Eigen::Index>(s)] = LocalMean(map, p.intensity, crusher.sensors[s].z_m, crusher.sensors[s].theta_deg, r);
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
  // Eq. 9 per row: least-squares scale through the origin over the row's sensors,
  // s = sum(I_j w_j) / sum(I_j^2); with one sensor this is W_s0 / W_i0 exactly.
  std::vector<double> num(nrows, 0.0), den(nrows, 0.0);
  std::vector<size_t> used(nrows, 0);
  for (const auto& sw : sensor_wear) {
    for (size_t s = 0; s < crusher.sensors.size(); ++s) {
      if (crusher.sensors[s].id != sw.sensor_id) continue;
      const int row = crusher.RowIndex(crusher.sensors[s].row);
      const double I = plan.sensor_intensity[static_cast<Eigen::Index>(s)];
      if (row < 0 || !(I > 0)) break;
      num[static_cast<size_t>(row)] += I * sw.wear_mm;
      den[static_cast<size_t>(row)] += I * I;
      ++used[static_cast<size_t>(row)];
      break;
    }
  }
  std::vector<std::pair<double, double>> knots;  // (z centre, scale) of rows with sensors
  std::vector<double> row_scale(nrows, std::numeric_limits<double>::quiet_NaN());
  for (size_t r = 0; r < nrows; ++r) {
    if (den[r] > 0) {
      row_scale[r] = num[r] / den[r];
      knots.emplace_back(0.5 * (crusher.rows[r].z_min_m + crusher.rows[r].z_max_m), row_scale[r]);
    }
  }
  std::sort(knots.begin(), knots.end());
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
  Reconstruction& out = *result;
  const Eigen::Index n = static_cast<Eigen::Index>(map.face_count());
  out.wear_mm.resize(n);  // no reallocation when `result` already holds arrays of this size
  out.remaining_mm.resize(n);
  out.min_thickness_mm = std::numeric_limits<double>::max();
  out.rows.resize(nrows);
  std::vector<double> wear_sum(nrows, 0.0), area_sum(nrows, 0.0);
  for (size_t r = 0; r < nrows; ++r) {
    out.rows[r].row = crusher.rows[r].name;
    out.rows[r].scale_mm_per_unit = std::isnan(row_scale[r]) ? scale_at(0.5 * (crusher.rows[r].z_min_m + crusher.rows[r].z_max_m), static_cast<int>(r)) : row_scale[r];
    out.rows[r].min_thickness_mm = std::numeric_limits<double>::max();
    out.rows[r].sensors_used = used[r];
  }
  // Per face scale: constant per row when stepping; piecewise linear in z between row centres
  // otherwise (clamped outside the first and last knot). Precomputed per segment so the face loop
  // is one pass with no search for the usual handful of rows.
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
  std::vector<double> step_scale(nrows + 1, 0.0);  // by row index + 1 (0: outside every row)
  if (!plan.options.interpolate_between_rows) {
    for (size_t r = 0; r < nrows; ++r) step_scale[r + 1] = scale_at(0.5 * (crusher.rows[r].z_min_m + crusher.rows[r].z_max_m), static_cast<int>(r));
  }
  const double new_mm = crusher.thickness_new_mm;
  const double* intensity = plan.intensity.data();
  const double* z = map.z.data();
  const double* area = map.areas.data();
  const int* face_row = plan.face_row.data();
  double* wear_out = out.wear_mm.data();
  double* remaining_out = out.remaining_mm.data();
  const size_t nk = kz.size();
  double min_all = std::numeric_limits<double>::max();
  size_t min_face = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    const int r = face_row[i];
    double scale;
    if (nk == 0) {
      scale = plan.options.interpolate_between_rows ? 0.0
              : (r >= 0 ? step_scale[static_cast<size_t>(r) + 1] : scale_at(z[i], r));
    } else if (z[i] <= kz[0]) {
      scale = k0[0];
    } else {
      size_t k = 0;
      while (k + 1 < nk && z[i] > kz[k + 1]) ++k;
      scale = k + 1 < nk ? k0[k] + (z[i] - kz[k]) * kslope[k] : k0[nk - 1];
    }
    const double w = std::max(0.0, intensity[i] * scale);
    const double rem = new_mm - w;
    wear_out[i] = w;
    remaining_out[i] = rem;
    if (rem < min_all) {
      min_all = rem;
      min_face = static_cast<size_t>(i);
    }
    if (r < 0) continue;
    const size_t ru = static_cast<size_t>(r);
    wear_sum[ru] += area[i] * w;
    area_sum[ru] += area[i];
    RowSummary& row = out.rows[ru];
    if (rem < row.min_thickness_mm) {
      row.min_thickness_mm = rem;
      row.min_face = static_cast<size_t>(i);
    }
  }
  out.min_thickness_mm = min_all;
  out.min_face = min_face;
  for (size_t r = 0; r < nrows; ++r) {
    const size_t f = out.rows[r].min_face;
    if (area_sum[r] > 0) {
      out.rows[r].min_z_m = map.z[static_cast<Eigen::Index>(f)];
      out.rows[r].min_theta_deg = map.theta_deg[static_cast<Eigen::Index>(f)];
    }
  }
  for (size_t r = 0; r < nrows; ++r) {
    out.rows[r].mean_wear_mm = area_sum[r] > 0 ? wear_sum[r] / area_sum[r] : 0.0;
    if (area_sum[r] == 0) out.rows[r].min_thickness_mm = crusher.thickness_new_mm;
  }
}

Reconstruction Reconstruct(const CrusherConfig& crusher, const WearMap& map, const std::vector<SensorWear>& sensor_wear,
                           const ReconstructionOptions& options) {
  return Reconstruct(PrepareReconstruction(crusher, map, options), sensor_wear);
}

}  // namespace lw::core
