#include "core/thinnest_area.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdio>
#include <cstdlib>
#include <map>

#include "core/time.hpp"

#include "core/surface_index.hpp"

namespace lw::core {
namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

/// Per face: the three parts of its sd that combine
/// differently over a patch (header): the row scale's, the smoothing's (both correlated), the
/// sampling noise's (correlated over the kernel's footprint only).
struct FaceErrors {
  Eigen::VectorXd scale, bias, noise;
};

/// Each face's sd in its three parts. The map's part (beyond the row scale's) is the model's, or
/// Reconstruct's floor beyond every sensor's reach: its sampling noise is the model's share of the
/// model's part, and the rest, the floor included, is pattern error (correlated over an area).
FaceErrors SplitErrors(const ReconstructionPlan& plan, const Reconstruction& rec) {
  const Eigen::Index n = rec.remaining_sd_mm.size();
  const MapModel& m = plan.model;
  const bool split = m.intensity_noise_sd.size() == n && m.intensity_sd.size() == n;
  const bool estimated = rec.wear_estimate_mm.size() == n;
  FaceErrors e{Eigen::VectorXd(n), Eigen::VectorXd(n), Eigen::VectorXd(n)};
  for (Eigen::Index i = 0; i < n; ++i) {
    const double sd = rec.remaining_sd_mm[i];
    const double s = rec.scale_sd_mm.size() == n ? std::min(sd, rec.scale_sd_mm[i]) : 0.0;
    const double map_sd = std::sqrt(std::max(0.0, sd * sd - s * s));
    // Without the model's split, all of the map's error counts as correlated (the wider band).
    double q = 0.0;
    if (split && m.intensity_sd[i] > 0) q = std::clamp(std::pow(m.intensity_noise_sd[i] / m.intensity_sd[i], 2), 0.0, 1.0);
    const double model_sd = estimated ? std::min(map_sd, ModelMapSd(plan, rec.calibration, i, rec.wear_estimate_mm[i])) : map_sd;
    e.scale[i] = s;
    e.noise[i] = model_sd * std::sqrt(q);
    e.bias[i] = std::sqrt(std::max(0.0, map_sd * map_sd - e.noise[i] * e.noise[i]));
  }
  return e;
}

/// Area-weighted sums over the faces of one area.
struct Sums {
  double area = 0, wear = 0, scale = 0, bias = 0, noise = 0;
  void Add(double a, double w, const FaceErrors& e, Eigen::Index i) {
    area += a;
    wear += a * w;
    scale += a * e.scale[i];
    bias += a * e.bias[i];
    noise += a * e.noise[i];
  }
};

struct Context {
  const ReconstructionPlan& plan;
  const Reconstruction& rec;
  const FaceErrors errors;
  double new_mm = 0;
  double sigmas = 2.0;
  /// The map error's correlation lengths after smoothing, along z and around (2 sqrt(pi) x the
  /// kernel's sd, at least a face): an area of extent L keeps l / (l + L) of the variance per axis.
  double ell_z = 0, ell_arc = 0;
};

/// Thickness and band of an area from its sums; `extent_z`, `extent_arc`: its size along z and
/// around (a ring's: the circumference), which the map's error is averaged over.
void BandOf(const Context& c, const Sums& s, double extent_z, double extent_arc, ThinnestArea* a) {
  const double wear = s.wear / s.area, scale = s.scale / s.area, bias = s.bias / s.area, noise = s.noise / s.area;
  const double keep = c.ell_z / (c.ell_z + extent_z) * (c.ell_arc / (c.ell_arc + extent_arc));
  const double map_var = (bias * bias + noise * noise) * keep;
  const double sd = std::sqrt(scale * scale + map_var);
  a->scale_sd_mm = scale;
  a->map_sd_mm = std::sqrt(map_var);
  // From the unclamped estimate: an area estimated beyond the liner's thickness by more than its
  // band is worn through (hi 0); one at 0 within its band is not (yet) known to be.
  const double t = c.new_mm - wear;
  a->thickness_mm = std::clamp(t, 0.0, c.new_mm);
  a->lo_mm = std::clamp(t - c.sigmas * sd, 0.0, c.new_mm);
  a->hi_mm = std::clamp(t + c.sigmas * sd, 0.0, c.new_mm);
  a->raw_lo_mm = t - c.sigmas * sd;
  a->raw_hi_mm = t + c.sigmas * sd;
  a->half_width_mm = c.sigmas * sd;
}

/// The band of the thinnest of several areas: [min lo, min hi] over them, clipped and not.
struct MinBand {
  double lo = std::numeric_limits<double>::max(), hi = lo, raw_lo = lo, raw_hi = lo;
  void Add(const ThinnestArea& a) {
    lo = std::min(lo, a.lo_mm);
    hi = std::min(hi, a.hi_mm);
    raw_lo = std::min(raw_lo, a.raw_lo_mm);
    raw_hi = std::min(raw_hi, a.raw_hi_mm);
  }
  void Into(ThinnestArea* a) const {
    a->lo_mm = lo;
    a->hi_mm = hi;
    a->raw_lo_mm = raw_lo;
    a->raw_hi_mm = raw_hi;
    a->half_width_mm = 0.5 * (raw_hi - raw_lo);
  }
};

/// The centres of a row's square patches of side `patch`: on a half-patch grid within the row
/// (one height when the row is lower than a patch), around the circumference at the radius there.
std::vector<std::pair<double, double>> PatchCentres(const Row& r, const RadiusProfile& radius, double patch) {
  const double half = 0.5 * patch, height = r.z_max_m - r.z_min_m;
  std::vector<double> zs;
  if (height <= patch) {
    zs.push_back(0.5 * (r.z_min_m + r.z_max_m));
  } else {
    for (double z = r.z_min_m + half; z <= r.z_max_m - half + 1e-9; z += half) zs.push_back(z);
  }
  std::vector<std::pair<double, double>> out;
  for (const double z : zs) {
    const int n_around = std::max(1, static_cast<int>(std::ceil(2.0 * M_PI * radius.At(z) / half)));
    for (int k = 0; k < n_around; ++k) out.emplace_back(z, 360.0 * k / n_around);
  }
  return out;
}

/// Calls fn(face) for the faces of `row` in the patch centred at (z, theta) (index built with a
/// half-patch reach); returns whether the patch is an area of the row: a patch mostly off the map
/// (a hole, an edge) is not.
template <typename Fn>
bool VisitPatch(const ReconstructionPlan& plan, const SurfaceIndex& index, const RadiusProfile& radius, int row, double z,
                double theta, double patch, Fn&& fn) {
  const WearMap& map = *plan.map;
  const Row& r = plan.crusher->rows[static_cast<size_t>(row)];
  double area = 0;
  index.Visit(z, theta, radius.At(z), [&](uint32_t j, double, double) {
    if (plan.face_row[j] != row) return;
    area += map.areas[static_cast<Eigen::Index>(j)];
    fn(static_cast<Eigen::Index>(j));
  });
  return area >= 0.25 * patch * std::min(patch, r.z_max_m - r.z_min_m);
}

/// The row's thinnest square patch of side `patch`, with the band of the thinnest: [min lo, min hi]
/// over its patches. nullopt when no patch has faces.
std::optional<ThinnestArea> ThinnestPatch(const Context& c, const SurfaceIndex& index, const RadiusProfile& radius, int row,
                                          double patch) {
  const WearMap& map = *c.plan.map;
  const Row& r = c.plan.crusher->rows[static_cast<size_t>(row)];
  std::optional<ThinnestArea> best;
  MinBand band;
  for (const auto& [z, theta] : PatchCentres(r, radius, patch)) {
    Sums s;
    if (!VisitPatch(c.plan, index, radius, row, z, theta, patch,
                    [&](Eigen::Index i) { s.Add(map.areas[i], c.rec.wear_estimate_mm[i], c.errors, i); }))
      continue;
    ThinnestArea a;
    BandOf(c, s, std::min(patch, r.z_max_m - r.z_min_m), patch, &a);
    band.Add(a);
    if (!best || a.thickness_mm < best->thickness_mm) {
      a.z_m = z;
      a.theta_deg = theta;
      best = a;
    }
  }
  if (best) {
    band.Into(&*best);
    best->patch_m = patch;
  }
  return best;
}

/// A row's faces sorted by z, with running sums of what an area's band needs: a ring's (a band of
/// height h all around) sums are a difference of two entries.
class RowRings {
 public:
  RowRings(const Context& c, int row) {
    const WearMap& map = *c.plan.map;
    for (Eigen::Index i = 0; i < map.z.size(); ++i)
      if (c.plan.face_row[static_cast<size_t>(i)] == row) order_.push_back(i);
    std::sort(order_.begin(), order_.end(), [&](Eigen::Index a, Eigen::Index b) { return map.z[a] < map.z[b]; });
    z_.reserve(order_.size());
    prefix_.assign(order_.size() + 1, Sums{});
    for (size_t k = 0; k < order_.size(); ++k) {
      const Eigen::Index i = order_[k];
      z_.push_back(map.z[i]);
      prefix_[k + 1] = prefix_[k];
      prefix_[k + 1].Add(map.areas[i], c.rec.wear_estimate_mm[i], c.errors, i);
    }
  }
  /// Sums over the faces with |z - zc| <= half.
  Sums Between(double zc, double half) const {
    const double tol = 1e-9 * std::max(1.0, half);
    const size_t a = static_cast<size_t>(std::lower_bound(z_.begin(), z_.end(), zc - half - tol) - z_.begin());
    const size_t b = static_cast<size_t>(std::upper_bound(z_.begin(), z_.end(), zc + half + tol) - z_.begin());
    Sums s;
    if (b <= a) return s;
    s.area = prefix_[b].area - prefix_[a].area;
    s.wear = prefix_[b].wear - prefix_[a].wear;
    s.scale = prefix_[b].scale - prefix_[a].scale;
    s.bias = prefix_[b].bias - prefix_[a].bias;
    s.noise = prefix_[b].noise - prefix_[a].noise;
    return s;
  }

 private:
  std::vector<Eigen::Index> order_;
  std::vector<double> z_;
  std::vector<Sums> prefix_;
};

/// The centres of a row's rings of height `height` (a half-height grid; one, at mid-row, when the
/// row is lower than that) and the ring's actual height.
std::vector<double> RingCentres(const Row& r, double height) {
  const double half = 0.5 * height, row_h = r.z_max_m - r.z_min_m;
  std::vector<double> zs;
  if (row_h <= height) return {0.5 * (r.z_min_m + r.z_max_m)};
  for (double z = r.z_min_m + half; z <= r.z_max_m - half + 1e-9; z += half) zs.push_back(z);
  return zs;
}

/// The row's thinnest ring of height `height` (all around the circumference), band [min lo, min hi]
/// over its rings. nullopt when no ring has faces.
std::optional<ThinnestArea> ThinnestRing(const Context& c, const RowRings& rings, const RadiusProfile& radius, int row,
                                         double height) {
  const Row& r = c.plan.crusher->rows[static_cast<size_t>(row)];
  const double h = std::min(height, r.z_max_m - r.z_min_m);
  std::optional<ThinnestArea> best;
  MinBand band;
  for (const double z : RingCentres(r, height)) {
    const Sums s = rings.Between(z, 0.5 * h);
    const double circumference = 2.0 * M_PI * radius.At(z);
    if (!(s.area >= 0.25 * h * circumference)) continue;  // mostly off the map
    ThinnestArea a;
    BandOf(c, s, h, circumference, &a);
    band.Add(a);
    if (!best || a.thickness_mm < best->thickness_mm) {
      a.z_m = z;
      best = a;
    }
  }
  if (best) {
    band.Into(&*best);
    best->patch_m = h;
    best->shape = AreaShape::kRing;
    best->theta_deg = kNan;
  }
  return best;
}

ThinnestArea WholeRow(const Context& c, const RadiusProfile& radius, int row) {
  const WearMap& map = *c.plan.map;
  const Row& r = c.plan.crusher->rows[static_cast<size_t>(row)];
  Sums s;
  for (Eigen::Index i = 0; i < map.z.size(); ++i)
    if (c.plan.face_row[static_cast<size_t>(i)] == row) s.Add(map.areas[i], c.rec.wear_estimate_mm[i], c.errors, i);
  ThinnestArea a;
  a.whole_row = true;
  a.shape = AreaShape::kRow;
  a.patch_m = r.z_max_m - r.z_min_m;
  a.z_m = 0.5 * (r.z_min_m + r.z_max_m);
  a.theta_deg = kNan;
  if (s.area > 0) {
    BandOf(c, s, a.patch_m, 2.0 * M_PI * radius.At(a.z_m), &a);
  } else {
    a.thickness_mm = a.lo_mm = a.hi_mm = kNan;
  }
  return a;
}

/// Whether the area's band supports acting on its number: its half-width before clipping. An
/// estimate 75 mm past worn through with an 86 mm half-width is clipped to the band 0-11 mm, which
/// says nothing about whether the area is 0 or 60 mm thick; and a noisy small patch estimated far
/// past worn through (-96 +/- 95 mm beside its row's 37 +/- 31 mm, in the test) is no finding
/// either, though its whole band lies below 0.
bool Within(const ThinnestArea& a, double target) {
  return std::isfinite(a.thickness_mm) && a.half_width_mm <= target + 1e-9;
}

/// Surface distance from an area's centre to the nearest sensor of `used` (a ring or a whole row: along z
/// from its centre height); infinity when there is none.
double NearestSensor(const CrusherConfig& crusher, const RadiusProfile& radius, const std::vector<Reading>& used,
                     const ThinnestArea& a) {
  std::vector<const SensorInfo*> sensors;
  for (const Reading& r : used)
    if (const SensorInfo* s = crusher.FindSensor(r.sensor_id)) sensors.push_back(s);
  return NearestSensorDistance(sensors, radius, a.z_m, a.theta_deg, a.shape == AreaShape::kSquare);
}

/// The thinnest reading among `used` of `row` (empty: of every row).
std::optional<SensorFallback> ThinnestReading(const CrusherConfig& crusher, const std::vector<Reading>& used,
                                              const std::string& row) {
  std::optional<SensorFallback> out;
  for (const Reading& r : used) {
    const SensorInfo* s = crusher.FindSensor(r.sensor_id);
    if (!s || (!row.empty() && s->row != row)) continue;
    if (!out || r.thickness_mm < out->thickness_mm) out = SensorFallback{r.sensor_id, r.thickness_mm, r.time};
  }
  return out;
}

/// The labels every area gets once chosen: reach, worn through, the sensors' fallback.
void Label(const Context& c, const RadiusProfile& radius, const std::vector<Reading>& used, double target, ThinnestArea* a) {
  const ThinnestAreaConfig& cfg = c.plan.crusher->thinnest_area;
  a->supported = Within(*a, target);
  a->nearest_sensor_m = NearestSensor(*c.plan.crusher, radius, used, *a);
  a->extrapolated = !(a->nearest_sensor_m <= 0.5 * a->patch_m + cfg.sensor_reach_m);
  a->worn_through = a->supported && a->hi_mm <= 0.0;
  for (const RowSummary& r : c.rec.rows)
    if (r.row == a->row) a->row_sensors = r.sensors_used;
  if (!a->supported) a->sensor_fallback = ThinnestReading(*c.plan.crusher, used, a->row);
}

Context MakeContext(const ReconstructionPlan& plan, const Reconstruction& rec) {
  const double face = plan.model.face_size_m;
  const double root4pi = 2.0 * std::sqrt(M_PI);
  return Context{plan,
                 rec,
                 SplitErrors(plan, rec),
                 plan.crusher->thickness_new_mm,
                 plan.options.band_sigmas,
                 std::max(face, root4pi * plan.model.bandwidth_m),
                 std::max(face, root4pi * plan.model.bandwidth_arc_m)};
}

}  // namespace

ThinnestAreas FindThinnestAreas(const ReconstructionPlan& plan, const Reconstruction& rec, const std::vector<Reading>& used) {
  const CrusherConfig& crusher = *plan.crusher;
  const ThinnestAreaConfig& cfg = crusher.thinnest_area;
  const Context c = MakeContext(plan, rec);
  const RadiusProfile& radius = plan.radius;
  const size_t nrows = crusher.rows.size();
  const double target = cfg.band_half_width_mm;
  ThinnestAreas out;
  out.rows.resize(nrows);
  std::vector<bool> done(nrows, false);
  bool liner_done = false;
  const bool scaled = rec.status != kStatusNoSensors;
  std::vector<RowRings> rings;
  if (scaled)
    for (size_t r = 0; r < nrows; ++r) rings.emplace_back(c, static_cast<int>(r));
  // The ladder goes by height, the finest first: at each size a square patch, then the ring of that
  // height all around; then (below) the whole row. Height first, because the thinnest wear of a
  // gyratory concave is a band around it (the discharge edge): a large square there averages the
  // band with the thicker liner above it, a ring of the band's height does not. Each row takes the
  // first step whose band is narrow enough; so does the liner, from the thinnest of the rows' areas
  // at that step (band [min lo, min hi]).
  for (const double patch : cfg.patches_m) {
    for (const AreaShape shape : {AreaShape::kSquare, AreaShape::kRing}) {
      if (!scaled) break;
      std::optional<SurfaceIndex> index;
      if (shape == AreaShape::kSquare) index.emplace(*plan.map, 0.5 * patch, 0.5 * patch);
      std::optional<ThinnestArea> liner;
      for (size_t r = 0; r < nrows; ++r) {
        std::optional<ThinnestArea> a = shape == AreaShape::kSquare
                                            ? ThinnestPatch(c, *index, radius, static_cast<int>(r), patch)
                                            : ThinnestRing(c, rings[r], radius, static_cast<int>(r), patch);
        if (!a) continue;
        a->row = crusher.rows[r].name;
        if (!done[r] && Within(*a, target)) {
          out.rows[r] = *a;
          done[r] = true;
        }
        if (!liner) {
          liner = a;
        } else {
          MinBand band;
          band.Add(*liner);
          band.Add(*a);
          if (a->thickness_mm < liner->thickness_mm) liner = a;
          band.Into(&*liner);
        }
      }
      if (!liner_done && liner && Within(*liner, target)) {
        out.liner = *liner;
        liner_done = true;
      }
    }
  }
  // The whole row, where no patch was narrow enough; and for the liner, the thinnest row.
  std::optional<ThinnestArea> liner_row;
  for (size_t r = 0; r < nrows; ++r) {
    ThinnestArea whole = WholeRow(c, radius, static_cast<int>(r));
    whole.row = crusher.rows[r].name;
    if (!scaled) whole.thickness_mm = whole.lo_mm = whole.hi_mm = kNan;
    if (!done[r]) out.rows[r] = whole;
    if (!std::isfinite(whole.thickness_mm)) continue;
    if (!liner_row) {
      liner_row = whole;
    } else {
      MinBand band;
      band.Add(*liner_row);
      band.Add(whole);
      if (whole.thickness_mm < liner_row->thickness_mm) liner_row = whole;
      band.Into(&*liner_row);
    }
  }
  if (!liner_done) {
    if (liner_row) {
      out.liner = *liner_row;
    } else {
      out.liner.thickness_mm = out.liner.lo_mm = out.liner.hi_mm = out.liner.theta_deg = kNan;
      out.liner.whole_row = true;
      out.liner.shape = AreaShape::kRow;
    }
  }
  for (ThinnestArea& a : out.rows) Label(c, radius, used, target, &a);
  Label(c, radius, used, target, &out.liner);
  if (!out.liner.supported) out.liner.sensor_fallback = ThinnestReading(crusher, used, "");
  return out;
}

SettingEstimate EstimateSetting(const ReconstructionPlan& plan, const Reconstruction& rec, const std::vector<Reading>& used) {
  const CrusherConfig& crusher = *plan.crusher;
  SettingEstimate out;
  out.css_set_mm = crusher.setting.css_mm;
  ThinnestArea& a = out.ring;
  a.shape = AreaShape::kRing;
  a.theta_deg = kNan;
  a.thickness_mm = a.lo_mm = a.hi_mm = kNan;
  out.opening_mm = out.opening_lo_mm = out.opening_hi_mm = kNan;
  int lowest = -1;
  for (size_t r = 0; r < crusher.rows.size(); ++r)
    if (lowest < 0 || crusher.rows[r].z_min_m < crusher.rows[static_cast<size_t>(lowest)].z_min_m) lowest = static_cast<int>(r);
  if (lowest < 0) return out;
  const Row& row = crusher.rows[static_cast<size_t>(lowest)];
  const double h = std::min(crusher.setting.ring_height_m, row.z_max_m - row.z_min_m);
  a.row = row.name;
  a.patch_m = h;
  a.z_m = row.z_min_m + 0.5 * h;
  if (rec.status == kStatusNoSensors) return out;
  const Context c = MakeContext(plan, rec);
  const RadiusProfile& radius = plan.radius;
  const RowRings rings(c, lowest);
  const Sums s = rings.Between(a.z_m, 0.5 * h);
  if (!(s.area > 0)) return out;
  BandOf(c, s, h, 2.0 * M_PI * radius.At(a.z_m), &a);
  Label(c, radius, used, crusher.thinnest_area.band_half_width_mm, &a);
  // The setting opens by the ring's wear: the liner's new thickness less what is left (its band
  // edges swap: the thinnest edge is the widest opening).
  out.opening_mm = c.new_mm - a.thickness_mm;
  out.opening_lo_mm = c.new_mm - a.hi_mm;
  out.opening_hi_mm = c.new_mm - a.lo_mm;
  return out;
}

double AreaMean(const ReconstructionPlan& plan, const Eigen::VectorXd& values, const ThinnestArea& area) {
  const WearMap& map = *plan.map;
  const CrusherConfig& crusher = *plan.crusher;
  int row = -1;
  for (size_t r = 0; r < crusher.rows.size(); ++r)
    if (crusher.rows[r].name == area.row) row = static_cast<int>(r);
  double sum = 0, w = 0;
  if (row < 0 || !std::isfinite(area.z_m)) return kNan;
  if (area.shape != AreaShape::kSquare) {
    // A ring: the row's faces within half its height of its centre (RowRings::Between); a row: all.
    const double half = 0.5 * area.patch_m, tol = 1e-9 * std::max(1.0, half);
    for (Eigen::Index i = 0; i < map.z.size(); ++i)
      if (plan.face_row[static_cast<size_t>(i)] == row &&
          (area.shape == AreaShape::kRow || std::fabs(map.z[i] - area.z_m) <= half + tol))
        sum += map.areas[i] * values[i], w += map.areas[i];
  } else {
    const SurfaceIndex index(map, 0.5 * area.patch_m, 0.5 * area.patch_m);
    const RadiusProfile& radius = plan.radius;
    VisitPatch(plan, index, radius, row, area.z_m, area.theta_deg, area.patch_m,
               [&](Eigen::Index i) { sum += map.areas[i] * values[i], w += map.areas[i]; });
  }
  return w > 0 ? sum / w : kNan;
}

ThinnestArea ThinnestPatchOf(const ReconstructionPlan& plan, const Eigen::VectorXd& remaining, int row, double patch_m,
                             AreaShape shape) {
  const WearMap& map = *plan.map;
  const CrusherConfig& crusher = *plan.crusher;
  const SurfaceIndex index(map, 0.5 * patch_m, 0.5 * patch_m);
  const RadiusProfile& radius = plan.radius;
  ThinnestArea best;
  best.thickness_mm = best.lo_mm = best.hi_mm = kNan;
  best.patch_m = patch_m;
  best.shape = shape;
  best.whole_row = shape == AreaShape::kRow;
  for (size_t r = 0; r < crusher.rows.size(); ++r) {
    if (row >= 0 && static_cast<int>(r) != row) continue;
    if (shape != AreaShape::kSquare) {
      const Row& rw = crusher.rows[r];
      const double h = shape == AreaShape::kRow ? rw.z_max_m - rw.z_min_m : std::min(patch_m, rw.z_max_m - rw.z_min_m);
      const std::vector<double> zs =
          shape == AreaShape::kRow ? std::vector<double>{0.5 * (rw.z_min_m + rw.z_max_m)} : RingCentres(rw, patch_m);
      for (const double z : zs) {
        ThinnestArea a = best;
        a.row = rw.name;
        a.z_m = z;
        a.patch_m = h;
        a.theta_deg = kNan;
        const double t = AreaMean(plan, remaining, a);
        if (std::isfinite(t) && !(t >= best.thickness_mm)) {
          a.thickness_mm = a.lo_mm = a.hi_mm = t;
          best = a;
        }
      }
      continue;
    }
    for (const auto& [z, theta] : PatchCentres(crusher.rows[r], radius, patch_m)) {
      double sum = 0, w = 0;
      if (!VisitPatch(plan, index, radius, static_cast<int>(r), z, theta, patch_m,
                      [&](Eigen::Index i) { sum += map.areas[i] * remaining[i], w += map.areas[i]; }))
        continue;
      const double t = sum / w;
      if (!(t >= best.thickness_mm)) {
        best.thickness_mm = best.lo_mm = best.hi_mm = t;
        best.z_m = z;
        best.theta_deg = theta;
        best.row = crusher.rows[r].name;
      }
    }
  }
  return best;
}

namespace {

nlohmann::ordered_json Rounded(double v, double step) {
  if (!std::isfinite(v)) return nullptr;
  const double inv = std::round(1.0 / step);
  return std::round(v * inv) / inv;
}

/// Where the area's number comes from, in words (empty for a supported area near a sensor).
std::string Detail(const ThinnestArea& a) {
  char b[200];
  std::string d;
  if (!std::isfinite(a.thickness_mm)) return "no wear estimate (no row scale)";
  if (!a.supported) {
    std::snprintf(b, sizeof b, "band wider than the target at every patch up to the whole row");
    d = b;
    // What would narrow it: the larger of the band's two parts.
    // Three or more sensors that still leave the scale this uncertain disagree with the map's
    // pattern among themselves: more of them pins the scale, only a scan shows the pattern.
    if (a.scale_sd_mm >= a.map_sd_mm && a.row_sensors >= 3)
      std::snprintf(b, sizeof b,
                    "; most of it is row %s's scale: its %zu sensors disagree with the DEM map's pattern (a scan of the "
                    "liner would show the pattern; more sensors would pin the scale)",
                    a.row.c_str(), a.row_sensors);
    else if (a.scale_sd_mm >= a.map_sd_mm)
      std::snprintf(b, sizeof b,
                    "; most of it is row %s's scale, set by %zu sensor%s (more sensors in this row, or a scan, would narrow it)",
                    a.row.c_str(), a.row_sensors, a.row_sensors == 1 ? "" : "s");
    else
      std::snprintf(b, sizeof b,
                    "; most of it is the DEM map's own error here (a scan of the liner, or a longer DEM run, would "
                    "narrow it)");
    d += b;
    if (a.sensor_fallback) {
      std::snprintf(b, sizeof b, "; the sensors show %.0f mm (sensor %s, %s)", a.sensor_fallback->thickness_mm,
                    a.sensor_fallback->sensor.c_str(), FormatIsoTime(a.sensor_fallback->time).c_str());
      d += b;
    }
  }
  if (a.extrapolated) {
    if (std::isfinite(a.nearest_sensor_m))
      std::snprintf(b, sizeof b, "extrapolated from the DEM map, nearest sensor %.2f m away", a.nearest_sensor_m);
    else
      std::snprintf(b, sizeof b, "extrapolated from the DEM map, no sensor reports");
    d += (d.empty() ? "" : "; ") + std::string(b);
  }
  if (a.worn_through) d += (d.empty() ? "" : "; ") + std::string("worn through (the whole band is at 0 mm)");
  return d;
}

}  // namespace

nlohmann::ordered_json ThinnestAreaJson(const ThinnestArea& a) {
  nlohmann::ordered_json j;
  j["thickness_mm"] = Rounded(a.thickness_mm, 0.01);
  j["band_mm"] = nlohmann::ordered_json::array({Rounded(a.lo_mm, 0.01), Rounded(a.hi_mm, 0.01)});
  j["patch_m"] = Rounded(a.patch_m, 0.001);
  j["z_m"] = Rounded(a.z_m, 0.001);
  j["theta_deg"] = a.shape != AreaShape::kSquare ? nlohmann::ordered_json(nullptr) : Rounded(a.theta_deg, 0.1);
  j["shape"] = a.shape == AreaShape::kSquare ? "square" : a.shape == AreaShape::kRing ? "ring" : "row";
  j["supported"] = a.supported;
  j["extrapolated"] = a.extrapolated;
  j["nearest_sensor_m"] = Rounded(a.nearest_sensor_m, 0.001);
  j["row"] = a.row;
  j["whole_row"] = a.whole_row;
  j["worn_through"] = a.worn_through;
  j["half_width_mm"] = Rounded(a.half_width_mm, 0.01);
  j["band_parts_mm"] = {{"row_scale_sd", Rounded(a.scale_sd_mm, 0.01)}, {"map_sd", Rounded(a.map_sd_mm, 0.01)}};
  j["detail"] = Detail(a);
  if (a.sensor_fallback) {
    j["sensor_fallback"] = {{"sensor", a.sensor_fallback->sensor},
                            {"thickness_mm", a.sensor_fallback->thickness_mm},
                            {"thickness_interval_mm", {a.sensor_fallback->thickness_mm, a.sensor_fallback->thickness_mm + 1.0}},
                            {"time", FormatIsoTime(a.sensor_fallback->time)}};
  }
  return j;
}

double SettingEstimate::OpeningSince() const {
  return opening_mm - (check ? check->opening_mm : 0.0);
}

void ApplySettingChecks(const std::vector<SettingCheck>& checks, TimePoint at, SettingEstimate* setting) {
  setting->check.reset();
  for (const SettingCheck& c : checks)
    if (c.time <= at && (!setting->check || c.time > setting->check->time)) setting->check = c;
}

namespace {

/// The CSS the setting is counted from: the latest measured one, else crusher.json's.
std::optional<double> CssBase(const SettingEstimate& s) {
  return s.check ? std::optional(s.check->css_mm) : s.css_set_mm;
}

}  // namespace

nlohmann::ordered_json SettingJson(const SettingEstimate& s) {
  const ThinnestArea& a = s.ring;
  nlohmann::ordered_json j;
  // The CSS is its base plus the opening since; the band is today's band shifted by the opening at
  // the check, which the measured CSS then anchors.
  const std::optional<double> base = CssBase(s);
  const double at_base = s.check ? s.check->opening_mm : 0.0;
  const auto css = [&](double opening) {
    return base ? Rounded(*base + opening - at_base, 0.01) : nlohmann::ordered_json(nullptr);
  };
  j["opening_mm"] = Rounded(s.opening_mm, 0.01);
  j["opening_band_mm"] = nlohmann::ordered_json::array({Rounded(s.opening_lo_mm, 0.01), Rounded(s.opening_hi_mm, 0.01)});
  j["css_set_mm"] = s.css_set_mm ? nlohmann::ordered_json(*s.css_set_mm) : nlohmann::ordered_json(nullptr);
  j["css_mm"] = css(s.opening_mm);
  j["css_band_mm"] =
      base ? nlohmann::ordered_json::array({css(s.opening_lo_mm), css(s.opening_hi_mm)}) : nlohmann::ordered_json(nullptr);
  j["opening_since_mm"] = Rounded(s.OpeningSince(), 0.01);
  j["checked"] = s.check ? nlohmann::ordered_json{{"time", FormatIsoTime(s.check->time)},
                                                  {"css_mm", s.check->css_mm},
                                                  {"opening_mm", Rounded(s.check->opening_mm, 0.01)},
                                                  {"opening_supported", s.check->opening_supported},
                                                  {"by", s.check->by}}
                         : nlohmann::ordered_json(nullptr);
  j["supported"] = a.supported;
  j["half_width_mm"] = Rounded(a.half_width_mm, 0.01);
  j["ring"] = {{"row", a.row},
               {"z_m", Rounded(a.z_m, 0.001)},
               {"height_m", Rounded(a.patch_m, 0.001)},
               {"thickness_mm", Rounded(a.thickness_mm, 0.01)},
               {"nearest_sensor_m", Rounded(a.nearest_sensor_m, 0.001)},
               {"extrapolated", a.extrapolated}};
  char basis[200];
  std::snprintf(basis, sizeof basis,
                "the concave's wear at its discharge ring (row %s, the lowest %.2f m all around), normal to the liner; the "
                "mantle's wear is not measured",
                a.row.c_str(), a.patch_m);
  j["basis"] = basis;
  j["detail"] = SettingText(s);
  return j;
}

std::string SettingText(const SettingEstimate& s) {
  const ThinnestArea& a = s.ring;
  if (!std::isfinite(s.opening_mm)) return "setting: no estimate (no sensor sets a scale)";
  char b[320];
  if (!a.supported) {
    // An unsupported ring gives no number to act on: its band is clipped at the liner's bounds
    // (a band of "120..120" on a real map whose half-width is 137 mm), so no CSS is named.
    std::snprintf(b, sizeof b,
                  "setting: not supported: the discharge ring's band half-width %.1f mm is wider than the thinnest-area "
                  "target, so the opening by the concave's wear is not known better than 0..%.0f mm",
                  a.half_width_mm, s.opening_mm + a.thickness_mm);
    return std::string(b) + (a.extrapolated ? "; from the DEM map alone" : "") + "; the mantle's wear is not included";
  }
  if (s.check && !std::isfinite(s.check->opening_mm))
    std::snprintf(b, sizeof b,
                  "setting: measured %.0f mm on %s; the opening since is not known (no reading of this liner up to "
                  "then), opened %.1f mm (band %.1f..%.1f) since installation",
                  s.check->css_mm, FormatIsoTime(s.check->time).substr(0, 10).c_str(), s.opening_mm, s.opening_lo_mm,
                  s.opening_hi_mm);
  else if (s.check)
    std::snprintf(b, sizeof b,
                  "setting: opened %.1f mm (band %.1f..%.1f) by the concave's wear at the discharge ring since it was "
                  "measured %.0f mm on %s: CSS about %.0f mm",
                  s.OpeningSince(), s.opening_lo_mm - s.check->opening_mm, s.opening_hi_mm - s.check->opening_mm, s.check->css_mm,
                  FormatIsoTime(s.check->time).substr(0, 10).c_str(), s.check->css_mm + s.OpeningSince());
  else if (s.css_set_mm)
    std::snprintf(
        b, sizeof b,
        "setting: opened %.1f mm (band %.1f..%.1f) by the concave's wear at the discharge ring: CSS about %.0f mm (set %.0f)",
        s.opening_mm, s.opening_lo_mm, s.opening_hi_mm, *s.css_set_mm + s.opening_mm, *s.css_set_mm);
  else
    std::snprintf(b, sizeof b, "setting: opened %.1f mm (band %.1f..%.1f) by the concave's wear at the discharge ring",
                  s.opening_mm, s.opening_lo_mm, s.opening_hi_mm);
  std::string out = b;
  if (s.check && std::isfinite(s.check->opening_mm) && !s.check->opening_supported)
    out += "; the opening at the measurement is the central estimate of a ring not supported then";
  if (a.extrapolated) out += "; from the DEM map alone (no sensor within reach of the ring)";
  return out + "; the mantle's wear is not included";
}

nlohmann::ordered_json MapCalibrationJson(const MapCalibration& calibration) {
  return {{"factor", Rounded(calibration.factor, 0.001)},
          {"sensors", calibration.sensors},
          {"point_rel_sd", Rounded(calibration.point_rel_sd, 0.0001)}};
}

std::string ThinnestAreaText(const ThinnestArea& a) {
  if (!std::isfinite(a.thickness_mm)) return "thinnest area: " + Detail(a);
  char b[240];
  if (a.shape == AreaShape::kRow)
    std::snprintf(b, sizeof b, "thinnest area (row %s as a whole): %.1f mm, band %.1f..%.1f mm", a.row.c_str(), a.thickness_mm,
                  a.lo_mm, a.hi_mm);
  else if (a.shape == AreaShape::kRing)
    std::snprintf(b, sizeof b, "thinnest area (a %.2f m band all around, row %s, z %.2f m): %.1f mm, band %.1f..%.1f mm",
                  a.patch_m, a.row.c_str(), a.z_m, a.thickness_mm, a.lo_mm, a.hi_mm);
  else
    std::snprintf(b, sizeof b, "thinnest area (%.2f m patch, row %s, z %.2f m, theta %.0f deg): %.1f mm, band %.1f..%.1f mm",
                  a.patch_m, a.row.c_str(), a.z_m, a.theta_deg, a.thickness_mm, a.lo_mm, a.hi_mm);
  const std::string d = Detail(a);
  return std::string(b) + (d.empty() ? "" : "; " + d);
}

}  // namespace lw::core
