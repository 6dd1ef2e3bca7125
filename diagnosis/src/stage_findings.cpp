// Diagnosis stage 6, findings (stage_findings.hpp).
#include "stage_findings.hpp"

#include "scan_craters.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

namespace lw::diagnosis::detail {

ResidualEvidence BaselineResidualEvidence(const Problem& prob, const NullModel& null) {
  const FitResult& null_fit = null.fit;
  const Eigen::MatrixXd& w = null.w;
  std::vector<double> res_null, f_normal, f_depth;
  for (const Obs& o : prob.obs) {
    double pred = Interp(w, o);
    if (o.sensor >= 0) pred *= 1.0 + null_fit.u[static_cast<size_t>(o.sensor)];
    if (pred <= 0.5) continue;
    res_null.push_back((pred - o.wear) / pred);
    f_normal.push_back(prob.points[o.point].normal_tilde);
    f_depth.push_back(o.wear);
  }
  return {Correlation(res_null, f_normal), Correlation(res_null, f_depth)};
}

double Confidence(const ModelEval& ev, double runner_up_score) {
  const Thresholds th;
  const double s1 = 1.0 / (1.0 + std::exp(-(ev.delta_bic - th.min_delta_bic) / 8.0));
  const double s2 = 1.0 / (1.0 + std::exp(-(ev.ho_rel - th.min_holdout_rel) / 0.05));
  const double share = ev.score > 0 ? ev.score / (ev.score + std::max(0.0, runner_up_score)) : 0.5;
  return std::clamp(s1 * s2 * (0.5 + 0.5 * share) * 1.2, 0.0, 0.99);
}

std::vector<Finding> ModelFindings(const Hypotheses& h, const ModelEval& null_eval, const ExplainContext& context, size_t n_obs) {
  std::vector<Finding> findings;
  const ModelEval* chosen = h.Chosen();
  if (!chosen) return findings;
  const std::vector<ModelEval>& evals = h.evals;
  const size_t singles = h.singles;
  double runner_up = 0;
  for (size_t k = 0; k < singles; ++k) {
    const ModelEval& ev = evals[k];
    bool part = false;
    for (Effect e : chosen->full.spec.effects)
      if (std::string(EffectName(ev.full.spec.effects[0])) == EffectName(e)) part = true;
    if (!part) runner_up = std::max(runner_up, ev.score);
  }
  // Order the chosen model's effects by their own contribution (drop-one chi-square).
  std::vector<std::pair<double, Effect>> parts;
  for (Effect e : chosen->full.spec.effects) {
    double contribution = chosen->delta_bic;
    if (chosen->full.spec.effects.size() > 1) {
      for (size_t k = 0; k < singles; ++k) {
        const Effect other = evals[k].full.spec.effects[0];
        if (other != e && std::find(chosen->full.spec.effects.begin(), chosen->full.spec.effects.end(), other) !=
                              chosen->full.spec.effects.end())
          contribution = evals[k].full.chi2 - chosen->full.chi2;
      }
    }
    parts.push_back({contribution, e});
  }
  std::sort(parts.begin(), parts.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  const double conf = Confidence(*chosen, runner_up);
  for (size_t k = 0; k < parts.size(); ++k) {
    Finding f;
    f.effect = EffectName(parts[k].second);
    f.confidence = Round(k == 0 ? conf : conf * 0.9, 3);
    DescribeEffect(context, chosen->full, parts[k].second, f);
    f.evidence["model"] = chosen->full.spec.Name();
    f.evidence["delta_bic"] = Round(chosen->delta_bic, 2);
    f.evidence["chi2_baseline"] = Round(null_eval.full.chi2, 2);
    f.evidence["chi2_model"] = Round(chosen->full.chi2, 2);
    f.evidence["observations"] = n_obs;
    f.evidence["holdout_chi2_baseline"] = Round(null_eval.ho_chi2, 2);
    f.evidence["holdout_chi2_model"] = Round(chosen->ho_chi2, 2);
    f.evidence["holdout_improvement"] = Round(chosen->ho_rel, 3);
    f.evidence["contribution_chi2"] = Round(parts[k].first, 2);
    f.evidence["residual_corr_normal_stress"] = Round(context.corr_normal, 3);
    f.evidence["residual_corr_depth"] = Round(context.corr_depth, 3);
    nlohmann::ordered_json alternatives = nlohmann::ordered_json::object();
    for (size_t m = 0; m < singles; ++m) alternatives[evals[m].full.spec.Name()] = Round(evals[m].delta_bic, 2);
    f.evidence["alternatives_delta_bic"] = alternatives;
    // Named over a better-scoring effect that it explains away in their joint fit (docs/diagnosis.md).
    if (h.encompassing.explained_away >= 0)
      f.evidence["explains_away"] = evals[static_cast<size_t>(h.encompassing.explained_away)].full.spec.Name();
    findings.push_back(std::move(f));
  }
  return findings;
}

Finding UnexplainedFinding(double mismatch_z, const std::vector<ModelEval>& evals) {
  const Thresholds th;
  Finding f;
  f.effect = kUnexplained;
  f.confidence = Round(std::clamp(1.0 - std::exp(-(mismatch_z - th.mismatch_z) / 4.0), 0.3, 0.95), 3);
  f.explanation =
      Fmt("The recordings disagree with the DEM-based reconstruction by more than sensor quantisation, map noise and "
          "scan noise allow (chi-square excess %.1f sigma), but none of the modelled effects explains it on held-out "
          "data. See the mismatch regions.",
          mismatch_z);
  f.evidence["mismatch_z_score"] = Round(mismatch_z, 2);
  nlohmann::ordered_json alternatives = nlohmann::ordered_json::object();
  for (const ModelEval& ev : evals) alternatives[ev.full.spec.Name()] = Round(ev.delta_bic, 2);
  f.evidence["alternatives_delta_bic"] = alternatives;
  return f;
}

nlohmann::ordered_json HypothesesTable(const std::vector<ModelEval>& evals, size_t rows) {
  nlohmann::ordered_json table = nlohmann::ordered_json::array();
  for (const ModelEval& ev : evals) {
    nlohmann::ordered_json h;
    h["model"] = ev.full.spec.Name();
    h["delta_bic"] = Round(ev.delta_bic, 2);
    h["holdout_chi2"] = Round(ev.ho_chi2, 2);
    h["holdout_improvement"] = Round(ev.ho_rel, 3);
    h["significance"] = Round(std::min(ev.significance, 1e6), 2);
    h["accepted"] = ev.accepted;
    nlohmann::ordered_json params = nlohmann::ordered_json::object();
    size_t idx = rows;
    for (Effect e : ev.full.spec.effects)
      for (const auto& ps : EffectParams(e)) params[ps.name] = Round(ev.full.x[static_cast<Eigen::Index>(idx++)], 4);
    h["parameters"] = params;
    table.push_back(h);
  }
  return table;
}

void SummariseNoise(const Problem& prob, const NullModel& null, const std::vector<Fold>& folds, DiagnosisResult& result) {
  const FitResult& null_fit = null.fit;
  const Eigen::MatrixXd& w_null_fit = null.w;
  {
    // Chi-square of the refit baseline split by data kind: checks the noise model.
    double cs = 0, cc = 0;
    size_t ns = 0, nc = 0;
    for (const Obs& o : prob.obs) {
      double pred = Interp(w_null_fit, o);
      if (o.sensor >= 0) pred *= 1.0 + null_fit.u[static_cast<size_t>(o.sensor)];
      const double z = (pred - o.wear) / o.sigma;
      (o.sensor >= 0 ? cs : cc) += z * z;
      ++(o.sensor >= 0 ? ns : nc);
    }
    result.noise["baseline_chi2_per_sensor_event"] = Round(ns ? cs / static_cast<double>(ns) : 0.0, 3);
    result.noise["baseline_chi2_per_scan_cell"] = Round(nc ? cc / static_cast<double>(nc) : 0.0, 3);
    result.noise["sensor_events"] = ns;
    result.noise["scan_cells"] = nc;
  }
  result.noise["baseline_chi2_per_observation"] =
      Round(null_fit.chi2 / std::max<double>(1.0, static_cast<double>(null_fit.n_train)), 3);
  result.noise["mismatch_z_score"] = Round(null.mismatch_z, 2);
  {
    // Per observation type, the parts of the very chi-square z is made of (scan cells with their
    // band offsets' priors; the sensors' intensity-error priors apart from their events).
    const Chi2Parts& c = null.parts;
    auto part = [](double chi2, size_t n) {
      nlohmann::ordered_json j;
      j["chi2"] = Round(chi2, 3);
      j["n"] = n;
      j["per_observation"] = Round(n ? chi2 / static_cast<double>(n) : 0.0, 4);
      return j;
    };
    nlohmann::ordered_json by = nlohmann::ordered_json::object();
    by["sensor_events"] = part(c.events, c.n_events);
    by["sensor_priors"] = part(c.priors, c.n_priors);
    by["scan_cells"] = part(c.scan, c.n_scan);
    result.noise["refit_chi2_by_type"] = by;
    result.noise["mismatch_dof"] = std::max(1.0, static_cast<double>(null.fit.n_train) - static_cast<double>(prob.rows));
    result.noise["mismatch_z_modelled_noise"] = Round(null.mismatch_z_modelled, 2);
    // The calibration the test uses (MismatchCalibration): each type's variance scale learned
    // from its groups held out, its effective correlation, and the chi-square per observation
    // after it (about 1 where the noise is learned).
    const MismatchCalibration& m = null.calibration;
    nlohmann::ordered_json cal = nlohmann::ordered_json::object();
    const char* names[3] = {"sensor_events", "sensor_priors", "scan_cells"};
    for (int t = 0; t < 3; ++t) {
      if (m.n[t] == 0) continue;
      nlohmann::ordered_json j;
      j["groups"] = m.groups[t];
      j["learned"] = m.learned[t];
      j["variance_scale"] = Round(m.scale[t], 4);
      j["correlation"] = Round(m.correlation[t], 2);
      j["chi2_per_observation"] = Round(m.chi2_calibrated[t] / static_cast<double>(m.n[t]), 3);
      cal[names[t]] = j;
    }
    result.noise["mismatch_calibration"] = cal;
  }
  {
    nlohmann::ordered_json f = nlohmann::ordered_json::array();
    for (const Fold& fold : folds) f.push_back(fold.name);
    result.noise["holdout_folds"] = f;
  }
}

ErrorSummary ModelMetrics(const Problem& prob, const ModelEval& ev) {
  const size_t n_obs = prob.obs.size();
  ErrorSummary m;
  Eigen::MatrixXd w;
  Simulate(ev.full.spec, ev.full.x, prob.points, prob.grid, w);
  SensorDepthRows(prob, ev.full.spec, ev.full.x, ev.full.u, w);
  double sq = 0, mx = 0;
  for (const Obs& o : prob.obs) {
    double pred = Interp(w, o);
    if (o.sensor >= 0) pred *= 1.0 + ev.full.u[static_cast<size_t>(o.sensor)];
    const double e = pred - o.wear;
    sq += e * e;
    mx = std::max(mx, std::fabs(e));
  }
  m.rmse_mm = n_obs ? std::sqrt(sq / static_cast<double>(n_obs)) : 0;
  m.max_abs_mm = mx;
  m.observations = n_obs;
  m.holdout_rmse_mm = ev.ho_n ? std::sqrt(ev.ho_sq_mm / static_cast<double>(ev.ho_n)) : 0;
  m.holdout_observations = ev.ho_n;
  return m;
}

std::vector<Finding> RankFindings(const FindingsInput& in) {
  const Thresholds th;
  const ProblemSetup& s = in.setup;
  ExplainContext context;
  context.has_normal = s.fields.has_normal;
  context.height_m = s.fields.z_top - s.fields.z_bottom;
  context.thickness_new_mm = in.bundle.crusher.thickness_new_mm;
  for (const Obs& o : s.prob.obs) context.span_days = std::max(context.span_days, o.t);
  context.throughput_cv = s.time.throughput_cv;
  for (const auto& o : in.bundle.operations)
    if (o.ore_ai) context.with_ai = true;
  const ResidualEvidence evidence = BaselineResidualEvidence(s.prob, in.null);
  context.corr_normal = evidence.corr_normal;
  context.corr_depth = evidence.corr_depth;
  std::vector<Finding> findings = ModelFindings(in.hypotheses, in.null.eval, context, s.prob.obs.size());
  const std::vector<CraterSighting> craters =
      in.scan_craters ? FindCratersInScans(in.bundle.map, s.fields, s.scans) : std::vector<CraterSighting>{};
  for (Finding& f : MaterialLossFindings(s.sensors, craters, s.fields.face_size_m, in.bundle.crusher.installed_at))
    findings.push_back(std::move(f));
  std::stable_sort(findings.begin(), findings.end(),
                   [](const Finding& a, const Finding& b) { return a.confidence > b.confidence; });
  const Encompassing& enc = in.hypotheses.encompassing;
  if (findings.empty() && enc.explained_away >= 0 && enc.best < 0) {
    // The best-scoring effect fitted something real, but another effect the data cannot confirm
    // explains it away: a mismatch without a determined cause (docs/diagnosis.md, encompassing).
    Finding f = UnexplainedFinding(in.null.mismatch_z, in.hypotheses.evals);
    const std::string a = in.hypotheses.evals[static_cast<size_t>(enc.explained_away)].full.spec.Name();
    const std::string b = in.hypotheses.evals[static_cast<size_t>(enc.by)].full.spec.Name();
    f.explanation =
        Fmt("The recordings disagree with the DEM-based reconstruction in a way %s fits (delta BIC %.1f), but "
            "fitted together with %s its effect falls to nothing while %s's stays, and %s alone predicts the "
            "held-out data better; %s is not confirmed on its own. The cause is not determined: a later scan "
            "or more months of readings will tell them apart.",
            a.c_str(), in.hypotheses.evals[static_cast<size_t>(enc.explained_away)].delta_bic, b.c_str(), b.c_str(), b.c_str(),
            b.c_str());
    f.evidence["explained_away"] = a;
    f.evidence["by"] = b;
    findings.push_back(std::move(f));
  }
  if (in.null.mismatch_z > th.mismatch_z && findings.empty())
    findings.push_back(UnexplainedFinding(in.null.mismatch_z, in.hypotheses.evals));
  return findings;
}

bool MismatchDetected(double mismatch_z, const std::vector<Finding>& findings) {
  const Thresholds th;
  return mismatch_z > th.mismatch_z || !findings.empty();
}

}  // namespace lw::diagnosis::detail
