#include "core/scan_correction.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "core/median.hpp"
#include "core/surface_index.hpp"

namespace lw::core {
namespace {

constexpr double kNone = std::numeric_limits<double>::quiet_NaN();  // a median of no samples

}  // namespace

const Scan* LatestScanAt(const std::vector<Scan>& scans, TimePoint at) {
  const Scan* latest = nullptr;
  for (const Scan& s : scans)
    if (s.date <= at && (!latest || s.date >= latest->date)) latest = &s;
  return latest;
}

ScanFaces ProjectScanToFaces(const WearMap& map, const Scan& scan, double floor_mm) {
  const Eigen::Index n = static_cast<Eigen::Index>(map.face_count());
  ScanFaces out;
  out.wear_mm = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::quiet_NaN());
  out.sd_mm = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::quiet_NaN());
  out.points.assign(static_cast<size_t>(n), 0);
  out.points_total = scan.points.size();
  if (n == 0) return out;
  std::vector<double> sizes;
  for (Eigen::Index i = 0; i < n; ++i) sizes.push_back(std::sqrt(2.0 * std::max(map.areas[i], 0.0)));
  const double face = std::max(UpperMedian(sizes, kNone), 1e-4);
  const SurfaceIndex index(map, 2.0 * face);
  std::vector<std::vector<double>> depth(static_cast<size_t>(n));
  for (const Eigen::Vector3d& q : scan.points) {
    if (!q.allFinite()) continue;
    const double r = std::hypot(q.x(), q.y());
    double theta = std::atan2(q.y(), q.x()) * 180.0 / M_PI;
    if (theta < 0) theta += 360.0;
    long best = -1;
    double best_d2 = std::numeric_limits<double>::max();
    index.ForEachWithin(q.z(), theta, r, [&](uint32_t j, double d2) {
      if (d2 < best_d2) {
        best_d2 = d2;
        best = static_cast<long>(j);
      }
    });
    if (best < 0) continue;
    const auto j = static_cast<size_t>(best);
    depth[j].push_back(1000.0 * (map.centroids[j] - q).dot(map.normals[j]));
    ++out.points_used;
  }
  for (Eigen::Index i = 0; i < n; ++i) {
    auto& d = depth[static_cast<size_t>(i)];
    if (d.empty()) continue;
    const double m = UpperMedian(d, kNone);
    double ss = 0;
    for (double x : d) ss += (x - m) * (x - m);
    // One point: its scatter is unknown, counted as 1 mm; more: the sample sd / sqrt(n).
    const double se = d.size() > 1 ? std::sqrt(ss / static_cast<double>(d.size() - 1) / static_cast<double>(d.size())) : 1.0;
    out.wear_mm[i] = m;
    out.sd_mm[i] = std::sqrt(se * se + floor_mm * floor_mm);
    out.points[static_cast<size_t>(i)] = static_cast<int>(d.size());
  }
  return out;
}

ScanCorrection ApplyScan(ReconstructionPlan& plan, const ScanFaces& scan, const std::vector<SensorWear>& wear_at_scan) {
  ScanCorrection out;
  if (!plan.map || !plan.crusher) {
    out.detail = "no map";
    return out;
  }
  const WearMap& map = *plan.map;
  const CrusherConfig& crusher = *plan.crusher;
  const Eigen::Index n = plan.intensity.size();
  if (scan.wear_mm.size() != n) {
    out.detail = "the scan was projected on another map";
    return out;
  }
  // Row scales at the scan's date (Eq. 9 with the uncorrected map).
  const Reconstruction at_scan = Reconstruct(plan, wear_at_scan);
  std::map<std::string, std::pair<double, double>> scale;  // row -> (scale, sd)
  for (const RowSummary& r : at_scan.rows)
    if (r.sensors_used > 0 && r.scale_mm_per_unit > 0) scale[r.row] = {r.scale_mm_per_unit, r.scale_sd};
  if (scale.empty()) {
    out.detail = "no row has a sensor reading at the scan's date";
    return out;
  }
  // Per face: the map model's intensity and error, the scan's intensity and error.
  struct Face {
    Eigen::Index i;
    double i_m, sd_m, i_s, sd_s;
    /// What the scan's difference from the map holds beyond both noises (a variance; < 0 when less).
    double Excess() const { return (i_s - i_m) * (i_s - i_m) - sd_m * sd_m - sd_s * sd_s; }
  };
  std::vector<Face> faces;
  for (Eigen::Index i = 0; i < n; ++i) {
    const int row = plan.face_row[static_cast<size_t>(i)];
    if (row < 0 || !std::isfinite(scan.wear_mm[i]) || !(scan.sd_mm[i] > 0)) continue;
    const auto it = scale.find(crusher.rows[static_cast<size_t>(row)].name);
    if (it == scale.end()) continue;
    // The scan's intensity: its wear over the face's scale at the scan's date (Eq. 9's predicted wear
    // there over the intensity: the row scale, interpolated along z as Reconstruct does). Its error
    // is the scan's alone: the scale's error is shared by the row and cancels, because the sensors'
    // intensities are corrected from the same scan below (later wear = scan wear x the sensors'
    // wear since then over their wear at the scan, whatever the scale was).
    // Where Eq. 9 says the face is worn through its wear is clamped at the liner's thickness, so the
    // face's scale is its row's: those are the faces where the map is most likely wrong and the
    // scan matters most (a hot spot of the map's noise the scan does not see).
    const double i_m = plan.intensity[i], pred = at_scan.wear_mm[i];
    if (!(i_m > 0) || !(pred > 0)) continue;
    const double k = pred < crusher.thickness_new_mm ? pred / i_m : at_scan.rows[static_cast<size_t>(row)].scale_mm_per_unit;
    if (!(k > 0)) continue;
    faces.push_back({i, i_m, plan.intensity_rel_sd[i] * i_m, std::max(scan.wear_mm[i], 0.0) / k, scan.sd_mm[i] / k});
  }
  // The map's own model error: a DEM map's pattern can be wrong beyond its sampling noise (the
  // physics it left out, the chamber it assumed, a discharge edge it resolves worst). Its relative
  // variance tau^2 is what the scan's differences from the map hold beyond both noises (moment
  // estimate, top 2 % trimmed, >= 0), over the whole scan (reported) and per band of z one face
  // high: the error is not the same everywhere, and a global figure set by the many faces where the
  // map is right would let the map outweigh the scan where it is wrong. A face's own excess counts
  // too when it is larger: a hot spot narrower than the map model's kernel (a discharge-edge sector
  // smoothed around the ring) is a few faces of a band, too few to move the band's mean, and there
  // the scan, ground truth at its date, must win.
  const double face = std::max(plan.model.face_size_m, 1e-4);  // the map's median face edge
  auto tau_of = [](std::vector<double> excess) {
    std::sort(excess.begin(), excess.end());
    const size_t keep = excess.size() - excess.size() / 50;
    double sum = 0;
    for (size_t k = 0; k < keep; ++k) sum += excess[k];
    return keep ? std::sqrt(std::max(0.0, sum / static_cast<double>(keep))) : 0.0;
  };
  const double z0 = map.z.size() ? map.z.minCoeff() : 0.0;
  auto band_of = [&](Eigen::Index i) { return static_cast<long>(std::floor((map.z[i] - z0) / face)); };
  std::map<long, std::vector<double>> band_excess;  // relative excess (over i_m^2) of every face (i_m > 0)
  {
    std::vector<double> excess;
    for (const Face& f : faces) {
      excess.push_back(f.Excess() / (f.i_m * f.i_m));
      band_excess[band_of(f.i)].push_back(excess.back());
    }
    out.map_model_error_rel = tau_of(std::move(excess));
  }
  constexpr size_t kMinBandFaces = 20;  // fewer: the band takes the whole scan's figure
  std::map<long, double> band_tau;
  for (auto& [b, e] : band_excess) band_tau[b] = e.size() >= kMinBandFaces ? tau_of(std::move(e)) : out.map_model_error_rel;
  Eigen::VectorXd ratio = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::quiet_NaN());
  Eigen::VectorXd weight = Eigen::VectorXd::Zero(n);
  std::vector<double> ratios;
  for (const Face& f : faces) {
    const double tau = band_tau.at(band_of(f.i));
    const double var_m = f.sd_m * f.sd_m + std::max(std::pow(tau * f.i_m, 2), f.Excess());
    const double wm = var_m > 0 ? 1.0 / var_m : 0.0, ws = 1.0 / (f.sd_s * f.sd_s);
    const double i_new = wm > 0 ? (wm * f.i_m + ws * f.i_s) / (wm + ws) : f.i_s;
    const double sd_new = std::sqrt(1.0 / (wm + ws));
    ratio[f.i] = i_new / f.i_m;  // i_m > 0: faces hold only those
    weight[f.i] = ws / (wm + ws);
    ratios.push_back(ratio[f.i]);
    plan.intensity[f.i] = i_new;
    plan.intensity_rel_sd[f.i] = i_new > 0 ? sd_new / i_new : 1.0;
    ++out.faces_corrected;
  }
  if (out.faces_corrected == 0) {
    out.detail = "the scan covers no face of a row with sensors";
    return out;
  }
  out.median_ratio = UpperMedian(ratios, kNone);
  // Places the scan measured no face at, from the corrected faces around them (Gaussian weights of
  // the map's face size, within 1.5 of it):
  // - sensors: the mean ratio (corrected / map), so the row scale after the scan divides the
  //   sensors' wear by the intensity the scan measured there;
  // - faces no point fell on (a scan of a few points per face leaves a few per cent of faces empty,
  //   and one of them keeping the map's hot spot would be the liner's thinnest point): the mean of
  //   the corrected intensities, the scan's pattern interpolated.
  const SurfaceIndex index(map, 1.5 * face);
  // Mean ratio, corrected intensity and relative sd of the corrected faces around (z, theta); false
  // when there is none.
  struct Around {
    double ratio = 1, intensity = 0, rel_sd = 0;
  };
  auto around = [&](double z, double theta_deg, Around& a) {
    double sw = 0, sr = 0, si = 0, s_rel2 = 0;
    index.ForEachWithin(z, theta_deg, -1, [&](uint32_t j, double d2) {
      const auto jj = static_cast<Eigen::Index>(j);
      if (!std::isfinite(ratio[jj])) return;
      const double w = map.areas[jj] * std::exp(-0.5 * d2 / (face * face));
      sw += w;
      sr += w * ratio[jj];
      si += w * plan.intensity[jj];
      s_rel2 += w * plan.intensity_rel_sd[jj] * plan.intensity_rel_sd[jj];
    });
    if (!(sw > 0)) return false;
    a = {sr / sw, si / sw, std::sqrt(s_rel2 / sw)};
    return true;
  };
  std::vector<std::pair<Eigen::Index, Around>> filled;  // applied after, so none feeds another
  for (Eigen::Index i = 0; i < n; ++i) {
    if (std::isfinite(ratio[i]) || plan.face_row[static_cast<size_t>(i)] < 0 || !(plan.intensity[i] > 0)) continue;
    Around a;
    if (around(map.z[i], map.theta_deg[i], a) && a.intensity > 0) filled.push_back({i, a});
  }
  out.face_ratio = ratio.unaryExpr([](double r) { return std::isfinite(r) ? r : 1.0; });
  for (const auto& [i, a] : filled) {
    out.face_ratio[i] = a.intensity / plan.intensity[i];  // > 0: only such faces are filled
    plan.intensity[i] = a.intensity;
    plan.intensity_rel_sd[i] = a.rel_sd;
  }
  out.face_weight = std::move(weight);
  out.faces_filled = filled.size();
  for (size_t s = 0; s < crusher.sensors.size(); ++s) {
    const auto& sn = crusher.sensors[s];
    Around a;
    if (!around(sn.z_m, sn.theta_deg, a)) continue;
    const double r = a.ratio, rel_sd = a.rel_sd;
    const auto ss = static_cast<Eigen::Index>(s);
    plan.sensor_intensity[ss] *= r;
    plan.sensor_intensity_sd[ss] = std::min(plan.sensor_intensity_sd[ss], rel_sd * plan.sensor_intensity[ss]);
  }
  return out;
}

}  // namespace lw::core
