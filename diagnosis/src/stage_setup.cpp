// Diagnosis stage 1, problem set-up (stage_setup.hpp).
#include "stage_setup.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

namespace lw::diagnosis::detail {
namespace {

size_t AddObs(Problem& prob, Obs o) {
  const double x = std::clamp(o.t / prob.grid.dt, 0.0, static_cast<double>(prob.grid.steps));
  o.j = static_cast<size_t>(std::floor(x));
  o.frac = x - static_cast<double>(o.j);
  prob.obs.push_back(o);
  return prob.obs.size() - 1;
}

}  // namespace

void Interpolator::Weights(double z, int& a, int& b, double& wa) const {
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

ModelPoint MakePoint(const MapFields& fields, const Interpolator& interp, const PointField& f, double half_thickness) {
  const double z_mid = 0.5 * (fields.z_bottom + fields.z_top);
  const double height = std::max(fields.z_top - fields.z_bottom, 1e-3);
  ModelPoint mp;
  mp.intensity = f.intensity;
  mp.normal_tilde = f.normal_tilde;
  mp.normal_i = f.normal_i;
  mp.broad_i = f.broad_i;
  mp.zn = (f.z - z_mid) / height;
  mp.shift_rel = ProfileShiftRel(fields, f.z);
  mp.cos_t = std::cos(f.theta_deg * kPi / 180.0);
  mp.sin_t = std::sin(f.theta_deg * kPi / 180.0);
  mp.half_thickness_mm = half_thickness;
  interp.Weights(f.z, mp.row_a, mp.row_b, mp.weight_a);
  return mp;
}

MapFields DescribeMap(const core::Bundle& bundle, DiagnosisResult& result) {
  MapFields fields = ComputeMapFields(bundle);
  result.noise["map_face_relative_noise"] = Round(fields.face_rel_noise);
  result.noise["map_harmonic1_relative_sd"] = Round(fields.harmonic1_rel_sd);
  result.noise["map_band_relative_sd_law"] = Round(fields.band_rel_sd);
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
  return fields;
}

std::vector<SensorData> AnalyseSensors(const core::Bundle& bundle, const MapFields& fields, DiagnosisResult& result) {
  const Thresholds th;
  const core::CrusherConfig& crusher = bundle.crusher;
  const core::TimePoint t0 = crusher.installed_at;
  auto to_time = [&](double days) { return core::AddDays(t0, days); };
  auto days = [&](core::TimePoint t) { return core::DaysBetween(t0, t); };
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
    std::vector<RawReading> raw;
    std::optional<core::TimePoint> first_old, last_old;  // a previous liner's readings (before a reline)
    size_t old = 0;
    for (const core::Reading& r : bundle.readings) {
      if (r.sensor_id != info.id) continue;
      if (crusher.OfThisLiner(info.id, r.time, r.thickness_mm)) {
        raw.push_back({days(r.time), r.thickness_mm});
        continue;
      }
      ++old;
      first_old = std::min(first_old.value_or(r.time), r.time);
      last_old = std::max(last_old.value_or(r.time), r.time);
    }
    if (old > 0)
      result.data_quality.push_back(
          {s.id, "previous_liner", *first_old, *last_old,
           std::to_string(old) + " readings of a previous liner (dated before installed_at), left out"});
    s.analysis = AnalyseSensor(std::move(raw), s.thickness);
    for (const auto& q : s.analysis.issues)
      result.data_quality.push_back({s.id, q.issue, to_time(q.from_days), to_time(q.to_days), q.detail});
    if (s.analysis.readings.empty())
      result.data_quality.push_back(
          {s.id, "no_readings", t0, t0, old > 0 ? "no reading of this liner" : "the sensor never reported"});
    s.field = FieldAt(bundle.map, fields, s.z, s.theta);
    s.usable = s.analysis.events.size() >= 2 && s.field.intensity > 1e-6;
    s.sigma_u = std::sqrt(s.field.rel_noise * s.field.rel_noise + th.u_floor_rel * th.u_floor_rel);
    sensors.push_back(std::move(s));
  }
  return sensors;
}

std::vector<std::string> AnchorRows(const core::CrusherConfig& crusher, const std::vector<SensorData>& sensors,
                                    Interpolator& interp) {
  std::vector<std::string> anchor_rows;
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
  return anchor_rows;
}

TimeSetup BuildTimeGrid(const core::Bundle& bundle, const std::vector<SensorData>& sensors, const DiagnoseOptions& options,
                        DiagnosisResult& result) {
  auto days = [&](core::TimePoint t) { return core::DaysBetween(bundle.crusher.installed_at, t); };
  TimeSetup ts;
  // Time extent.
  double t_max = 1.0;
  for (const SensorData& s : sensors)
    if (!s.analysis.readings.empty()) t_max = std::max(t_max, s.analysis.readings.back().t_days);
  for (const core::Scan& scan : bundle.scans) t_max = std::max(t_max, days(scan.date));
  if (options.predict_at) t_max = std::max(t_max, days(*options.predict_at));
  ts.grid.dt = std::max(t_max / 150.0, 0.05);
  ts.grid.steps = static_cast<size_t>(std::ceil(t_max / ts.grid.dt)) + 1;

  // Throughput x abrasiveness per step.
  for (const SensorData& s : sensors) ts.t_obs_end = std::max(ts.t_obs_end, s.analysis.last_time_days);
  ts.grid.throughput.assign(ts.grid.steps, 1.0);
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
    for (size_t j = 0; j < ts.grid.steps; ++j) {
      const double tm = (static_cast<double>(j) + 0.5) * ts.grid.dt;
      while (k + 1 < series.size() && series[k + 1].first <= tm) ++k;
      ts.grid.throughput[j] = series[k].second;
    }
    double sum = 0, sum2 = 0;
    size_t n = 0;
    for (size_t j = 0; j < ts.grid.steps; ++j) {
      if ((static_cast<double>(j) + 0.5) * ts.grid.dt > std::max(ts.t_obs_end, 1.0)) break;
      sum += ts.grid.throughput[j];
      sum2 += ts.grid.throughput[j] * ts.grid.throughput[j];
      ++n;
    }
    const double mean = n ? sum / static_cast<double>(n) : 0;
    if (mean > 0) {
      for (double& q : ts.grid.throughput) q /= mean;
      ts.throughput_cv = std::sqrt(std::max(0.0, sum2 / static_cast<double>(n) - mean * mean)) / mean;
      ts.throughput_available = ts.throughput_cv > 0.03;
    }
    if (!ts.throughput_available) {
      for (double& q : ts.grid.throughput) q = 1.0;
      result.notes.push_back(
          Fmt("operations.csv shows almost constant throughput (variation %.1f %%): "
              "throughput_variation not identifiable, skipped",
              100.0 * ts.throughput_cv));
    }
  } else {
    result.notes.push_back("no operations.csv: throughput_variation skipped");
  }
  return ts;
}

void AddSensorObservations(const MapFields& fields, const Interpolator& interp, std::vector<SensorData>& sensors, Problem& prob,
                           DiagnosisResult& result) {
  const Thresholds th;
  int usable_count = 0;
  for (SensorData& s : sensors) {
    if (!s.usable) continue;
    s.usable_index = usable_count++;
    const size_t point = prob.points.size();
    prob.points.push_back(MakePoint(fields, interp, s.field, 0.5 * s.thickness));
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
      prob.sensor_obs.back().push_back(AddObs(prob, o));
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
}

std::vector<ScanCells> AddScanObservations(const core::Bundle& bundle, const MapFields& fields, const Interpolator& interp,
                                           const CellGrid& grid, Problem& prob, DiagnosisResult& result) {
  const core::CrusherConfig& crusher = bundle.crusher;
  auto days = [&](core::TimePoint t) { return core::DaysBetween(crusher.installed_at, t); };
  // Scans.
  std::vector<ScanCells> scans;
  for (const core::Scan& scan : bundle.scans) {
    ScanCells sc = ProjectScan(bundle.map, fields, grid, scan, days(scan.date), crusher.thickness_new_mm);
    result.noise["scan_point_noise_mm:" + scan.file] = Round(sc.point_noise_mm, 3);
    if (sc.points_used < sc.points_total / 2) {
      result.notes.push_back("scan " + scan.file + ": only " + std::to_string(sc.points_used) + " of " +
                             std::to_string(sc.points_total) + " points lie on the mapped surface");
    }
    const int scan_index = static_cast<int>(scans.size());
    for (size_t c = 0; c < grid.cells.size(); ++c) {
      if (!std::isfinite(sc.wear_mm[c]) || sc.points[c] < 3 || sc.fields[c].intensity <= 0) continue;
      const size_t point = prob.points.size();
      prob.points.push_back(MakePoint(fields, interp, sc.fields[c], 0.5 * crusher.thickness_new_mm));
      Obs o;
      o.point = point;
      o.t = sc.t_days;
      o.raw = o.wear = sc.wear_mm[c];
      o.sigma = 0;  // set once a baseline prediction exists
      o.scan = scan_index;
      o.cell = static_cast<int>(c);
      prob.scan_obs.push_back(AddObs(prob, o));
    }
    scans.push_back(std::move(sc));
  }
  return scans;
}

ProblemSetup SetUpProblem(const core::Bundle& bundle, const DiagnoseOptions& options, DiagnosisResult& result) {
  ProblemSetup s;
  s.fields = DescribeMap(bundle, result);
  s.sensors = AnalyseSensors(bundle, s.fields, result);
  s.anchor_rows = AnchorRows(bundle.crusher, s.sensors, s.interp);
  if (!s.Diagnosable()) {
    result.notes.push_back("no usable sensor readings: nothing to diagnose");
    return s;
  }
  s.prob.rows = s.interp.centres.size();
  s.prob.map_harmonic1_sd = s.fields.harmonic1_rel_sd;
  s.time = BuildTimeGrid(bundle, s.sensors, options, result);
  s.prob.grid = s.time.grid;
  AddSensorObservations(s.fields, s.interp, s.sensors, s.prob, result);
  s.grid = BuildCellGrid(bundle.map, s.fields, 240);
  s.scans = AddScanObservations(bundle, s.fields, s.interp, s.grid, s.prob, result);
  return s;
}

}  // namespace lw::diagnosis::detail
