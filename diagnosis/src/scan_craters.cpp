// Material loss read from a scan's shape (scan_craters.hpp).
#include "scan_craters.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <utility>

#include "core/median.hpp"
#include "core/surface_index.hpp"
#include "model_fit.hpp"
#include "text_format.hpp"

namespace lw::diagnosis::detail {
namespace {

constexpr double kPi = 3.14159265358979323846;

struct Background {
  double value = kNaN;
  double gradient = 0;  ///< mm per m, at the face
};

// The ring's faces' wear fitted with a surface (linear around, quadratic along z: the wear profile
// curves along the liner), twice, the second time
// without the faces beyond 3 robust sd of the first (a crater reaching into the ring, or another):
// its value at the face is the face's background.
Background RingBackground(const core::WearMap& map, const core::SurfaceIndex& ring, const std::vector<double>& wear, size_t f,
                          double r_in, double r_out) {
  std::vector<Eigen::Vector3d> pts;  // dz, arc, wear
  const auto fi = static_cast<Eigen::Index>(f);
  size_t quadrant[4] = {0, 0, 0, 0};  // below, above, one side, the other
  ring.Visit(map.z[fi], map.theta_deg[fi], map.radius[fi], [&](uint32_t j, double dz, double arc) {
    const double d2 = dz * dz + arc * arc;
    if (d2 < r_in * r_in || d2 > r_out * r_out || !std::isfinite(wear[j])) return;
    pts.push_back({dz, arc, wear[j]});
    ++quadrant[std::fabs(dz) >= std::fabs(arc) ? (dz < 0 ? 0 : 1) : (arc < 0 ? 2 : 3)];
  });
  if (pts.size() < 12) return {};
  // Only where the ring surrounds the face: every quarter holds at least half its share. Near the
  // map's ends or a large unscanned area the background would be an extrapolation (the discharge
  // edge's own wear peak then looks like a dip).
  for (size_t q : quadrant)
    if (8 * q < pts.size()) return {};
  auto row = [&](const Eigen::Vector3d& p) {
    Eigen::Vector4d x(1.0, p.x(), p.y(), p.x() * p.x());
    return x;
  };
  std::vector<char> keep(pts.size(), 1);
  Eigen::Vector4d c = Eigen::Vector4d::Zero();
  for (int pass = 0; pass < 2; ++pass) {
    Eigen::Matrix4d a = Eigen::Matrix4d::Zero();
    Eigen::Vector4d b = Eigen::Vector4d::Zero();
    size_t n = 0;
    for (size_t k = 0; k < pts.size(); ++k) {
      if (!keep[k]) continue;
      const Eigen::Vector4d x = row(pts[k]);
      a += x * x.transpose();
      b += x * pts[k].z();
      ++n;
    }
    if (n < 8) return {};
    c = a.ldlt().solve(b);
    std::vector<double> res(pts.size());
    for (size_t k = 0; k < pts.size(); ++k) res[k] = std::fabs(pts[k].z() - row(pts[k]).dot(c));
    const double s = 1.4826 * core::UpperMedian(res, kNaN);
    for (size_t k = 0; k < pts.size(); ++k) keep[k] = res[k] <= 3.0 * s + 1e-9;
  }
  if (!std::isfinite(c[0])) return {};
  return {c[0], std::hypot(c[1], c[2])};
}

// Each scanned face's wear minus its ring background (NaN where either is missing), and the
// background's gradient there.
void Residuals(const core::WearMap& map, const std::vector<double>& wear, double r_in, double r_out, std::vector<double>& resid,
               std::vector<double>& gradient) {
  const size_t nf = map.face_count();
  resid.assign(nf, kNaN);
  gradient.assign(nf, 0.0);
  const core::SurfaceIndex ring(map, r_out);
  for (size_t f = 0; f < nf; ++f) {
    if (!std::isfinite(wear[f])) continue;
    const Background bg = RingBackground(map, ring, wear, f, r_in, r_out);
    if (!std::isfinite(bg.value)) continue;
    resid[f] = wear[f] - bg.value;
    gradient[f] = bg.gradient;
  }
}

// Faces within `index`'s reach of any face of `from` with a residual and not yet in `mark` (marked here).
std::vector<size_t> Layer(const core::WearMap& map, const core::SurfaceIndex& index, const std::vector<size_t>& from,
                          const std::vector<double>& resid, std::vector<char>& mark) {
  std::vector<size_t> out;
  for (size_t f : from) {
    const auto fi = static_cast<Eigen::Index>(f);
    index.ForEachWithin(map.z[fi], map.theta_deg[fi], map.radius[fi], [&](uint32_t j, double) {
      if (mark[j] || !std::isfinite(resid[j])) return;
      mark[j] = 1;
      out.push_back(j);
    });
  }
  return out;
}

std::vector<double> Values(const std::vector<size_t>& faces, const std::vector<double>& v) {
  std::vector<double> out;
  out.reserve(faces.size());
  for (size_t f : faces) out.push_back(v[f]);
  return out;
}

// Place, size, depth and edge of one patch; `adjacent` finds each face's neighbours.
ScanCrater DescribePatch(const core::WearMap& map, const core::SurfaceIndex& adjacent, const std::vector<size_t>& patch,
                         const std::vector<double>& resid, const std::vector<double>& gradient, double& compactness) {
  ScanCrater c;
  double sa = 0, sz = 0, ss = 0, sc = 0, sr = 0;
  for (size_t f : patch) {
    const auto fi = static_cast<Eigen::Index>(f);
    const double a = map.areas[fi];
    sa += a;
    sz += a * map.z[fi];
    ss += a * std::sin(map.theta_deg[fi] * kPi / 180.0);
    sc += a * std::cos(map.theta_deg[fi] * kPi / 180.0);
    sr += a * map.radius[fi];
    c.volume_mm_m2 += a * resid[f];
    c.max_depth_mm = std::max(c.max_depth_mm, resid[f]);
  }
  c.area_m2 = sa;
  c.z_m = sz / sa;
  c.theta_deg = std::fmod(std::atan2(ss, sc) * 180.0 / kPi + 360.0, 360.0);
  const double radius = sr / sa;
  c.radius_m = radius;
  double lo = 0, hi = 0, reach = 0, best = std::numeric_limits<double>::max();
  c.z_min_m = c.z_max_m = c.z_m;
  for (size_t f : patch) {
    const auto fi = static_cast<Eigen::Index>(f);
    const double d = AngleDiffDeg(map.theta_deg[fi], c.theta_deg);
    lo = std::min(lo, d);
    hi = std::max(hi, d);
    c.z_min_m = std::min(c.z_min_m, map.z[fi]);
    c.z_max_m = std::max(c.z_max_m, map.z[fi]);
    const double r = std::hypot(map.z[fi] - c.z_m, d * kPi / 180.0 * radius);
    reach = std::max(reach, r);
    if (r < best) {
      best = r;
      c.ring_gradient_mm_per_m = gradient[f];
    }
  }
  c.theta_min_deg = std::fmod(c.theta_deg + lo + 360.0, 360.0);
  c.theta_max_deg = std::fmod(c.theta_deg + hi + 360.0, 360.0);
  reach += 0.5 * std::sqrt(sa / static_cast<double>(patch.size()));  // to the outer face's edge
  compactness = sa / (kPi * reach * reach);
  c.depth_mm = core::UpperMedian(Values(patch, resid), kNaN);
  c.faces = patch.size();
  // The edge: the patch's faces with a neighbour outside, those neighbours, and the next layer out.
  std::vector<char> mark(map.face_count(), 0);
  for (size_t f : patch) mark[f] = 1;
  const std::vector<size_t> out1 = Layer(map, adjacent, patch, resid, mark);
  const std::vector<size_t> out2 = Layer(map, adjacent, out1, resid, mark);
  std::vector<char> in_out1(map.face_count(), 0);
  for (size_t f : out1) in_out1[f] = 1;
  std::vector<size_t> boundary;
  for (size_t f : patch) {
    bool edge = false;
    const auto fi = static_cast<Eigen::Index>(f);
    adjacent.ForEachWithin(map.z[fi], map.theta_deg[fi], map.radius[fi], [&](uint32_t j, double) {
      edge = edge || in_out1[j];
      if (!std::isfinite(resid[j]) && !mark[j]) {
        mark[j] = 1;
        ++c.open_edge_faces;
      }
    });
    if (edge) boundary.push_back(f);
  }
  c.edge_faces = out1.size();
  const double in_edge = core::UpperMedian(Values(boundary, resid), kNaN),
               out_edge = core::UpperMedian(Values(out1, resid), kNaN);
  const double next = core::UpperMedian(Values(out2, resid), kNaN);
  c.edge_step_mm = std::isfinite(in_edge) && std::isfinite(out_edge) ? in_edge - out_edge : 0.0;
  c.outside_change_mm = std::isfinite(out_edge) && std::isfinite(next) ? out_edge - next : 0.0;
  return c;
}

// Connected patches of faces above `grow` around seeds above `seed`, deepest seed first.
std::vector<std::vector<size_t>> Patches(const core::WearMap& map, const core::SurfaceIndex& adjacent,
                                         const std::vector<double>& resid, double seed, double grow) {
  std::vector<size_t> seeds;
  for (size_t f = 0; f < resid.size(); ++f)
    if (resid[f] > seed) seeds.push_back(f);
  std::sort(seeds.begin(), seeds.end(), [&](size_t a, size_t b) { return resid[a] > resid[b]; });
  std::vector<char> taken(resid.size(), 0);
  std::vector<std::vector<size_t>> patches;
  for (size_t s : seeds) {
    if (taken[s]) continue;
    std::vector<size_t> patch = {s};
    taken[s] = 1;
    for (size_t k = 0; k < patch.size(); ++k) {
      const auto fi = static_cast<Eigen::Index>(patch[k]);
      adjacent.ForEachWithin(map.z[fi], map.theta_deg[fi], map.radius[fi], [&](uint32_t j, double) {
        if (taken[j] || !(resid[j] > grow)) return;
        taken[j] = 1;
        patch.push_back(j);
      });
    }
    patches.push_back(std::move(patch));
  }
  return patches;
}

}  // namespace

std::vector<ScanCrater> FindScanCraters(const core::WearMap& map, const MapFields& fields, const ScanCells& scan,
                                        size_t scan_index, const CraterRules& rules) {
  std::vector<ScanCrater> craters;
  const size_t nf = map.face_count();
  if (nf == 0 || scan.face_wear_mm.size() != nf) return craters;
  const double h = fields.face_size_m;
  const double r_in = std::max(rules.ring_inner_m, 2.0 * h);
  const double r_out = std::max(rules.ring_outer_m, r_in + 2.0 * h);
  std::vector<double> resid, gradient;
  Residuals(map, scan.face_wear_mm, r_in, r_out, resid, gradient);
  std::vector<double> finite;
  for (double r : resid)
    if (std::isfinite(r)) finite.push_back(r);
  if (finite.size() < 20) return craters;
  // The scan's own face-to-face noise: the residuals' robust sd (a crater is a few of many faces).
  const double centre = core::UpperMedian(finite, kNaN);
  for (double& r : finite) r = std::fabs(r - centre);
  const double noise = std::max(1.4826 * core::UpperMedian(finite, kNaN), 0.05);
  const double seed = std::max(rules.seed_sigmas * noise, rules.min_depth_mm);
  const core::SurfaceIndex adjacent(map, 1.2 * h);
  for (const std::vector<size_t>& patch : Patches(map, adjacent, resid, seed, 0.5 * seed)) {
    if (patch.size() < 2) continue;
    double area = 0;
    for (size_t f : patch) area += map.areas[static_cast<Eigen::Index>(f)];
    if (area < rules.min_area_m2 || area > rules.max_area_m2) continue;
    double compactness = 0;
    ScanCrater c = DescribePatch(map, adjacent, patch, resid, gradient, compactness);
    // Seen whole: at most one neighbour in five without a tested value (a patch cut by the map's
    // end or an unscanned area shows no wall on that side; a face the scan missed is no matter).
    if (5 * c.open_edge_faces > c.edge_faces || compactness < rules.min_compactness ||
        c.depth_mm < std::max(0.75 * seed, rules.min_depth_mm))
      continue;
    if (c.edge_step_mm < rules.min_edge_fraction * c.depth_mm) continue;
    if (c.edge_step_mm < rules.min_edge_over_outside * std::max(c.outside_change_mm, 0.5 * noise)) continue;
    c.scan = scan_index;
    c.t_days = scan.t_days;
    c.file = scan.file;
    c.noise_mm = noise;
    craters.push_back(c);
  }
  return craters;
}

namespace {

// Surface distance (m) from a crater's centre to (z, theta), at the crater's radius.
double DistanceTo(const ScanCrater& c, double z, double theta_deg) {
  return std::hypot(z - c.z_m, AngleDiffDeg(theta_deg, c.theta_deg) * kPi / 180.0 * c.radius_m);
}

// The crater's half-size: the radius of a disc of its area.
double HalfSize(const ScanCrater& c) {
  return std::sqrt(c.area_m2 / kPi);
}

}  // namespace

std::vector<CraterSighting> FindCratersInScans(const core::WearMap& map, const MapFields& fields,
                                               const std::vector<ScanCells>& scans, const CraterRules& rules) {
  std::vector<size_t> order(scans.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return scans[a].t_days < scans[b].t_days; });
  std::vector<CraterSighting> sightings;
  for (size_t si : order) {
    for (const ScanCrater& c : FindScanCraters(map, fields, scans[si], si, rules)) {
      bool again = false;
      for (CraterSighting& s : sightings) {
        if (DistanceTo(s.crater, c.z_m, c.theta_deg) <= HalfSize(s.crater) + HalfSize(c)) {
          s.seen_again_days.push_back(c.t_days);
          again = true;
          break;
        }
      }
      if (!again) sightings.push_back({c, {}});
    }
  }
  return sightings;
}

namespace {

void AddCraterParts(const ScanCrater& c, core::TimePoint installed_at, Finding& f) {
  f.parameters["z_min_m"] = Round(c.z_min_m, 3);
  f.parameters["z_max_m"] = Round(c.z_max_m, 3);
  f.parameters["theta_min_deg"] = Round(c.theta_min_deg, 1);
  f.parameters["theta_max_deg"] = Round(c.theta_max_deg, 1);
  f.parameters["area_m2"] = Round(c.area_m2, 3);
  f.evidence["found_in"] = f.parameters.contains("sensor_id") ? "sensor and scan" : "scan";
  f.evidence["scan"] = c.file;
  f.evidence["scan_date"] = core::FormatIsoTime(core::AddDays(installed_at, c.t_days));
  f.evidence["scan_depth_mm"] = Round(c.depth_mm, 1);
  f.evidence["scan_max_depth_mm"] = Round(c.max_depth_mm, 1);
  f.evidence["volume_litres"] = Round(c.volume_mm_m2, 2);
  f.evidence["faces"] = c.faces;
  f.evidence["edge_step_mm"] = Round(c.edge_step_mm, 2);
  f.evidence["outside_change_mm"] = Round(c.outside_change_mm, 2);
  f.evidence["ring_gradient_mm_per_m"] = Round(c.ring_gradient_mm_per_m, 2);
  f.evidence["scan_face_noise_mm"] = Round(c.noise_mm, 2);
}

std::string CraterSentence(const ScanCrater& c, core::TimePoint installed_at) {
  return Fmt(
      "The scan of %s shows a sharp-edged crater at z %.2f m (%.2f-%.2f m), theta %.0f-%.0f deg: %.3f m^2, %.1f mm "
      "deeper than the wear around it, its edge a %.1f mm step where the wear just outside changes by %.1f mm "
      "(the scan's face noise %.2f mm).",
      core::FormatIsoTime(core::AddDays(installed_at, c.t_days)).substr(0, 10).c_str(), c.z_m, c.z_min_m, c.z_max_m,
      c.theta_min_deg, c.theta_max_deg, c.area_m2, c.depth_mm, c.edge_step_mm, c.outside_change_mm, c.noise_mm);
}

Finding SensorLossFinding(const SensorData& s, const LossEvent& loss, core::TimePoint installed_at) {
  Finding f;
  f.effect = kMaterialLoss;
  f.confidence = Round(std::clamp(0.5 + 0.08 * loss.depth_mm, 0.5, 0.95), 3);
  f.parameters["sensor_id"] = s.id;
  f.parameters["time"] = core::FormatIsoTime(core::AddDays(installed_at, loss.t_days));
  f.parameters["depth_mm"] = Round(loss.depth_mm, 1);
  f.parameters["z_m"] = Round(s.z, 3);
  f.parameters["theta_deg"] = Round(s.theta, 1);
  f.explanation =
      Fmt("Sensor %s lost %.0f mm at once on day %.1f, then kept wearing at its normal rate (%.2f mm/day) from the lower level: "
          "material broke out of the liner (spall), which a DEM wear law does not model. Not a sensor fault: a crack would "
          "stay flat until the wear caught up.",
          s.id.c_str(), loss.depth_mm, loss.t_days, s.analysis.rate_mm_per_day);
  f.evidence["step_mm"] = loss.step_mm;
  f.evidence["rate_mm_per_day"] = Round(s.analysis.rate_mm_per_day, 3);
  return f;
}

Finding CraterFinding(const CraterSighting& s, core::TimePoint installed_at) {
  const ScanCrater& c = s.crater;
  Finding f;
  f.effect = kMaterialLoss;
  // Deeper and sharper is surer; a scan alone never reaches a sensor's step's top confidence.
  const double sharp = std::clamp(c.edge_step_mm / std::max(c.depth_mm, 1e-9), 0.0, 1.0);
  f.confidence = Round(std::clamp(0.45 + 0.02 * c.depth_mm + 0.1 * sharp, 0.5, 0.9), 3);
  f.parameters["z_m"] = Round(c.z_m, 3);
  f.parameters["theta_deg"] = Round(c.theta_deg, 1);
  f.parameters["depth_mm"] = Round(c.depth_mm, 1);
  AddCraterParts(c, installed_at, f);
  nlohmann::ordered_json again = nlohmann::ordered_json::array();
  for (double d : s.seen_again_days) again.push_back(core::FormatIsoTime(core::AddDays(installed_at, d)));
  f.evidence["seen_again_in_scans"] = again;
  f.explanation = CraterSentence(c, installed_at) +
                  " Material broke out of the liner there (spall), which a DEM wear law does not model; no smooth wear "
                  "pattern makes such a wall. No sensor's step saw it: when it broke out is known only as before that scan.";
  return f;
}

}  // namespace

std::vector<Finding> MaterialLossFindings(const std::vector<SensorData>& sensors, const std::vector<CraterSighting>& craters,
                                          double face_size_m, core::TimePoint installed_at) {
  std::vector<Finding> findings;
  std::vector<char> used(craters.size(), 0);
  for (const SensorData& s : sensors) {
    for (const LossEvent& loss : s.analysis.losses) {
      Finding f = SensorLossFinding(s, loss, installed_at);
      // The crater the sensor sits in (its centre within the crater's half-size and a face), if a
      // scan after the step shows one: the same spall, one finding.
      for (size_t k = 0; k < craters.size(); ++k) {
        const ScanCrater& c = craters[k].crater;
        if (used[k] || c.t_days < loss.t_days) continue;
        if (DistanceTo(c, s.z, s.theta) > HalfSize(c) + face_size_m) continue;
        used[k] = 1;
        AddCraterParts(c, installed_at, f);
        f.explanation += " " + CraterSentence(c, installed_at) + " It is this spall, seen by the sensor and the scan.";
        break;
      }
      findings.push_back(std::move(f));
    }
  }
  for (size_t k = 0; k < craters.size(); ++k)
    if (!used[k]) findings.push_back(CraterFinding(craters[k], installed_at));
  return findings;
}

}  // namespace lw::diagnosis::detail
