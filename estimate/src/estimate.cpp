#include "estimate/estimate.hpp"

#include <algorithm>
#include <cmath>
#include <set>

namespace lw::estimate {
namespace {

/// The forecasts of `st` (its wear and areas already set) from the usable readings.
void Forecast(const CrusherModel& model, const std::vector<core::Reading>& usable, const WearEstimate* previous,
              WearEstimate& st) {
  const core::CrusherConfig& config = model.config;
  for (const core::SensorInfo& s : config.sensors) {
    core::SensorForecast f = core::ForecastSensor(config, s, usable);
    if (std::find(st.stuck.begin(), st.stuck.end(), s.id) != st.stuck.end()) {
      // A frozen value's curve would never reach the minimum: no forecast from it.
      f.ok = false;
      f.note = "stuck: its value has not moved while its row wore; left out (docs/wear.md, Global wear)";
      f.reach.reset();
      f.reach_earliest.reset();
      f.reach_latest.reset();
      f.points.clear();
    }
    st.sensor_forecasts.push_back(std::move(f));
  }
  // A row whose only sensors are stale still gets its reline date from their curves (each anchored
  // at its own last reading); a row with a fresh sensor takes the fresh ones alone.
  std::vector<core::SensorWear> forecast_wear = st.sensor_wear;
  if (!st.stale.empty()) {
    std::set<std::string> fresh_rows;
    for (const core::SensorWear& w : st.sensor_wear) fresh_rows.insert(config.FindSensor(w.sensor_id)->row);
    for (const core::SensorWear& w : core::SensorWearAt(config, usable, st.time))
      if (!fresh_rows.contains(config.FindSensor(w.sensor_id)->row)) forecast_wear.push_back(w);
  }
  st.row_forecasts = core::ForecastRows(config, st.areas.rows, forecast_wear, st.sensor_forecasts, st.time);
  if (previous) core::HoldRowForecasts(previous->row_forecasts, &st.row_forecasts);
}

}  // namespace

nlohmann::ordered_json ScanJson(const CrusherModel& model, const ScannedPlan* scan) {
  using nlohmann::ordered_json;
  if (!scan) return nullptr;
  const auto num = [](double v) {
    return std::isfinite(v) ? ordered_json(std::round(v * 1000.0) / 1000.0) : ordered_json(nullptr);
  };
  const ModelScan& sc = model.ScanOf(*scan);
  const core::ScanCorrection& k = scan->correction;
  ordered_json j = {{"file", sc.scan.file},
                    {"date", core::FormatIsoTime(sc.scan.date)},
                    {"points_used", sc.faces.points_used},
                    {"points_total", sc.faces.points_total},
                    {"applied", k.detail.empty()}};
  if (k.detail.empty()) {
    j["faces_corrected"] = k.faces_corrected;
    j["faces_filled"] = k.faces_filled;
    j["median_ratio"] = num(k.median_ratio);
    j["map_model_error_relative"] = num(k.map_model_error_rel);
  } else {
    j["detail"] = k.detail;
  }
  if (const auto& p = scan->prior) {
    j["prior_campaign"] = model.prior->campaign;
    j["pattern_change_relative"] = num(p->change_rel);
    j["sensors_spread_prior_relative"] = num(p->spread_prior_rel);
    j["sensors_spread_map_relative"] = num(p->spread_map_rel);
    j["sensors_compared"] = p->sensors;
  }
  return j;
}

std::vector<Sample> SamplesOf(const std::vector<core::Reading>& readings) {
  std::vector<Sample> out;
  out.reserve(readings.size());
  for (size_t i = 0; i < readings.size(); ++i) {
    Sample s;
    s.seq = static_cast<int64_t>(i) + 1;  // one per reading, in file order: ties resolve as in the file
    s.time_s = readings[i].time.time_since_epoch().count();
    s.thickness_mm = readings[i].thickness_mm;
    s.sensor = readings[i].sensor_id;
    out.push_back(std::move(s));
  }
  return out;
}

WearEstimate Estimate(const CrusherModel& model, const ReadingWindow& window, std::optional<core::TimePoint> at,
                      const EstimateOptions& options, const WearEstimate* previous) {
  return Estimate(model, window.Readings(), at, options, previous);
}

WearEstimate Estimate(const CrusherModel& model, const std::vector<Sample>& readings, std::optional<core::TimePoint> at,
                      const EstimateOptions& options, const WearEstimate* previous) {
  const core::CrusherConfig& config = model.config;
  const core::TimePoint until = at.value_or(core::TimePoint::max());
  WearEstimate st;
  std::vector<core::Reading> usable;
  std::vector<const Sample*> source;  // the sample behind each usable reading
  usable.reserve(readings.size());
  source.reserve(readings.size());
  for (const Sample& r : readings) {
    if (core::FromUnixSeconds(r.time_s) > until || !UsableForWear(config, r.sensor, r)) continue;
    core::Reading c;
    c.time = core::FromUnixSeconds(r.time_s);
    c.sensor_id = r.sensor;
    c.thickness_mm = r.thickness_mm;
    usable.push_back(std::move(c));
    source.push_back(&r);
    st.time = std::max(st.time, core::FromUnixSeconds(r.time_s));
  }
  if (usable.empty()) return st;
  // A sensor whose latest reading lags the newest by more than 8 of its reporting periods (dead, or
  // its radio lost) would give an old day's wear, too little: it sets no row scale (core::Staleness);
  // nor does one that keeps reporting one value while its row wears (core::StuckRule).
  const std::vector<size_t> fresh = core::LiveReadingIndices(config, usable, st.time, &st.stale, &st.stuck);
  st.sensor_wear = core::SensorWearFrom(config, usable, fresh, options.interval_centre);
  for (const size_t i : fresh) st.used.push_back(*source[i]);
  // The latest scan up to `at` corrects the map between the sensors.
  if (options.use_scans) st.scan = model.PlanWithScan(usable, until, st.stuck, options.interval_centre);
  const core::ReconstructionPlan& plan = st.scan && st.scan->correction.detail.empty() ? st.scan->plan : model.plan;
  st.reconstruction = core::Reconstruct(plan, st.sensor_wear);
  std::vector<core::Reading> used;
  for (const size_t i : fresh) used.push_back(usable[i]);
  st.areas = core::FindThinnestAreas(plan, st.reconstruction, used);
  st.setting = core::EstimateSetting(plan, st.reconstruction, used);
  st.has_wear = true;
  if (options.forecast) Forecast(model, usable, previous, st);
  return st;
}

}  // namespace lw::estimate
