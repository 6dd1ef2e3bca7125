#include "estimate/model.hpp"

#include <algorithm>

namespace lw::estimate {
namespace {

/// `bundle`'s scans projected onto `model`'s map, by date.
void ProjectScans(const core::Bundle& bundle, CrusherModel& model) {
  for (const core::Scan& scan : bundle.scans) {
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
  return m;
}

std::unique_ptr<CrusherModel> CrusherModel::FromBundle(const core::Bundle& bundle, core::MapModel model,
                                                       const core::ReconstructionOptions& options) {
  auto m = std::make_unique<CrusherModel>();
  m->config = bundle.crusher;
  m->map = bundle.map;
  m->plan = core::PrepareReconstruction(m->config, m->map, std::move(model), options);
  ProjectScans(bundle, *m);
  return m;
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
  if (!latest) return nullptr;
  std::vector<core::SensorWear> wear = core::ScanSensorWear(config, readings, latest->scan.date, stuck, at, interval_centre);
  std::lock_guard<std::mutex> lock(scan_mutex_);
  const auto same = [&](const ScannedPlan& p) {
    if (p.scan != index || p.wear_at_scan.size() != wear.size()) return false;
    for (size_t k = 0; k < wear.size(); ++k)
      if (p.wear_at_scan[k].sensor_id != wear[k].sensor_id || p.wear_at_scan[k].wear_mm != wear[k].wear_mm) return false;
    return true;
  };
  if (scanned_ && same(*scanned_)) return scanned_;
  auto p = std::make_shared<ScannedPlan>();
  p->scan = index;
  p->plan = plan;
  p->correction = core::ApplyScan(p->plan, latest->faces, wear);
  p->wear_at_scan = std::move(wear);
  scanned_ = p;
  return p;
}

}  // namespace lw::estimate
