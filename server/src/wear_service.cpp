#include "server/wear_service.hpp"

#include "core/csv.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/time.hpp"
#include "server/ingest.hpp"

namespace lw::server {
namespace {

using nlohmann::ordered_json;

ordered_json OptTime(const std::optional<core::TimePoint>& t) {
  return t ? ordered_json(core::FormatIsoTime(*t)) : ordered_json(nullptr);
}

double Round(double v, double step) {
  const double inv = std::round(1.0 / step);  // divide by an exact integer: 0.0278, not 0.027800000000000002
  return std::round(v * inv) / inv;
}

/// A number, or null when there is none (NaN: the map or sensors cannot support it).
ordered_json Num(double v, double step) {
  return std::isfinite(v) ? ordered_json(Round(v, step)) : ordered_json(nullptr);
}

}  // namespace

CrusherState ComputeCrusherState(const Crusher& crusher, const std::vector<estimate::Sample>& readings,
                                 std::optional<core::TimePoint> at, const CrusherState* previous,
                                 const std::vector<core::SettingCheck>& checks, const estimate::EstimateOptions& options) {
  CrusherState st;
  // Reline dates hold only against this crusher's own previous state.
  const bool hold = previous && previous->crusher == &crusher;
  static_cast<estimate::WearEstimate&>(st) = estimate::Estimate(crusher, readings, at, options, hold ? previous : nullptr);
  // A check before this liner's installation measured the liner before it.
  std::vector<core::SettingCheck> this_liner;
  for (const core::SettingCheck& c : checks)
    if (c.time >= crusher.config.installed_at) this_liner.push_back(c);
  core::ApplySettingChecks(this_liner, at.value_or(core::TimePoint::max()), &st.setting);
  st.crusher = &crusher;
  st.at = at;
  return st;
}

CrusherState ComputeCrusherState(const Crusher& crusher, const std::vector<StoredReading>& readings,
                                 const CrusherState* previous) {
  std::vector<estimate::Sample> samples;
  samples.reserve(readings.size());
  for (const StoredReading& r : readings) {
    estimate::Sample s;
    static_cast<estimate::Point&>(s) = PointOf(r);
    s.sensor = r.sensor;
    samples.push_back(std::move(s));
  }
  return ComputeCrusherState(crusher, samples, std::nullopt, previous);
}

namespace {

/// The reading each sensor contributed, named in every published result.
ordered_json ReadingsUsedJson(const CrusherState& st) {
  ordered_json used = ordered_json::array();
  for (const estimate::Sample& r : st.used) {
    used.push_back(
        {{"sensor", r.sensor}, {"seq", r.seq}, {"time", core::FormatIsoSeconds(r.time_s)}, {"thickness_mm", r.thickness_mm}});
  }
  return used;
}

}  // namespace

ordered_json WearJson(const CrusherState& st, bool with_faces) {
  const Crusher& c = *st.crusher;
  const core::Reconstruction& rec = st.reconstruction;
  ordered_json j;
  j["crusher_id"] = c.config.crusher_id;
  if (st.at) j["at"] = core::FormatIsoTime(*st.at);
  j["time"] = core::FormatIsoTime(st.time);
  j["map_sha256"] = c.map.sha256;
  j["thickness_new_mm"] = c.config.thickness_new_mm;
  j["thickness_min_mm"] = c.config.thickness_min_mm;
  const bool supported = rec.status != core::kStatusNoSensors;
  j["status"] = rec.status;
  if (!rec.status_detail.empty()) j["status_detail"] = rec.status_detail;
  j["min_thickness_mm"] = Num(rec.min_thickness_mm, 0.001);
  j["min_thickness_band_mm"] =
      supported ? ordered_json::array({Num(rec.min_thickness_lo_mm, 0.001), Num(rec.min_thickness_hi_mm, 0.001)})
                : ordered_json(nullptr);
  // The headline: the thinnest area the data support. Worn through is said only at that scale; the
  // faces' own counts stay with the faces (face_level).
  j["thinnest_area"] = core::ThinnestAreaJson(st.areas.liner);
  j["worn_through"] = st.areas.liner.worn_through;
  j["setting"] = core::SettingJson(st.setting);
  j["map_error_at_sensors"] = core::MapCalibrationJson(rec.calibration);
  j["face_level"] = {{"estimate_at_zero_faces", rec.worn_through_faces},
                     {"band_reaches_zero_faces", rec.maybe_worn_through_faces}};
  const size_t f = rec.min_face;
  std::string min_row;
  if (f < c.plan.face_row.size() && c.plan.face_row[f] >= 0)
    min_row = c.config.rows[static_cast<size_t>(c.plan.face_row[f])].name;
  if (supported) {
    j["min"] = {{"face", f},
                {"z_m", f < c.map.face_count() ? Round(c.map.z[static_cast<Eigen::Index>(f)], 1e-4) : 0.0},
                {"theta_deg", f < c.map.face_count() ? Round(c.map.theta_deg[static_cast<Eigen::Index>(f)], 0.01) : 0.0},
                {"row", min_row}};
  } else {
    j["min"] = nullptr;
  }
  ordered_json rows = ordered_json::array();
  for (size_t k = 0; k < rec.rows.size(); ++k) {
    const core::RowSummary& r = rec.rows[k];
    const core::ThinnestArea& area = st.areas.rows[k];
    rows.push_back({{"row", r.row},
                    {"scale_mm_per_unit", Num(r.scale_mm_per_unit, 1e-9)},
                    {"scale_sd", Num(r.scale_sd, 1e-9)},
                    {"min_thickness_mm", Num(r.min_thickness_mm, 0.001)},
                    {"min_thickness_band_mm",
                     supported ? ordered_json::array({Num(r.min_thickness_lo_mm, 0.001), Num(r.min_thickness_hi_mm, 0.001)})
                               : ordered_json(nullptr)},
                    {"min_z_m", Round(r.min_z_m, 1e-4)},
                    {"min_theta_deg", Round(r.min_theta_deg, 0.01)},
                    {"mean_wear_mm", Num(r.mean_wear_mm, 0.001)},
                    {"thinnest_area", core::ThinnestAreaJson(area)},
                    {"worn_through", area.worn_through},
                    {"face_level", {{"estimate_at_zero_faces", r.worn_through_faces}}},
                    {"sensors_used", r.sensors_used}});
  }
  j["rows"] = rows;
  const core::MapModel& m = c.plan.model;
  j["map_model"] = {{"bandwidth_m", Round(m.bandwidth_m, 1e-4)},
                    {"bandwidth_arc_m", Round(m.bandwidth_arc_m, 1e-4)},
                    {"local_linear", m.local_linear},
                    {"bandwidth_method", m.bandwidth_method},
                    {"noise_source", m.noise_source},
                    {"face_relative_noise", Round(m.face_cv, 1e-3)},
                    {"smoothing_error_relative", Round(m.smoothing_error_rel, 1e-3)},
                    {"outlier_faces_capped", m.outlier_faces},
                    {"windows", c.map.windows}};
  j["scan"] = estimate::ScanJson(c, st.scan.get());
  j["readings_used"] = ReadingsUsedJson(st);
  j["sensors_stale"] = st.stale;
  j["sensors_stuck"] = st.stuck;
  j["note"] =
      "a reading n means thickness in [n, n+1) mm; estimates use n + 0.5; bands are +/-2 sd (map noise, "
      "sensor quantisation, row scale); remaining thickness is never below 0 (worn through)";
  if (with_faces) {
    if (supported) {
      std::vector<double> remaining(static_cast<size_t>(rec.remaining_mm.size())), sd(remaining.size());
      for (Eigen::Index i = 0; i < rec.remaining_mm.size(); ++i) {
        remaining[static_cast<size_t>(i)] = Round(rec.remaining_mm[i], 0.001);
        sd[static_cast<size_t>(i)] = Round(rec.remaining_sd_mm[i], 0.001);
      }
      j["remaining_mm"] = remaining;
      j["remaining_sd_mm"] = sd;
    } else {
      j["remaining_mm"] = nullptr;
    }
  }
  return j;
}

std::string WearCsv(const CrusherState& st) {
  const Crusher& c = *st.crusher;
  const core::Reconstruction& rec = st.reconstruction;
  std::string out;
  core::AppendCsvRecord(&out, {"face", "row", "z_m", "theta_deg", "remaining_mm", "remaining_sd_mm", "wear_mm"});
  const bool scaled =
      rec.status != core::kStatusNoSensors && rec.remaining_mm.size() == static_cast<Eigen::Index>(c.map.face_count());
  // Fixed decimals per column: metres to 0.1 mm, degrees to 0.01, millimetres to 1 um.
  const auto num = [](double v, int decimals) {
    char b[32];
    std::snprintf(b, sizeof b, "%.*f", decimals, v);
    return std::string(b);
  };
  for (size_t f = 0; f < c.map.face_count(); ++f) {
    const auto i = static_cast<Eigen::Index>(f);
    const int row = c.plan.face_row[f];
    std::vector<std::string> rec_fields = {std::to_string(f), row >= 0 ? c.config.rows[static_cast<size_t>(row)].name : "",
                                           num(c.map.z[i], 4), num(c.map.theta_deg[i], 2)};
    if (scaled) {
      rec_fields.push_back(num(rec.remaining_mm[i], 3));
      rec_fields.push_back(num(rec.remaining_sd_mm[i], 3));
      rec_fields.push_back(num(rec.wear_mm[i], 3));
    } else {
      rec_fields.insert(rec_fields.end(), 3, "");
    }
    core::AppendCsvRecord(&out, rec_fields);
  }
  return out;
}

ordered_json ForecastJson(const CrusherState& st) {
  const Crusher& c = *st.crusher;
  ordered_json j;
  j["crusher_id"] = c.config.crusher_id;
  if (st.at) j["at"] = core::FormatIsoTime(*st.at);
  j["time"] = core::FormatIsoTime(st.time);
  j["thickness_min_mm"] = c.config.thickness_min_mm;
  j["map_sha256"] = c.map.sha256;
  j["readings_used"] = ReadingsUsedJson(st);
  ordered_json rows = ordered_json::array();
  for (const core::RowForecast& r : st.row_forecasts) {
    ordered_json o = {
        {"row", r.row},
        {"min_thickness_mm", Num(r.min_thickness_mm, 0.001)},
        {"min_thickness_band_mm", ordered_json::array({Num(r.min_thickness_lo_mm, 0.001), Num(r.min_thickness_hi_mm, 0.001)})},
        {"rate_mm_per_day", Round(r.rate_mm_per_day, 1e-4)},
        {"rate_sd_mm_per_day", Round(r.rate_sd_mm_per_day, 1e-4)},
        {"reach_date", OptTime(r.reach)},
        {"reach_earliest", OptTime(r.reach_earliest)},
        {"reach_latest", OptTime(r.reach_latest)},
        {"below_minimum_since", OptTime(r.below_minimum_since)},
        {"reach_held", r.reach_held}};
    o["reach_set_by_sensor"] = r.reach_set_by.empty() ? ordered_json(nullptr) : ordered_json(r.reach_set_by);
    if (r.reach_held) o["reach_estimate"] = OptTime(r.reach_estimate);
    if (!r.reach_note.empty()) o["reach_note"] = r.reach_note;
    if (!r.note.empty()) o["note"] = r.note;
    rows.push_back(o);
  }
  j["rows"] = rows;
  ordered_json sensors = ordered_json::array();
  for (const core::SensorForecast& f : st.sensor_forecasts) {
    ordered_json o = {{"id", f.sensor_id}, {"ok", f.ok}};
    if (f.ok) {
      o["last_time"] = core::FormatIsoTime(f.last_time);
      o["last_reading_mm"] = f.last_reading_mm;
      o["thickness_interval_mm"] = {f.last_reading_mm, f.last_reading_mm + 1.0};
      o["thickness_mm"] = Round(f.thickness_mm, 0.001);
      o["rate_mm_per_day"] = Round(f.rate_mm_per_day, 1e-4);
      o["reach_date"] = OptTime(f.reach);
      o["reach_earliest"] = OptTime(f.reach_earliest);
      o["reach_latest"] = OptTime(f.reach_latest);
      ordered_json curve = ordered_json::array();
      for (const core::CurvePoint& p : f.points) {
        curve.push_back({{"time", core::FormatIsoTime(p.time)},
                         {"thickness_mm", Round(p.thickness_mm, 0.01)},
                         {"lo_mm", Round(p.lo_mm, 0.01)},
                         {"hi_mm", Round(p.hi_mm, 0.01)}});
      }
      o["curve"] = curve;
    }
    if (!f.note.empty()) o["note"] = f.note;
    sensors.push_back(o);
  }
  j["sensors"] = sensors;
  j["note"] =
      "a reading n means thickness in [n, n+1) mm; fits use n + 0.5; bands are +/-2 sd; a row's earliest "
      "date starts from the thin edge of its thinnest point's band";
  return j;
}

WearService::WearService(const Registry& registry, const LiveState& live) : registry_(registry), live_(live) {}

WearService::Entry& WearService::EntryOf(const std::string& crusher) {
  std::lock_guard<std::mutex> lock(mutex_);
  return entries_[crusher];  // std::map: entries never move
}

void WearService::MarkChanged(const std::string& crusher) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++entries_[crusher].version;
}

void WearService::Reset(const std::string& crusher) {
  Entry& e = EntryOf(crusher);
  std::lock_guard<std::mutex> compute(e.compute);  // a computation under way finishes first, then is dropped
  std::lock_guard<std::mutex> lock(mutex_);
  ++e.version;
  e.state = nullptr;
}

std::shared_ptr<const CrusherState> WearService::ComputeLocked(const Crusher& crusher, Entry& e) {
  int64_t version = 0;
  std::shared_ptr<const CrusherState> previous;  // the state published last: its dates hold within their band
  std::vector<core::SettingCheck> checks;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (e.state && e.state->version == e.version) return e.state;
    version = e.version;
    previous = e.state;
    checks = e.checks;
  }
  // The version is read before the inputs: readings committed after it bump it again.
  auto st = std::make_shared<CrusherState>(
      ComputeCrusherState(crusher, live_.WearSamples(crusher.config.crusher_id), std::nullopt, previous.get(), checks));
  st->version = version;
  const auto text = [](const nlohmann::ordered_json& j) {
    return j.dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::replace);
  };
  st->wear_body = text(WearJson(*st, true));
  st->wear_body_no_faces = text(WearJson(*st, false));
  st->forecast_body = text(ForecastJson(*st));
  std::lock_guard<std::mutex> lock(mutex_);
  e.state = st;
  return st;
}

std::shared_ptr<const CrusherState> WearService::Get(const std::string& crusher_id) {
  const Crusher* crusher = registry_.Find(crusher_id);
  if (!crusher) return nullptr;
  Entry& e = EntryOf(crusher_id);
  std::lock_guard<std::mutex> compute(e.compute);
  return ComputeLocked(*registry_.Find(crusher_id), e);  // the model of now: a reline may have replaced it meanwhile
}

void WearService::SetSettingChecks(const std::string& crusher, std::vector<core::SettingCheck> checks) {
  std::lock_guard<std::mutex> lock(mutex_);
  Entry& e = entries_[crusher];
  e.checks = std::move(checks);
  ++e.version;
}

std::vector<core::SettingCheck> WearService::SettingChecks(const std::string& crusher) {
  std::lock_guard<std::mutex> lock(mutex_);
  return entries_[crusher].checks;
}

std::shared_ptr<const CrusherState> WearService::Latest(const std::string& crusher_id) {
  const Crusher* crusher = registry_.Find(crusher_id);
  if (!crusher) return nullptr;
  Entry& e = EntryOf(crusher_id);
  std::lock_guard<std::mutex> lock(mutex_);
  return e.state;  // current, the last one while new readings wait for the wear worker, or none yet
}

}  // namespace lw::server
