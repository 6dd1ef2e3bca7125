// Diagnosis stage 8, predictions and report data (stage_predictions.hpp).
#include "stage_predictions.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

#include "core/scan_correction.hpp"
#include "report_maps.hpp"

namespace lw::diagnosis::detail {
namespace {

// Material the sensor lost in steps up to time t.
double LossOffset(const SensorData& s, double t) {
  double off = 0;
  for (const auto& l : s.analysis.losses)
    if (t >= l.t_days) off += l.depth_mm;
  return off;
}

// The improved model's intensity error at the sensor (0 for the baseline or an unused sensor).
double SensorU(const PredictionInput& in, const SensorData& s) {
  return (in.use_improved && s.usable) ? in.model.u[static_cast<size_t>(s.usable_index)] : 0.0;
}

// Per sensor, the factor its improved-model point's rate is scaled by so that it wears along its
// own depth curve (OwnRateFactor of its intensity error; 1 for the baseline, SimulateOwnRates).
std::vector<double> DepthFactors(const PredictionInput& in) {
  std::vector<double> f(in.setup.sensors.size(), 1.0);
  if (in.use_improved)
    for (size_t i = 0; i < f.size(); ++i) f[i] = OwnRateFactor(SensorU(in, in.setup.sensors[i]));
  return f;
}

double Days(const PredictionInput& in, core::TimePoint t) {
  return core::DaysBetween(in.bundle.crusher.installed_at, t);
}

// The scan the face predictions at a time take as ground truth at its date: the latest at or
// before it, projected on the map's faces, and the live map's correction by it (core ApplyScan with
// the readings the diagnosis kept: the weights of the server's live wear).
struct FaceAnchor {
  double t_days = 0;
  Eigen::VectorXd scan_wear_mm;  // per face, NaN where no point fell
  // Per face no point fell on that the live map filled from its scanned neighbours (within 1.5
  // face sizes): the scan's wear there, interpolated (Eq. 9 at the scan's date x the live map's
  // correction ratio of the face); NaN elsewhere.
  Eigen::VectorXd filled_wear_mm;
  core::ScanCorrection corr;
  bool Applied() const { return corr.detail.empty() && corr.face_weight.size() == scan_wear_mm.size(); }
};

std::optional<FaceAnchor> AnchorAt(const PredictionInput& in, const std::vector<ModelPoint>& face_points,
                                   const std::vector<core::Reading>& used, core::TimePoint at, Prediction::ScanAnchor& report) {
  const core::Scan* latest = core::LatestScanAt(in.bundle.scans, at);
  if (!latest) return std::nullopt;
  FaceAnchor a;
  a.t_days = Days(in, latest->date);
  core::ReconstructionPlan plan = core::PrepareReconstruction(in.bundle.crusher, in.bundle.map, in.setup.fields.model);
  const core::ScanFaces sf = core::ProjectScanToFaces(in.bundle.map, *latest);
  a.scan_wear_mm = sf.wear_mm;
  // The sensors' wear at the scan's date sets the row scales there; a sensor whose last kept reading
  // is stale then (a stuck or dead sensor's readings are not kept) would give the wear of that older
  // day and bias its row's scale: core::FreshSensorWearAt leaves it out.
  const std::vector<core::SensorWear> wear = core::FreshSensorWearAt(in.bundle.crusher, used, latest->date);
  report.sensors_used = wear.size();
  a.corr = core::ApplyScan(plan, sf, wear);
  report.file = latest->file;
  report.date = latest->date;
  if (!a.Applied()) {
    report.detail = a.corr.detail.empty() ? "no correction per face" : a.corr.detail;
    return std::nullopt;
  }
  report.faces_measured = a.corr.faces_corrected;
  report.faces_filled = a.corr.faces_filled;
  const Eigen::VectorXd eq9_at_scan = SimulateAt(in.base.spec, in.base.eq9.x, face_points, in.setup.prob.grid, a.t_days);
  a.filled_wear_mm = Eigen::VectorXd::Constant(a.scan_wear_mm.size(), kNaN);
  for (Eigen::Index f = 0; f < a.filled_wear_mm.size() && f < eq9_at_scan.size(); ++f)
    if (!(a.corr.face_weight[f] > 0) && a.corr.face_ratio[f] != 1.0) a.filled_wear_mm[f] = eq9_at_scan[f] * a.corr.face_ratio[f];
  return a;
}

// A model's wear per face at t_days (mm, in [0, thickness]); with an anchor, taken to the scan at its
// date and carried forward by the model. Per face, the model's wear at the scan's date m_s moves to
// the scan's s with the live map's weight w (m_s + w (s - m_s); a face without scan points takes the
// scan's wear interpolated from its neighbours, as the live map does: not the model's value times
// the neighbours' ratio, which is relative to Eq. 9 and would count a model's own pattern twice),
// and the model's growth since then scales it (wear(t) x anchored / m_s), so a pattern the map got
// wrong stays corrected as the liner wears on, and each model keeps its own time course (Eq. 9: the
// row scales' growth, exactly as live wear does). Where the model has next to no wear at the scan
// (< kMinAnchorWearMm) the shift is added instead.
Eigen::VectorXd ModelFaceWear(const ModelSpec& spec, const Eigen::VectorXd& x, const std::vector<ModelPoint>& faces,
                              const TimeGrid& grid, double t_days, const FaceAnchor* anchor, double thickness_mm) {
  constexpr double kMinAnchorWearMm = 0.5;
  Eigen::VectorXd w = SimulateAt(spec, x, faces, grid, t_days);
  if (anchor && static_cast<size_t>(anchor->scan_wear_mm.size()) == faces.size()) {
    const Eigen::VectorXd at_scan = SimulateAt(spec, x, faces, grid, anchor->t_days);
    for (Eigen::Index f = 0; f < w.size(); ++f) {
      const double m_s = at_scan[f], s = anchor->scan_wear_mm[f], wt = anchor->corr.face_weight[f];
      const double filled = anchor->filled_wear_mm[f];
      const double anchored = wt > 0 && std::isfinite(s) ? m_s + wt * (std::max(s, 0.0) - m_s)
                              : std::isfinite(filled)    ? std::max(filled, 0.0)
                                                         : m_s;
      w[f] = m_s > kMinAnchorWearMm ? w[f] * anchored / m_s : w[f] + (anchored - m_s);
    }
  }
  return w.cwiseMax(0.0).cwiseMin(thickness_mm);
}

// The improved model's faces. Without a finding: Eq. 9's (the refit baseline's gain is its
// per-sensor terms, known at the sensors only). With one and a scan: the model anchored to the scan.
// With one and no scan: Eq. 9's faces times the model's wear over the refit baseline's, face by face
// (their difference above 0.5 mm of refit wear, additive below): the findings' pattern and time
// course, carried by the row levels Eq. 9 takes from the sensors. Both fits weight their row scales
// by the sensors' map-noise terms, which carried the sensors' own misfit to the faces of their rows
// (worse than Eq. 9 away from the sensors without a scan); in the ratio that misfit cancels.
Eigen::VectorXd ImprovedFaceWear(const PredictionInput& in, const std::vector<ModelPoint>& face_points, double t_days,
                                 const FaceAnchor* anchor, const Eigen::VectorXd& eq9_faces) {
  constexpr double kMinRefitWearMm = 0.5;
  if (!in.model_has_findings) return eq9_faces;
  const TimeGrid& grid = in.setup.prob.grid;
  const double thickness_mm = in.bundle.crusher.thickness_new_mm;
  Eigen::VectorXd w = ModelFaceWear(in.model.spec, in.model.x, face_points, grid, t_days, anchor, thickness_mm);
  if (anchor || !RefitUsable(in.null) || eq9_faces.size() != w.size()) return w;
  const Eigen::VectorXd r = ModelFaceWear(in.null.fit.spec, in.null.fit.x, face_points, grid, t_days, nullptr, thickness_mm);
  for (Eigen::Index f = 0; f < w.size(); ++f)
    w[f] = r[f] > kMinRefitWearMm ? eq9_faces[f] * w[f] / r[f] : eq9_faces[f] + (w[f] - r[f]);
  return w.cwiseMax(0.0).cwiseMin(thickness_mm);
}

SensorCurve CurveOf(const PredictionInput& in, size_t i, const Eigen::MatrixXd& w_base, const Eigen::MatrixXd& w_best) {
  const ProblemSetup& setup = in.setup;
  const TimeGrid& grid = setup.prob.grid;
  const SensorData& s = setup.sensors[i];
  SensorCurve c;
  c.sensor_id = s.id;
  c.row = s.row;
  c.thickness_new_mm = s.thickness;
  c.used = s.usable;
  for (size_t k = 0; k < s.analysis.readings.size(); ++k) {
    c.reading_days.push_back(s.analysis.readings[k].t_days);
    c.reading_mm.push_back(s.analysis.readings[k].value_mm);
    c.reading_used.push_back(s.analysis.used[k]);
  }
  const size_t stride = std::max<size_t>(1, grid.steps / 120);
  const double t_end = std::max(setup.time.t_obs_end, in.options.predict_at ? Days(in, *in.options.predict_at) : 0.0);
  for (size_t j = 0; j <= grid.steps; j += stride) {
    const double t = static_cast<double>(j) * grid.dt;
    if (t > t_end + grid.dt) break;
    c.model_days.push_back(t);
    const auto r = static_cast<Eigen::Index>(i);
    const auto jj = static_cast<Eigen::Index>(j);
    c.baseline_thickness_mm.push_back(s.thickness - w_base(r, jj));
    c.improved_thickness_mm.push_back(s.thickness - w_best(r, jj) * (1.0 + SensorU(in, s)) -
                                      (in.use_improved ? LossOffset(s, t) : 0.0));
  }
  return c;
}

}  // namespace

std::vector<ModelPoint> SensorPoints(const ProblemSetup& setup) {
  std::vector<ModelPoint> points;
  for (const SensorData& s : setup.sensors) points.push_back(MakePoint(setup.fields, setup.interp, s.field, 0.5 * s.thickness));
  return points;
}

std::vector<ModelPoint> FacePoints(const core::Bundle& bundle, const ProblemSetup& setup) {
  const MapFields& fields = setup.fields;
  std::vector<ModelPoint> face_points;
  face_points.reserve(bundle.map.face_count());
  for (Eigen::Index f = 0; f < static_cast<Eigen::Index>(bundle.map.face_count()); ++f) {
    PointField pf;
    pf.z = bundle.map.z[f];
    pf.theta_deg = bundle.map.theta_deg[f];
    pf.intensity = fields.intensity[f];
    pf.normal_tilde = fields.normal_tilde[f];
    pf.normal_i = fields.normal_i[f];
    pf.broad_i = fields.broad_i[f];
    face_points.push_back(MakePoint(fields, setup.interp, pf, 0.5 * bundle.crusher.thickness_new_mm));
  }
  return face_points;
}

std::vector<SensorCurve> SensorCurves(const PredictionInput& in) {
  const std::vector<ModelPoint> points = SensorPoints(in.setup);
  Eigen::MatrixXd w_base, w_best;
  Simulate(in.base.spec, in.base.eq9.x, points, in.setup.prob.grid, w_base);
  SimulateOwnRates(in.model.spec, in.model.x, points, DepthFactors(in), in.setup.prob.grid, w_best);
  std::vector<SensorCurve> curves;
  for (size_t i = 0; i < in.setup.sensors.size(); ++i) curves.push_back(CurveOf(in, i, w_base, w_best));
  return curves;
}

std::vector<ResidualGrid> ResidualGrids(const PredictionInput& in) {
  const Problem& prob = in.setup.prob;
  const CellGrid& grid = in.setup.grid;
  const Eigen::MatrixXd& w_null = in.null.w;
  Eigen::MatrixXd w_best;
  Simulate(in.model.spec, in.model.x, prob.points, prob.grid, w_best);
  std::vector<ResidualGrid> grids;
  for (size_t si = 0; si < in.setup.scans.size(); ++si) {
    ResidualGrid g;
    g.scan_file = in.setup.scans[si].file;
    g.date = in.bundle.scans[si].date;
    g.nz = grid.nz;
    g.ntheta = grid.nt;
    g.z_min_m = grid.z0;
    g.z_max_m = grid.z0 + grid.dz * static_cast<double>(grid.nz);
    g.theta_min_deg = grid.t0_deg;
    g.theta_max_deg = grid.t0_deg + grid.dt_deg * static_cast<double>(grid.nt);
    g.measured_mm.assign(grid.cells.size(), kNaN);
    g.before_mm.assign(grid.cells.size(), kNaN);
    g.after_mm.assign(grid.cells.size(), kNaN);
    for (size_t i : prob.scan_obs) {
      const Obs& o = prob.obs[i];
      if (o.scan != static_cast<int>(si)) continue;
      const auto c = static_cast<size_t>(o.cell);
      g.measured_mm[c] = o.wear;
      g.before_mm[c] = Interp(w_null, o) - o.wear;
      g.after_mm[c] = Interp(w_best, o) - o.wear;
    }
    grids.push_back(std::move(g));
  }
  return grids;
}

Prediction PredictAt(const PredictionInput& in, const std::vector<ModelPoint>& face_points,
                     const std::vector<core::Reading>& used, core::TimePoint at) {
  const TimeGrid& grid = in.setup.prob.grid;
  const double thickness_new_mm = in.bundle.crusher.thickness_new_mm;
  const std::vector<ModelPoint> sensor_points = SensorPoints(in.setup);
  Prediction pred;
  pred.time = at;
  const double t = Days(in, at);
  const Eigen::VectorXd wb = SimulateAt(in.base.spec, in.base.eq9.x, sensor_points, grid, t);
  const Eigen::VectorXd wi = SimulateOwnRatesAt(in.model.spec, in.model.x, sensor_points, DepthFactors(in), grid, t);
  const bool refit = RefitUsable(in.null);
  const Eigen::VectorXd wr = refit ? SimulateAt(in.null.fit.spec, in.null.fit.x, sensor_points, grid, t) : wb;
  for (size_t i = 0; i < in.setup.sensors.size(); ++i) {
    const SensorData& s = in.setup.sensors[i];
    const auto r = static_cast<Eigen::Index>(i);
    const double u_refit = refit && s.usable && static_cast<size_t>(s.usable_index) < in.null.fit.u.size()
                               ? in.null.fit.u[static_cast<size_t>(s.usable_index)]
                               : 0.0;
    pred.sensors.push_back(
        {s.id, std::max(0.0, s.thickness - wb[r]),
         std::max(0.0, s.thickness - wi[r] * (1.0 + SensorU(in, s)) - (in.use_improved ? LossOffset(s, t) : 0.0)),
         std::max(0.0, s.thickness - wr[r] * (1.0 + u_refit) - (refit ? LossOffset(s, t) : 0.0))});
  }
  // The faces: from the latest scan when there is one; physical (a face's wear is at most the
  // as-new thickness: worn through).
  const std::optional<FaceAnchor> anchor = AnchorAt(in, face_points, used, at, pred.faces_scan);
  const FaceAnchor* a = anchor ? &*anchor : nullptr;
  const Eigen::VectorXd fb = ModelFaceWear(in.base.spec, in.base.eq9.x, face_points, grid, t, a, thickness_new_mm);
  const Eigen::VectorXd fi = ImprovedFaceWear(in, face_points, t, a, fb);
  pred.face_wear_baseline_mm.assign(fb.data(), fb.data() + fb.size());
  pred.face_wear_improved_mm.assign(fi.data(), fi.data() + fi.size());
  return pred;
}

void Predict(const PredictionInput& in, DiagnosisResult& result) {
  result.curves = SensorCurves(in);
  result.grids = ResidualGrids(in);
  // Model points of every map face (the prediction and the report's liner maps).
  const std::vector<ModelPoint> face_points = FacePoints(in.bundle, in.setup);
  if (in.options.predict_at)
    result.prediction = PredictAt(in, face_points, UsedReadings(in.bundle.crusher, result.curves), *in.options.predict_at);
  // Unwrapped-liner maps and thinnest points for the HTML report (report_maps.cpp): each model as
  // it stands (compared with the scans there), not anchored to them.
  // Eq. 9's faces at each time, computed once: the improved faces scale them.
  const double thickness_new_mm = in.bundle.crusher.thickness_new_mm;
  std::map<double, Eigen::VectorXd> base_at;
  FillLinerReport(
      in.bundle, in.setup.fields, in.setup.scans,
      [&](bool improved, double t) {
        auto it = base_at.find(t);
        if (it == base_at.end())
          it = base_at
                   .emplace(t, ModelFaceWear(in.base.spec, in.base.eq9.x, face_points, in.setup.prob.grid, t, nullptr,
                                             thickness_new_mm))
                   .first;
        return improved ? ImprovedFaceWear(in, face_points, t, nullptr, it->second) : it->second;
      },
      result);
}

}  // namespace lw::diagnosis::detail
