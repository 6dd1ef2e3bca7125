// Data for the report's unwrapped-liner maps and thinnest points (report_maps.hpp).
#include "report_maps.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/forecast.hpp"
#include "core/reconstruction.hpp"
#include "core/scan_correction.hpp"
#include "core/thinnest_area.hpp"
#include "estimate/estimate.hpp"

namespace lw::diagnosis::detail {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string RowAt(const core::CrusherConfig& crusher, double z) {
  for (const core::Row& r : crusher.rows)
    if (z >= r.z_min_m && z <= r.z_max_m) return r.name;
  return "";
}

// Tiles of the unwrapped liner and, per face, the tile it belongs to.
struct Tiling {
  std::vector<LinerTile> tiles;
  std::vector<int> tile_of_face;
  bool faces = true;
};

Tiling MakeTiling(const core::WearMap& map) {
  Tiling t;
  const size_t nf = map.face_count();
  t.tile_of_face.assign(nf, -1);
  if (nf <= kMaxLinerTiles) {
    t.tiles.reserve(nf);
    for (size_t f = 0; f < nf; ++f) {
      LinerTile tile;
      const double c = map.theta_deg[static_cast<Eigen::Index>(f)];
      double lo = 1e300;
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d& p = map.points[map.faces[f][static_cast<size_t>(k)]];
        const double tv = std::atan2(p.y(), p.x()) * 180.0 / kPi;
        tile.theta_deg[k] = c + AngleDiffDeg(tv, c);  // unwrapped next to the centroid
        tile.z_m[k] = p.z();
        lo = std::min(lo, tile.theta_deg[k]);
      }
      if (lo < 0)
        for (double& th : tile.theta_deg) th += 360.0;
      t.tile_of_face[f] = static_cast<int>(f);
      t.tiles.push_back(tile);
    }
    return t;
  }
  // Large map: a regular raster of about kMaxLinerTiles / 2 cells (faces binned by centroid).
  t.faces = false;
  const size_t nt = 180;
  const size_t nz = std::max<size_t>(1, kMaxLinerTiles / 2 / nt);
  const double z0 = map.z.minCoeff(), z1 = map.z.maxCoeff();
  const double dz = std::max(z1 - z0, 1e-6) / static_cast<double>(nz), dt = 360.0 / static_cast<double>(nt);
  for (size_t iz = 0; iz < nz; ++iz) {
    for (size_t it = 0; it < nt; ++it) {
      LinerTile tile;
      tile.corners = 4;
      const double ta = dt * static_cast<double>(it), za = z0 + dz * static_cast<double>(iz);
      const double th[4] = {ta, ta + dt, ta + dt, ta};
      const double zz[4] = {za, za, za + dz, za + dz};
      for (int k = 0; k < 4; ++k) {
        tile.theta_deg[k] = th[k];
        tile.z_m[k] = zz[k];
      }
      t.tiles.push_back(tile);
    }
  }
  for (size_t f = 0; f < nf; ++f) {
    const auto e = static_cast<Eigen::Index>(f);
    const auto iz = std::min(nz - 1, static_cast<size_t>(std::max(0.0, (map.z[e] - z0) / dz)));
    const auto it = std::min(nt - 1, static_cast<size_t>(std::max(0.0, map.theta_deg[e] / dt)));
    t.tile_of_face[f] = static_cast<int>(iz * nt + it);
  }
  return t;
}

// Per-face values onto tiles: area-weighted mean of the finite values of a tile's faces (NaN if none).
std::vector<double> ToTiles(const Tiling& t, const core::WearMap& map, const Eigen::VectorXd& per_face) {
  if (t.faces) return std::vector<double>(per_face.data(), per_face.data() + per_face.size());
  std::vector<double> sum(t.tiles.size(), 0.0), area(t.tiles.size(), 0.0);
  for (size_t f = 0; f < t.tile_of_face.size(); ++f) {
    const auto e = static_cast<Eigen::Index>(f);
    if (!std::isfinite(per_face[e])) continue;
    const auto k = static_cast<size_t>(t.tile_of_face[f]);
    sum[k] += map.areas[e] * per_face[e];
    area[k] += map.areas[e];
  }
  std::vector<double> out(t.tiles.size(), kNaN);
  for (size_t k = 0; k < out.size(); ++k)
    if (area[k] > 0) out[k] = sum[k] / area[k];
  return out;
}

ThinnestPoint ModelThinnest(const std::string& label, core::TimePoint time, const core::Bundle& bundle,
                            const Eigen::VectorXd& wear) {
  ThinnestPoint p;
  p.label = label;
  p.time = time;
  Eigen::Index f = 0;
  const double w = wear.maxCoeff(&f);
  p.thickness_mm = std::max(0.0, bundle.crusher.thickness_new_mm - w);
  p.lo_mm = p.hi_mm = kNaN;
  p.z_m = bundle.map.z[f];
  p.theta_deg = bundle.map.theta_deg[f];
  p.row = RowAt(bundle.crusher, p.z_m);
  return p;
}

}  // namespace

std::vector<core::Reading> UsedReadings(const core::CrusherConfig& crusher, const std::vector<SensorCurve>& curves,
                                        double* last_days) {
  std::vector<core::Reading> used;
  double last = 0;
  for (const SensorCurve& c : curves) {
    for (size_t k = 0; k < c.reading_days.size(); ++k) {
      if (!c.reading_used[k] || !std::isfinite(c.reading_mm[k])) continue;
      core::Reading r;
      r.time = core::AddDays(crusher.installed_at, c.reading_days[k]);
      r.sensor_id = c.sensor_id;
      r.thickness_mm = c.reading_mm[k];
      used.push_back(r);
      last = std::max(last, c.reading_days[k]);
    }
  }
  std::sort(used.begin(), used.end(), [](const core::Reading& a, const core::Reading& b) {
    return a.sensor_id != b.sensor_id ? a.sensor_id < b.sensor_id : a.time < b.time;
  });
  if (last_days) *last_days = last;
  return used;
}

void FillLinerReport(const core::Bundle& bundle, const MapFields& fields, const std::vector<ScanCells>& scans,
                     const FaceWearAt& face_wear, DiagnosisResult& result) {
  const core::CrusherConfig& crusher = bundle.crusher;
  LinerReport& liner = result.liner;
  liner.thickness_new_mm = crusher.thickness_new_mm;
  liner.thickness_min_mm = crusher.thickness_min_mm;
  for (SensorCurve& c : result.curves) {
    if (const core::SensorInfo* s = crusher.FindSensor(c.sensor_id)) {
      c.z_m = s->z_m;
      c.theta_deg = s->theta_deg;
    }
  }
  if (bundle.map.face_count() == 0) return;
  const Tiling tiling = MakeTiling(bundle.map);
  liner.tiles = tiling.tiles;
  liner.tiles_are_faces = tiling.faces;

  // The readings the diagnosis kept (faults excluded): the live wear and forecast use the same.
  double now_days = 0;
  const std::vector<core::Reading> used = UsedReadings(crusher, result.curves, &now_days);
  liner.now = core::AddDays(crusher.installed_at, now_days);

  for (size_t si = 0; si < scans.size() && si < bundle.scans.size(); ++si) {
    LinerSnapshot s;
    s.time = bundle.scans[si].date;
    s.source = "scan:" + scans[si].file;
    const double t = core::DaysBetween(crusher.installed_at, s.time);
    Eigen::VectorXd measured(static_cast<Eigen::Index>(bundle.map.face_count()));
    for (Eigen::Index f = 0; f < measured.size(); ++f) {
      const auto k = static_cast<size_t>(f);
      measured[f] = k < scans[si].face_wear_mm.size() ? scans[si].face_wear_mm[k] : kNaN;
    }
    s.measured_mm = ToTiles(tiling, bundle.map, measured);
    s.baseline_mm = ToTiles(tiling, bundle.map, face_wear(false, t));
    s.improved_mm = ToTiles(tiling, bundle.map, face_wear(true, t));
    liner.snapshots.push_back(std::move(s));
  }
  const Eigen::VectorXd base_now = face_wear(false, now_days), best_now = face_wear(true, now_days);
  if (scans.empty()) {
    LinerSnapshot s;
    s.time = liner.now;
    s.source = "sensors";
    s.baseline_mm = ToTiles(tiling, bundle.map, base_now);
    s.improved_mm = ToTiles(tiling, bundle.map, best_now);
    liner.snapshots.push_back(std::move(s));
  }

  // The thinnest point now: the live reconstruction (Eq. 9 from the latest readings, with its band),
  // then the diagnosis' two models at the same time, then both at the prediction time.
  if (!used.empty()) {
    // The live wear as the server computes it (estimate::Estimate on the diagnosis' map model): the
    // latest scan corrects the map between the sensors, stale and stuck sensors set no scale.
    const auto model = estimate::CrusherModel::FromBundle(bundle, fields.model);
    const estimate::WearEstimate est = estimate::Estimate(*model, estimate::SamplesOf(used), liner.now);
    const core::Reconstruction& rec = est.reconstruction;
    const std::string with_scan = est.scan && est.scan->correction.detail.empty()
                                      ? ", the map corrected by scan " + model->ScanOf(*est.scan).scan.file
                                      : std::string();
    if (rec.remaining_mm.size() == static_cast<Eigen::Index>(bundle.map.face_count())) {
      ThinnestPoint p;
      p.label = "live reconstruction (Eq. 9 from the latest readings" + with_scan + ", as the dashboard shows it)";
      p.time = liner.now;
      p.thickness_mm = rec.min_thickness_mm;
      p.lo_mm = rec.min_thickness_lo_mm;
      p.hi_mm = rec.min_thickness_hi_mm;
      const auto f = static_cast<Eigen::Index>(rec.min_face);
      p.z_m = bundle.map.z[f];
      p.theta_deg = bundle.map.theta_deg[f];
      p.row = RowAt(crusher, p.z_m);
      p.status = rec.status;
      p.status_detail = rec.status_detail;
      liner.thinnest.push_back(p);
      liner.remaining_now_mm = ToTiles(tiling, bundle.map, rec.remaining_mm);
    }
    liner.thinnest_area = core::ThinnestAreaText(est.areas.liner);
    for (const core::RowForecast& r : est.row_forecasts)
      liner.reline.push_back({r.row, r.ok, r.note, r.reach, r.reach_earliest, r.reach_latest});
  }
  liner.thinnest.push_back(ModelThinnest("baseline model (plain Eq. 9, wear linear in time)", liner.now, bundle, base_now));
  liner.thinnest.push_back(ModelThinnest(ImprovedModelLabel(result.improved_model), liner.now, bundle, best_now));
  if (result.prediction && result.prediction->face_wear_baseline_mm.size() == bundle.map.face_count()) {
    const Prediction& pr = *result.prediction;
    const auto n = static_cast<Eigen::Index>(bundle.map.face_count());
    const std::string anchored =
        pr.faces_scan.detail.empty() && !pr.faces_scan.file.empty() ? " (from scan " + pr.faces_scan.file + ")" : "";
    liner.thinnest.push_back(ModelThinnest("baseline model at --predict-at" + anchored, pr.time, bundle,
                                           Eigen::Map<const Eigen::VectorXd>(pr.face_wear_baseline_mm.data(), n)));
    liner.thinnest.push_back(ModelThinnest("improved model at --predict-at" + anchored, pr.time, bundle,
                                           Eigen::Map<const Eigen::VectorXd>(pr.face_wear_improved_mm.data(), n)));
  }
}

}  // namespace lw::diagnosis::detail
