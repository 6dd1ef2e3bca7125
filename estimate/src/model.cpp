#include "estimate/model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "core/angles.hpp"

namespace lw::estimate {
namespace {

constexpr double kPi = 3.14159265358979323846;
// The readings' own error in a sensor's wear (1 mm ladder: the interval's half-width and the
// board's timing) and the prior scan's at a sensor position (points' scatter, registration).
constexpr double kReadingSdMm = 0.5, kPriorSdMm = 1.0;

/// The scan's wear at each of `config`'s sensors: the median of the faces it covers within 1.5 face
/// edges of the sensor, else the nearest covered face within three; sensors it does not reach are
/// left out.
std::vector<core::SensorWear> ScanWearAtSensors(const core::CrusherConfig& config, const core::WearMap& map,
                                                const core::ScanFaces& faces, double face_m) {
  std::vector<core::SensorWear> out;
  for (const core::SensorInfo& s : config.sensors) {
    std::vector<double> near;
    double best = std::numeric_limits<double>::infinity(), best_wear = 0;
    for (Eigen::Index i = 0; i < faces.wear_mm.size(); ++i) {
      if (!std::isfinite(faces.wear_mm[i])) continue;
      const double arc = core::AngleDiffDeg(map.theta_deg[i], s.theta_deg) * kPi / 180.0 * map.radius[i];
      const double d = std::hypot(map.z[i] - s.z_m, arc);
      if (d <= 1.5 * face_m) near.push_back(faces.wear_mm[i]);
      if (d < best) best = d, best_wear = faces.wear_mm[i];
    }
    double w = best_wear;
    if (!near.empty()) {
      std::nth_element(near.begin(), near.begin() + static_cast<std::ptrdiff_t>(near.size() / 2), near.end());
      w = near[near.size() / 2];
    } else if (best > 3 * face_m) {
      continue;
    }
    out.push_back({s.id, std::max(0.0, w)});
  }
  return out;
}

/// The latest scan of the latest earlier campaign that has one, as `model`'s prior.
void SetPriorFromHistory(const core::Bundle& bundle, CrusherModel& model) {
  // The latest scan of scans/ dated before this liner's installation is the previous liner's own;
  // a history/ campaign's is used when it is later.
  const core::Scan* before = nullptr;
  for (const core::Scan& s : bundle.scans)
    if (s.date < model.config.installed_at && (!before || s.date >= before->date)) before = &s;
  for (auto c = bundle.history.rbegin(); c != bundle.history.rend(); ++c) {
    if (c->scans.empty() || (before && c->scans.back().date < before->date)) continue;
    if (model.SetPrior(c->name, c->scans.back(), "history/" + c->name + "/" + c->scans.back().file)) return;
  }
  if (before) model.SetPrior("before " + core::FormatIsoTime(model.config.installed_at), *before, before->file);
}

/// PriorCheck of `prior` against the sensors' wear now (`now`), and of the map's pattern for comparison.
PriorCheck CheckPrior(const CrusherModel& model, const PriorScan& prior, const std::vector<core::SensorWear>& now) {
  struct Sensor {
    double wear, prior, map, map_rel_sd;
  };
  std::map<std::string, std::vector<Sensor>> rows;
  const core::CrusherConfig& config = model.config;
  for (const core::SensorWear& w : now) {
    const auto p = std::find_if(prior.wear_at_sensors.begin(), prior.wear_at_sensors.end(),
                                [&](const core::SensorWear& x) { return x.sensor_id == w.sensor_id; });
    if (p == prior.wear_at_sensors.end() || p->wear_mm < PriorCheck::kMinWearMm || w.wear_mm < PriorCheck::kMinWearMm) continue;
    size_t k = 0;
    while (k < config.sensors.size() && config.sensors[k].id != w.sensor_id) ++k;
    if (k == config.sensors.size()) continue;
    const double i = model.plan.sensor_intensity[static_cast<Eigen::Index>(k)];
    if (!(i > 0)) continue;
    rows[config.sensors[k].row].push_back(
        {w.wear_mm, p->wear_mm, i, model.plan.sensor_intensity_sd[static_cast<Eigen::Index>(k)] / i});
  }
  PriorCheck c;
  double excess_prior = 0, excess_map = 0;
  for (const auto& [row, s] : rows) {
    if (s.size() < 2) continue;
    const double n = static_cast<double>(s.size());
    double mean_p = 0, mean_m = 0;
    for (const Sensor& x : s) mean_p += x.wear / x.prior / n, mean_m += x.wear / x.map / n;
    for (const Sensor& x : s) {
      const double reading = (kReadingSdMm / x.wear) * (kReadingSdMm / x.wear);
      const double dp = x.wear / x.prior / mean_p - 1, dm = x.wear / x.map / mean_m - 1;
      excess_prior += dp * dp - (reading + (kPriorSdMm / x.prior) * (kPriorSdMm / x.prior)) * (n - 1) / n;
      excess_map += dm * dm - (reading + x.map_rel_sd * x.map_rel_sd) * (n - 1) / n;
    }
    c.sensors += s.size();
    c.dof += n - 1;
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double var_prior = c.dof > 0 ? std::max(0.0, excess_prior / c.dof) : 0.0;
  c.spread_prior_rel = c.dof > 0 ? std::sqrt(var_prior) : nan;
  c.spread_map_rel = c.dof > 0 ? std::sqrt(std::max(0.0, excess_map / c.dof)) : nan;
  const double k0 = PriorCheck::kPriorChange0;
  c.change_rel = std::sqrt((PriorCheck::kPriorDof0 * k0 * k0 + c.dof * var_prior) / (PriorCheck::kPriorDof0 + c.dof));
  // Rounded so that the corrected plan (and the check it reports) is recomputed when they move,
  // not at every reading.
  const auto round = [](double v) { return std::round(v * 200.0) / 200.0; };
  c.change_rel = std::max(0.05, round(c.change_rel));
  c.spread_prior_rel = round(c.spread_prior_rel);
  c.spread_map_rel = round(c.spread_map_rel);
  return c;
}

/// Whether two checks are the same as reported (NaN, "not measured", equal to NaN).
bool SameCheck(const PriorCheck& a, const PriorCheck& b) {
  const auto same = [](double x, double y) { return x == y || (std::isnan(x) && std::isnan(y)); };
  return same(a.change_rel, b.change_rel) && same(a.spread_prior_rel, b.spread_prior_rel) &&
         same(a.spread_map_rel, b.spread_map_rel) && a.sensors == b.sensors && a.dof == b.dof;
}

/// `bundle`'s scans of this liner (dated from its installation on) projected onto `model`'s map,
/// by date; an earlier one is a previous liner's (SetPriorFromHistory).
void ProjectScans(const core::Bundle& bundle, CrusherModel& model) {
  for (const core::Scan& scan : bundle.scans) {
    if (scan.date < model.config.installed_at) continue;
    ModelScan s;
    s.faces = core::ProjectScanToFaces(model.map, scan);
    s.scan.file = scan.file;
    s.scan.date = scan.date;
    model.scans.push_back(std::move(s));
  }
  model.SortScans();
}

}  // namespace

std::unique_ptr<CrusherModel> CrusherModel::FromBundle(const core::Bundle& bundle, const core::ReconstructionOptions& options) {
  auto m = std::make_unique<CrusherModel>();
  m->config = bundle.crusher;
  m->map = bundle.map;
  m->plan = core::PrepareReconstruction(m->config, m->map, options);
  ProjectScans(bundle, *m);
  SetPriorFromHistory(bundle, *m);
  return m;
}

std::unique_ptr<CrusherModel> CrusherModel::FromBundle(const core::Bundle& bundle, core::MapModel model,
                                                       const core::ReconstructionOptions& options) {
  auto m = std::make_unique<CrusherModel>();
  m->config = bundle.crusher;
  m->map = bundle.map;
  m->plan = core::PrepareReconstruction(m->config, m->map, std::move(model), options);
  ProjectScans(bundle, *m);
  SetPriorFromHistory(bundle, *m);
  return m;
}

bool CrusherModel::SetPrior(const std::string& campaign, const core::Scan& scan, const std::string& file) {
  PriorScan p;
  p.campaign = campaign;
  p.scan.faces = core::ProjectScanToFaces(map, scan);
  p.scan.scan.file = file;
  p.scan.scan.date = scan.date;
  p.wear_at_sensors = ScanWearAtSensors(config, map, p.scan.faces, std::max(plan.model.face_size_m, 1e-4));
  if (p.wear_at_sensors.empty()) return false;  // no row scale to divide the scan's pattern by
  prior = std::move(p);
  return true;
}

void CrusherModel::SortScans() {
  std::stable_sort(scans.begin(), scans.end(), [](const ModelScan& a, const ModelScan& b) { return a.scan.date < b.scan.date; });
}

std::shared_ptr<const ScannedPlan> CrusherModel::PlanWithScan(const std::vector<core::Reading>& readings, core::TimePoint at,
                                                              const std::vector<std::string>& stuck, bool interval_centre) const {
  const ModelScan* latest = nullptr;
  size_t index = 0;
  for (size_t k = 0; k < scans.size(); ++k)
    if (scans[k].scan.date <= at) {
      latest = &scans[k];
      index = k;
    }
  if (!latest) return prior ? PlanWithPrior(readings, at, stuck, interval_centre) : nullptr;
  std::vector<core::SensorWear> wear = core::ScanSensorWear(config, readings, latest->scan.date, stuck, at, interval_centre);
  std::lock_guard<std::mutex> lock(scan_mutex_);
  const auto same = [&](const ScannedPlan& p) {
    if (p.scan != index || p.wear_at_scan.size() != wear.size()) return false;
    for (size_t k = 0; k < wear.size(); ++k)
      if (p.wear_at_scan[k].sensor_id != wear[k].sensor_id || p.wear_at_scan[k].wear_mm != wear[k].wear_mm) return false;
    return true;
  };
  if (scanned_ && !scanned_->prior && same(*scanned_)) return scanned_;
  auto p = std::make_shared<ScannedPlan>();
  p->scan = index;
  p->plan = plan;
  p->correction = core::ApplyScan(p->plan, latest->faces, wear);
  p->wear_at_scan = std::move(wear);
  scanned_ = p;
  return p;
}

std::shared_ptr<const ScannedPlan> CrusherModel::PlanWithPrior(const std::vector<core::Reading>& readings, core::TimePoint at,
                                                               const std::vector<std::string>& stuck,
                                                               bool interval_centre) const {
  // The sensors that set the scales now: not stale (an old day's wear), not stuck.
  std::vector<core::SensorWear> now = core::FreshSensorWearAt(config, readings, at, {}, nullptr, interval_centre);
  std::erase_if(now,
                [&](const core::SensorWear& w) { return std::find(stuck.begin(), stuck.end(), w.sensor_id) != stuck.end(); });
  const PriorCheck check = CheckPrior(*this, *prior, now);
  std::lock_guard<std::mutex> lock(scan_mutex_);
  if (scanned_ && scanned_->prior && SameCheck(*scanned_->prior, check)) return scanned_;
  // The prior's faces with the pattern's change added to their error: it weighs against the map as
  // a scan of this liner would, less by as much as the pattern may have moved.
  core::ScanFaces faces = prior->scan.faces;
  for (Eigen::Index i = 0; i < faces.wear_mm.size(); ++i) {
    if (std::isfinite(faces.wear_mm[i]))
      faces.sd_mm[i] = std::hypot(faces.sd_mm[i], check.change_rel * std::max(0.0, faces.wear_mm[i]));
  }
  auto p = std::make_shared<ScannedPlan>();
  p->prior = check;
  p->plan = plan;
  p->correction = core::ApplyScan(p->plan, faces, prior->wear_at_sensors);
  p->wear_at_scan = prior->wear_at_sensors;
  scanned_ = p;
  return p;
}

}  // namespace lw::estimate
