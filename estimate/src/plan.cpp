#include "estimate/plan.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <tuple>

#include "core/angles.hpp"
#include "core/thinnest_area.hpp"
#include "core/time.hpp"
#include "estimate/estimate.hpp"

namespace lw::estimate {
namespace {
using core::AngleDiffDeg;

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
constexpr double kDegToRad = M_PI / 180.0;

/// Whether a sensor may sit at (row, z, theta): inside the row by the margin, clear of every joint.
bool Allowed(const core::CrusherConfig& c, const core::Row& row, double z, double theta, const PlanOptions& o) {
  if (z < row.z_min_m + o.edge_margin_m - 1e-9 || z > row.z_max_m - o.edge_margin_m + 1e-9) return false;
  for (const double j : c.joints_theta_deg)
    if (std::abs(AngleDiffDeg(theta, j)) < o.joint_clearance_deg) return false;
  return true;
}

/// The expected band of layouts (sets of entries of `config.sensors`: the candidates, then the
/// crusher.json sensors) through the live wear's own functions. Holds the plan the layouts are
/// reconstructed on; `plan` points into `config`, so an Evaluator stays where it was made.
class Evaluator {
 public:
  Evaluator(const CrusherModel& model, const PlanOptions& o) : model_(model) {
    const core::CrusherConfig& c = model.config;
    config_ = c;
    config_.sensors.clear();
    for (const core::Row& row : c.rows) {
      if (!(row.z_max_m - row.z_min_m > 2 * o.edge_margin_m))
        throw std::invalid_argument("--edge-margin-m: row '" + row.name + "' is " + Fmt(row.z_max_m - row.z_min_m, 2) +
                                    " m high, no room inside a margin of " + Fmt(o.edge_margin_m, 2) + " m");
      const int nz = std::max(1, o.z_levels);
      for (int k = 0; k < nz; ++k) {
        const double lo = row.z_min_m + o.edge_margin_m, hi = row.z_max_m - o.edge_margin_m;
        const double z = nz == 1 ? 0.5 * (lo + hi) : lo + (hi - lo) * k / (nz - 1);
        for (double t = 0; t < 360.0 - 1e-9; t += o.theta_step_deg)
          if (Allowed(c, row, z, t, o)) Add(row.name, z, t, "");
      }
    }
    candidates_ = config_.sensors.size();
    for (const core::SensorInfo& s : c.sensors) {
      Add(s.row, s.z_m, s.theta_deg, s.id);
      const core::Row& row = c.rows[static_cast<size_t>(c.RowIndex(s.row))];
      current_valid_.push_back(Allowed(c, row, s.z_m, s.theta_deg, o));
    }
    core::ReconstructionOptions ro = model.plan.options;
    ro.calibration_prior_dof = 0;  // planned sensors have no readings: the map model's error as it is
    plan_ = core::PrepareReconstruction(config_, model.map, model.plan.model, ro);
    const double face = plan_.model.face_size_m, root4pi = 2.0 * std::sqrt(M_PI);
    ell_z_ = std::max(face, root4pi * plan_.model.bandwidth_m);
    ell_arc_ = std::max(face, root4pi * plan_.model.bandwidth_arc_m);
  }
  Evaluator(const Evaluator&) = delete;
  Evaluator& operator=(const Evaluator&) = delete;

  static std::string Fmt(double v, int digits) {
    char b[32];
    std::snprintf(b, sizeof b, "%.*f", digits, v);
    return b;
  }
  size_t candidates() const { return candidates_; }
  size_t entries() const { return config_.sensors.size(); }
  const core::SensorInfo& entry(size_t i) const { return config_.sensors[i]; }
  bool current_valid(size_t k) const { return current_valid_[k]; }
  int row_of(size_t i) const { return config_.RowIndex(config_.sensors[i].row); }

  /// Two sensors within the map error's correlation length along z and around read the same error:
  /// the model's independent errors would overstate what the second adds.
  bool TooClose(size_t a, size_t b) const {
    const core::SensorInfo &x = config_.sensors[a], &y = config_.sensors[b];
    const double arc = AngleDiffDeg(x.theta_deg, y.theta_deg) * kDegToRad * RadiusAt(0.5 * (x.z_m + y.z_m));
    return std::abs(x.z_m - y.z_m) < ell_z_ && std::abs(arc) < ell_arc_;
  }

  /// The reline point and the area layouts are compared on, from the reference layout: the wear
  /// scale at which the liner's thinnest area (the crusher's own ladder) reaches the minimum, and
  /// that area's size. With `patch_m` > 0 the area is the thinnest square of that side instead,
  /// for the reline point as for the comparison.
  void Calibrate(const std::vector<size_t>& reference, double patch_m = 0) {
    const core::CrusherConfig& c = model_.config;
    config_.thinnest_area = c.thinnest_area;
    if (patch_m > 0) {  // a target every square meets: the liner's area is the first square
      config_.thinnest_area.patches_m = {patch_m};
      config_.thinnest_area.band_half_width_mm = std::numeric_limits<double>::max();
    }
    const double target_wear = c.thickness_new_mm - c.thickness_min_mm;
    scale_ = plan_.intensity.size() && plan_.intensity.maxCoeff() > 0 ? target_wear / plan_.intensity.maxCoeff() : 1.0;
    core::ThinnestAreas areas;
    for (int it = 0; it < 6; ++it) {
      areas = Areas(reference);
      const double wear = c.thickness_new_mm - areas.liner.thickness_mm;
      if (!(wear > 0) || !std::isfinite(wear)) break;
      scale_ *= target_wear / wear;
    }
    areas = Areas(reference);
    row_wear_.clear();
    for (const core::RowSummary& r : core::Reconstruct(plan_, Wear(reference)).rows) row_wear_.push_back(r.mean_wear_mm);
    if (patch_m > 0) {
      patch_ = patch_m;
      return;
    }
    on_row_ = areas.liner.shape == core::AreaShape::kRow || !std::isfinite(areas.liner.thickness_mm);
    patch_ = on_row_ ? 0.0 : areas.liner.patch_m;
    config_.thinnest_area.patches_m = {on_row_ ? c.thinnest_area.patches_m.back() : patch_};
    // A target no square can meet gives whole rows; one every square meets gives the first square.
    config_.thinnest_area.band_half_width_mm = on_row_ ? 1e-12 : std::numeric_limits<double>::max();
  }
  bool on_row() const { return on_row_; }
  /// Each row's predicted mean wear at the reline point (by row index): the rows' wear rates, in
  /// one measure for every row (their thinnest areas differ in shape and size from row to row).
  const std::vector<double>& row_wear() const { return row_wear_; }
  double patch() const { return patch_; }

  /// Band half-widths (band_sigmas sd) of the liner's thinnest area and each row's, on the compared area.
  struct Bands {
    double liner = kNan;
    std::vector<double> rows;
    double Objective() const {
      double sum = liner;
      for (const double r : rows) sum += r;
      return sum / static_cast<double>(rows.size() + 1);
    }
  };
  Bands Evaluate(const std::vector<size_t>& layout) const {
    Bands b;
    b.rows.assign(config_.rows.size(), kNan);
    const core::ThinnestAreas areas = Areas(layout);
    if (!std::isfinite(areas.liner.thickness_mm)) return b;
    auto half = [&](const core::ThinnestArea& a) { return plan_.options.band_sigmas * std::hypot(a.scale_sd_mm, a.map_sd_mm); };
    b.liner = half(areas.liner);
    for (size_t r = 0; r < areas.rows.size(); ++r) b.rows[r] = half(areas.rows[r]);
    return b;
  }
  /// The liner's thinnest area with `layout`, as the live wear reports it on the compared area.
  core::ThinnestArea Liner(const std::vector<size_t>& layout) const { return Areas(layout).liner; }
  double band_sigmas() const { return plan_.options.band_sigmas; }
  double Objective(const std::vector<size_t>& layout) const {
    const double j = Evaluate(layout).Objective();
    return std::isfinite(j) ? j : std::numeric_limits<double>::max();
  }
  /// The row scale's standard error of `row` with `layout`: what a sensor added to that row changes.
  double RowScaleSd(const std::vector<size_t>& layout, int row) const {
    const core::Reconstruction rec = core::Reconstruct(plan_, Wear(layout));
    return rec.status == core::kStatusNoSensors ? std::numeric_limits<double>::max()
                                                : rec.rows[static_cast<size_t>(row)].scale_sd;
  }

 private:
  void Add(const std::string& row, double z, double theta, const std::string& id) {
    core::SensorInfo s;
    s.id = id.empty() ? "candidate-" + std::to_string(config_.sensors.size()) : id;
    s.row = row;
    s.z_m = z;
    s.theta_deg = theta;
    s.thickness_new_mm = model_.config.thickness_new_mm;
    config_.sensors.push_back(s);
  }
  double RadiusAt(double z) const {
    double best = std::numeric_limits<double>::max(), r = 1.0;
    const core::WearMap& m = model_.map;
    for (Eigen::Index i = 0; i < m.z.size(); ++i)
      if (std::abs(m.z[i] - z) < best) best = std::abs(m.z[i] - z), r = m.radius[i];
    return r;
  }
  /// Each sensor reads what the map predicts at the reline point: the scale times the map at it.
  std::vector<core::SensorWear> Wear(const std::vector<size_t>& layout) const {
    std::vector<core::SensorWear> w;
    for (const size_t i : layout)
      w.push_back({config_.sensors[i].id, scale_ * plan_.sensor_intensity[static_cast<Eigen::Index>(i)]});
    return w;
  }
  core::ThinnestAreas Areas(const std::vector<size_t>& layout) const {
    const std::vector<core::SensorWear> wear = Wear(layout);
    const core::Reconstruction rec = core::Reconstruct(plan_, wear);
    std::vector<core::Reading> used;
    for (const core::SensorWear& w : wear)
      used.push_back({model_.config.installed_at, w.sensor_id, model_.config.thickness_new_mm - w.wear_mm, 0});
    return core::FindThinnestAreas(plan_, rec, used);
  }

  const CrusherModel& model_;
  core::CrusherConfig config_;
  core::ReconstructionPlan plan_;
  size_t candidates_ = 0;
  std::vector<bool> current_valid_;
  double ell_z_ = 0, ell_arc_ = 0, scale_ = 1, patch_ = 0;
  std::vector<double> row_wear_;
  bool on_row_ = false;
};

/// The best candidate to add to `layout`: per row the candidate that narrows its row scale most
/// (the estimate is the same for every layout, so a row's band only narrows with its scale's error),
/// then of those the one that lowers the objective most. Candidates too close to a chosen sensor
/// are skipped while any other is left; with `rows` (indexed by row), only rows marked true. SIZE_MAX
/// when none is left.
size_t BestAddition(const Evaluator& ev, const std::vector<size_t>& layout, double* objective,
                    const std::vector<bool>& rows = {}) {
  std::vector<std::pair<double, size_t>> best_in_row;  // indexed by row
  for (const bool spaced : {true, false}) {
    best_in_row.clear();
    for (size_t c = 0; c < ev.candidates(); ++c) {
      if (std::find(layout.begin(), layout.end(), c) != layout.end()) continue;
      if (spaced && std::any_of(layout.begin(), layout.end(), [&](size_t s) { return ev.TooClose(c, s); })) continue;
      const size_t r = static_cast<size_t>(ev.row_of(c));
      if (!rows.empty() && (r >= rows.size() || !rows[r])) continue;
      if (best_in_row.size() <= r) best_in_row.resize(r + 1, {std::numeric_limits<double>::max(), SIZE_MAX});
      std::vector<size_t> with = layout;
      with.push_back(c);
      const double sd = ev.RowScaleSd(with, static_cast<int>(r));
      if (sd < best_in_row[r].first) best_in_row[r] = {sd, c};
    }
    if (std::any_of(best_in_row.begin(), best_in_row.end(), [](const auto& b) { return b.second != SIZE_MAX; })) break;
  }
  size_t best = SIZE_MAX;
  double best_j = std::numeric_limits<double>::max();
  for (const auto& [sd, c] : best_in_row) {
    if (c == SIZE_MAX) continue;
    std::vector<size_t> with = layout;
    with.push_back(c);
    const double j = ev.Objective(with);
    if (best == SIZE_MAX || j < best_j) best = c, best_j = j;
  }
  if (objective) *objective = best_j;
  return best;
}

/// The fewest sensors the search leaves in each row (by row index): one in every row where K allows,
/// and a second in as many rows as the sensors left over cover, the fastest-wearing rows (the most
/// predicted mean wear at the reline point, `row_wear`) first, so the slowest rows give theirs up. One sensor's row
/// scale carries only the map's sampling error at that sensor: nothing checks the map's pattern
/// along the row, so its band is overconfident, and a search that minimises that band seeks such
/// rows out (bench/diagnosis/RESULTS.md, *Why the plan's bands miss in 5 of 60 cases*); where the
/// thinnest area is expected that is the miss a planner acts on.
std::vector<size_t> MinPerRow(size_t k, const std::vector<double>& row_wear) {
  const size_t rows = row_wear.size();
  std::vector<size_t> out(rows, k >= rows ? 1 : 0);
  if (k <= rows) return out;
  std::vector<size_t> order(rows);
  for (size_t r = 0; r < rows; ++r) order[r] = r;
  const auto wear = [&](size_t r) { return std::isfinite(row_wear[r]) ? row_wear[r] : -std::numeric_limits<double>::max(); };
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return wear(a) > wear(b); });
  for (size_t i = 0; i < std::min(rows, k - rows); ++i) out[order[i]] = 2;
  return out;
}

/// Sensors of `layout` per row.
std::vector<size_t> PerRow(const Evaluator& ev, const std::vector<size_t>& layout, size_t rows) {
  std::vector<size_t> n(rows, 0);
  for (const size_t i : layout)
    if (const int r = ev.row_of(i); r >= 0 && static_cast<size_t>(r) < rows) ++n[static_cast<size_t>(r)];
  return n;
}

/// Greedy fill of `layout` to k sensors (removing the least useful first when it holds more), then
/// exchanges: each sensor in turn taken out and the best addition put in, kept when the objective
/// falls, until a pass changes nothing. The fill serves rows below MinPerRow first; no removal takes
/// a row below it (a row moved out of it stays where it was).
std::vector<size_t> Search(const Evaluator& ev, std::vector<size_t> layout, size_t k, size_t rows) {
  std::vector<double> wear = ev.row_wear();
  wear.resize(rows, std::numeric_limits<double>::quiet_NaN());
  const std::vector<size_t> min_per_row = MinPerRow(k, wear);
  const auto keeps_row = [&](const std::vector<size_t>& l, size_t i) {
    const int r = ev.row_of(l[i]);
    return r < 0 || static_cast<size_t>(r) >= rows ||
           PerRow(ev, l, rows)[static_cast<size_t>(r)] > min_per_row[static_cast<size_t>(r)];
  };
  // A start that leaves a row below its minimum (crusher.json's layout) gives sensors up from the
  // rows above theirs until the fill can serve it.
  const auto deficit = [&](const std::vector<size_t>& l) {
    const std::vector<size_t> n = PerRow(ev, l, rows);
    size_t d = 0;
    for (size_t r = 0; r < rows; ++r) d += n[r] < min_per_row[r] ? min_per_row[r] - n[r] : 0;
    return d;
  };
  const auto any_spare = [&](const std::vector<size_t>& l) {
    for (size_t i = 0; i < l.size(); ++i)
      if (keeps_row(l, i)) return true;
    return false;
  };
  while (layout.size() > k || (!layout.empty() && layout.size() + deficit(layout) > k && any_spare(layout))) {
    size_t drop = 0;
    double best = std::numeric_limits<double>::max();
    bool any = false;
    for (const bool strict : {true, false}) {
      for (size_t i = 0; i < layout.size(); ++i) {
        if (strict && !keeps_row(layout, i)) continue;
        std::vector<size_t> without = layout;
        without.erase(without.begin() + static_cast<std::ptrdiff_t>(i));
        const double j = ev.Objective(without);
        if (j < best) best = j, drop = i, any = true;
      }
      if (any) break;
    }
    layout.erase(layout.begin() + static_cast<std::ptrdiff_t>(drop));
  }
  while (layout.size() < k) {
    const std::vector<size_t> n = PerRow(ev, layout, rows);
    std::vector<bool> short_rows(rows);
    for (size_t r = 0; r < rows; ++r) short_rows[r] = n[r] < min_per_row[r];
    size_t c = std::any_of(short_rows.begin(), short_rows.end(), [](bool b) { return b; })
                   ? BestAddition(ev, layout, nullptr, short_rows)
                   : SIZE_MAX;
    if (c == SIZE_MAX) c = BestAddition(ev, layout, nullptr);
    if (c == SIZE_MAX) break;
    layout.push_back(c);
  }
  double j = ev.Objective(layout);
  for (int pass = 0; pass < 4; ++pass) {
    bool changed = false;
    for (size_t i = 0; i < layout.size(); ++i) {
      // Taking out a row's last sensors above the minimum: the addition goes back into that row.
      std::vector<bool> only;
      if (!keeps_row(layout, i)) {
        only.assign(rows, false);
        only[static_cast<size_t>(ev.row_of(layout[i]))] = true;
      }
      std::vector<size_t> without = layout;
      without.erase(without.begin() + static_cast<std::ptrdiff_t>(i));
      double jj = 0;
      const size_t c = BestAddition(ev, without, &jj, only);
      if (c == SIZE_MAX || !(jj < j - 1e-9)) continue;
      without.push_back(c);
      layout = without;
      j = jj;
      changed = true;
    }
    if (!changed) break;
  }
  return layout;
}

}  // namespace

SensorPlan PlanSensors(const CrusherModel& model, const PlanOptions& options) {
  if (!(options.edge_margin_m >= 0)) throw std::invalid_argument("--edge-margin-m must be 0 or more");
  if (!(options.joint_clearance_deg >= 0 && options.joint_clearance_deg < 180))
    throw std::invalid_argument("--joint-clearance-deg must be in [0, 180)");
  if (!(options.theta_step_deg > 0 && options.theta_step_deg <= 180))
    throw std::invalid_argument("theta step must be in (0, 180]");
  Evaluator ev(model, options);
  if (options.sensors < 1 || options.sensors > ev.candidates())
    throw std::invalid_argument("--sensors " + std::to_string(options.sensors) + " is out of range: 1 to " +
                                std::to_string(ev.candidates()) +
                                " (the candidate positions inside the rows' margins, clear of joints)");
  const size_t nc = ev.candidates(), ncur = model.config.sensors.size();
  std::vector<size_t> current, current_valid;
  for (size_t k = 0; k < ncur; ++k) {
    current.push_back(nc + k);
    if (ev.current_valid(k)) current_valid.push_back(nc + k);
  }
  std::vector<size_t> all(nc);
  for (size_t c = 0; c < nc; ++c) all[c] = c;
  ev.Calibrate(current.empty() ? all : current);
  // Two starts: empty, and the crusher.json layout (its positions inside the margins and clear of
  // joints); the better result is the proposal. From the crusher.json layout with the same K, the
  // exchanges only accept a lower objective: the proposal is never worse than the current layout.
  const size_t rows = model.config.rows.size();
  std::vector<size_t> best = Search(ev, {}, options.sensors, rows);
  if (!current_valid.empty()) {
    const std::vector<size_t> from_current = Search(ev, current_valid, options.sensors, rows);
    if (ev.Objective(from_current) < ev.Objective(best)) best = from_current;
  }
  SensorPlan out;
  out.crusher_id = model.config.crusher_id;
  out.candidates = nc;
  out.compared_on_row = ev.on_row();
  out.compared_patch_m = ev.patch();
  std::sort(best.begin(), best.end(), [&](size_t a, size_t b) {
    const core::SensorInfo &x = ev.entry(a), &y = ev.entry(b);
    return std::tie(x.z_m, x.theta_deg) < std::tie(y.z_m, y.theta_deg);
  });
  for (const size_t i : best) {
    const core::SensorInfo& s = ev.entry(i);
    out.sensors.push_back({s.row, s.z_m, s.theta_deg, i >= nc ? s.id : ""});
  }
  const Evaluator::Bands now = current.empty() ? Evaluator::Bands{} : ev.Evaluate(current);
  const Evaluator::Bands proposed = ev.Evaluate(best);
  out.current_mm = current.empty() ? kNan : now.Objective();
  out.proposed_mm = proposed.Objective();
  out.liner_current_mm = now.liner;
  out.liner_proposed_mm = proposed.liner;
  for (size_t r = 0; r < model.config.rows.size(); ++r) {
    RowPlan rp;
    rp.row = model.config.rows[r].name;
    for (const size_t i : current) rp.current_sensors += ev.row_of(i) == static_cast<int>(r);
    for (const size_t i : best) rp.proposed_sensors += ev.row_of(i) == static_cast<int>(r);
    rp.current_mm = now.rows.empty() ? kNan : now.rows[r];
    rp.proposed_mm = proposed.rows[r];
    out.rows.push_back(rp);
  }
  return out;
}

void CheckMapBandPatch(const core::CrusherConfig& crusher, double patch_m) {
  double tallest = 0;
  for (const core::Row& r : crusher.rows) tallest = std::max(tallest, r.z_max_m - r.z_min_m);
  if (!(patch_m > 0 && patch_m <= tallest + 1e-9))
    throw std::invalid_argument("--patch " + Evaluator::Fmt(patch_m, 3) + " is out of range: (0, " + Evaluator::Fmt(tallest, 3) +
                                "] m (the tallest row's height; a larger area is the whole row)");
}

MapBand MapBandAt(const CrusherModel& model, double patch_m) {
  CheckMapBandPatch(model.config, patch_m);
  // The candidates only stand in for crusher.json's sensors when it has none: with readings that
  // follow the map every layout gives the same estimate, and the map's part of the band does not
  // depend on the layout.
  PlanOptions o;
  o.edge_margin_m = 0;
  o.z_levels = 1;
  o.theta_step_deg = 90;
  Evaluator ev(model, o);
  std::vector<size_t> layout;
  for (size_t k = 0; k < model.config.sensors.size(); ++k) layout.push_back(ev.candidates() + k);
  if (layout.empty())
    for (size_t c = 0; c < ev.candidates(); ++c) layout.push_back(c);
  ev.Calibrate(layout, patch_m);
  const core::ThinnestArea a = ev.Liner(layout);
  MapBand b;
  b.patch_m = patch_m;
  if (!std::isfinite(a.thickness_mm) || a.shape != core::AreaShape::kSquare)
    throw std::invalid_argument("--patch " + Evaluator::Fmt(patch_m, 3) +
                                ": no square of that side holds enough of the map's faces");
  b.map_sd_mm = a.map_sd_mm;
  b.scale_sd_mm = a.scale_sd_mm;
  b.half_width_mm = ev.band_sigmas() * std::hypot(a.scale_sd_mm, a.map_sd_mm);
  b.band_sigmas = ev.band_sigmas();
  b.thickness_mm = a.thickness_mm;
  b.row = a.row;
  b.z_m = a.z_m;
  b.theta_deg = a.theta_deg;
  return b;
}

namespace {

/// The band half-width the live wear judges an area by (before the band is clipped to [0, new]).
double ReportedHalf(const core::ThinnestArea& a) {
  return std::isfinite(a.thickness_mm) ? a.half_width_mm : kNan;
}

double DateBandDays(const core::RowForecast& f) {
  if (!f.reach_earliest || !f.reach_latest) return kNan;
  return core::DaysBetween(*f.reach_earliest, *f.reach_latest);
}

}  // namespace

std::optional<ScanAdvice> AdviseScan(const CrusherModel& model, const std::vector<Sample>& readings) {
  const WearEstimate now = Estimate(model, readings);
  if (!now.has_wear || now.reconstruction.status == core::kStatusNoSensors) return std::nullopt;
  // The same crusher with one more scan, dated at the latest reading, that reads the wear the live
  // map shows now at every face of a row (a dense scan: the scan's own error is its 0.5 mm floor,
  // core::ProjectScanToFaces). The live wear then takes its pattern as core::ApplyScan weighs it.
  auto scanned = std::make_unique<CrusherModel>();
  scanned->config = model.config;
  scanned->map = model.map;
  scanned->plan = core::PrepareReconstruction(scanned->config, scanned->map, model.plan.model, model.plan.options);
  scanned->scans = model.scans;
  ModelScan s;
  s.scan.file = "planned scan";
  s.scan.date = now.time;
  const Eigen::Index n = static_cast<Eigen::Index>(model.map.face_count());
  s.faces.wear_mm = Eigen::VectorXd::Constant(n, kNan);
  s.faces.sd_mm = Eigen::VectorXd::Constant(n, 0.5);
  s.faces.points.assign(static_cast<size_t>(n), 0);
  for (Eigen::Index i = 0; i < n; ++i) {
    if (model.plan.face_row[static_cast<size_t>(i)] < 0 || !std::isfinite(now.reconstruction.wear_mm[i])) continue;
    s.faces.wear_mm[i] = now.reconstruction.wear_mm[i];
    s.faces.points[static_cast<size_t>(i)] = 1;
    ++s.faces.points_used;
  }
  s.faces.points_total = s.faces.points_used;
  scanned->scans.push_back(std::move(s));
  scanned->SortScans();
  const WearEstimate with = Estimate(*scanned, readings);
  ScanAdvice a;
  a.at = core::FormatIsoTime(now.time);
  a.liner_now_mm = ReportedHalf(now.areas.liner);
  a.liner_scan_mm = ReportedHalf(with.areas.liner);
  std::optional<core::TimePoint> first;
  for (size_t r = 0; r < model.config.rows.size(); ++r) {
    ScanAdvice::Row row;
    row.row = model.config.rows[r].name;
    row.now_mm = ReportedHalf(now.areas.rows[r]);
    row.scan_mm = ReportedHalf(with.areas.rows[r]);
    row.now_days = r < now.row_forecasts.size() ? DateBandDays(now.row_forecasts[r]) : kNan;
    row.scan_days = r < with.row_forecasts.size() ? DateBandDays(with.row_forecasts[r]) : kNan;
    if (r < now.row_forecasts.size() && now.row_forecasts[r].reach && (!first || *now.row_forecasts[r].reach < *first)) {
      first = now.row_forecasts[r].reach;
      a.first_row = row.row;
    }
    a.rows.push_back(row);
  }
  return a;
}

namespace {

nlohmann::ordered_json Num(double v, double step = 0.01) {
  if (!std::isfinite(v)) return nullptr;
  return std::round(v / step) * step;
}

const char* kObjective =
    "mean band half-width (2 sd) of the liner's thinnest area and of each row's at the reline point, as the live wear "
    "computes it (row scale from the sensors, the DEM map model's error from its independent windows) if every sensor "
    "read what the map predicts there; compared on one area size for every layout";

nlohmann::ordered_json ScanJson(const ScanAdvice& s) {
  nlohmann::ordered_json j;
  j["at"] = s.at;
  j["liner_band_mm"] = {{"now", Num(s.liner_now_mm)}, {"with_scan", Num(s.liner_scan_mm)}};
  j["first_row"] = s.first_row.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(s.first_row);
  j["rows"] = nlohmann::ordered_json::array();
  for (const ScanAdvice::Row& r : s.rows)
    j["rows"].push_back({{"row", r.row},
                         {"band_mm", {{"now", Num(r.now_mm)}, {"with_scan", Num(r.scan_mm)}}},
                         {"reline_band_days", {{"now", Num(r.now_days, 0.1)}, {"with_scan", Num(r.scan_days, 0.1)}}}});
  return j;
}

}  // namespace

nlohmann::ordered_json PlanJson(const SensorPlan& p) {
  nlohmann::ordered_json j;
  j["sensors"] = nlohmann::ordered_json::array();
  for (const PlannedSensor& s : p.sensors)
    j["sensors"].push_back({{"row", s.row},
                            {"z_m", Num(s.z_m, 0.001)},
                            {"theta_deg", Num(s.theta_deg, 0.1)},
                            {"keeps", s.keeps.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(s.keeps)}});
  j["expected_band_mm"] = {{"current", Num(p.current_mm)}, {"proposed", Num(p.proposed_mm)}};
  j["liner_band_mm"] = {{"current", Num(p.liner_current_mm)}, {"proposed", Num(p.liner_proposed_mm)}};
  j["rows"] = nlohmann::ordered_json::array();
  for (const RowPlan& r : p.rows)
    j["rows"].push_back({{"row", r.row},
                         {"sensors", {{"current", r.current_sensors}, {"proposed", r.proposed_sensors}}},
                         {"band_mm", {{"current", Num(r.current_mm)}, {"proposed", Num(r.proposed_mm)}}}});
  j["compared_on"] = {{"shape", p.compared_on_row ? "row" : "square"},
                      {"patch_m", p.compared_on_row ? nlohmann::ordered_json(nullptr) : Num(p.compared_patch_m, 0.001)}};
  j["candidates"] = p.candidates;
  j["objective"] = kObjective;
  j["scan_now"] = p.scan ? ScanJson(*p.scan) : nlohmann::ordered_json(nullptr);
  return j;
}

std::string PlanText(const SensorPlan& p) {
  std::string out;
  char line[400];
  const std::string area =
      p.compared_on_row ? std::string("whole rows") : "the thinnest " + Evaluator::Fmt(p.compared_patch_m, 2) + " m square";
  std::snprintf(line, sizeof line, "Sensor plan for %s: %zu sensors for the next liner (from %zu candidate positions).\n",
                p.crusher_id.c_str(), p.sensors.size(), p.candidates);
  out += line;
  for (const PlannedSensor& s : p.sensors) {
    std::snprintf(line, sizeof line, "  row %-8s z %.3f m  theta %5.1f deg%s\n", s.row.c_str(), s.z_m, s.theta_deg,
                  s.keeps.empty() ? "" : ("  (where sensor " + s.keeps + " is now)").c_str());
    out += line;
  }
  out +=
      "How it is judged: at the reline point (the liner's thinnest area at its minimum thickness), if every sensor read\n"
      "what the DEM map predicts, the live wear's band differs between layouts only by how well each row's sensors pin\n"
      "its scale (how many there are, the map's wear intensity and its error at each, from the DEM run's windows).\n"
      "The figure is the mean band half-width (+/- 2 sd) of the liner's thinnest area and each row's, on " +
      area + ".\n";
  if (std::isfinite(p.current_mm)) {
    std::snprintf(line, sizeof line,
                  "Expected band: +/- %.1f mm with this layout against +/- %.1f mm with the crusher.json layout "
                  "(liner's thinnest area: +/- %.1f mm against +/- %.1f mm).\n",
                  p.proposed_mm, p.current_mm, p.liner_proposed_mm, p.liner_current_mm);
  } else {
    std::snprintf(line, sizeof line,
                  "Expected band: +/- %.1f mm (liner's thinnest area +/- %.1f mm); crusher.json has no sensors to compare.\n",
                  p.proposed_mm, p.liner_proposed_mm);
  }
  out += line;
  for (const RowPlan& r : p.rows) {
    std::snprintf(line, sizeof line,
                  "  row %-8s %zu sensors (now %zu): band +/- %.1f mm (now +/- %.1f mm); its reline date band %s in the "
                  "same proportion\n",
                  r.row.c_str(), r.proposed_sensors, r.current_sensors, r.proposed_mm, r.current_mm,
                  r.proposed_mm < r.current_mm ? "narrows" : "widens");
    out += line;
  }
  if (p.scan) {
    const ScanAdvice& s = *p.scan;
    const ScanAdvice::Row* first = nullptr;
    for (const ScanAdvice::Row& r : s.rows)
      if (r.row == s.first_row) first = &r;
    std::snprintf(
        line, sizeof line,
        "This campaign: a laser scan now (%s) would take the liner's thinnest-area band from +/- %.1f mm to +/- %.1f mm",
        s.at.c_str(), s.liner_now_mm, s.liner_scan_mm);
    out += line;
    if (first && std::isfinite(first->now_days) && std::isfinite(first->scan_days)) {
      std::snprintf(line, sizeof line,
                    ", and the reline date band of row %s (the first to reach the minimum) from %.0f to %.0f days",
                    first->row.c_str(), first->now_days, first->scan_days);
      out += line;
    }
    out += ".\n";
  }
  return out;
}

}  // namespace lw::estimate
