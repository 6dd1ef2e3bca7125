// Diagnose(): the diagnosis as a pipeline of stages, each in its own file with typed results
// (docs/diagnosis.md, "Method"):
//   stage_setup        bundle -> map fields, analysed sensors, time grid, observations
//   stage_baseline     Eq. 9 baseline on the sensors; the noise model measured against it
//   stage_folds        hold-out folds
//   stage_mismatch     refit baseline, mismatch test (and the benchmarks' oracle)
//   stage_hypotheses   every effect (and promising pairs) fitted and judged; the chosen model
//   stage_findings     findings with explanations, hypotheses table, noise summary, metrics
//   stage_regions      where the baseline misses beyond the noise
//   stage_predictions  curves, residual grids, prediction, liner report
//   stage_report       what the outputs say about the decisions: excluded sensors, residuals
//                      beside their noise, whether the noise model fits, why hypotheses failed
#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "diagnosis/diagnose.hpp"
#include "stage_baseline.hpp"
#include "stage_findings.hpp"
#include "stage_folds.hpp"
#include "stage_hypotheses.hpp"
#include "stage_limits.hpp"
#include "stage_mismatch.hpp"
#include "stage_predictions.hpp"
#include "stage_regions.hpp"
#include "stage_report.hpp"
#include "stage_setup.hpp"

namespace lw::diagnosis {

namespace {
struct ImprovedModelText {
  const char* name;   // the JSON's improved.model
  const char* label;  // a report's words
};
ImprovedModelText TextOf(ImprovedModel model) {
  switch (model) {
    case ImprovedModel::kFindings:
      return {"findings", "improved model (findings)"};
    case ImprovedModel::kRefitBaseline:
      return {"refit_baseline", "refit only (no findings: the map recalibrated at the sensors)"};
    case ImprovedModel::kBaseline:
      break;
  }
  return {"baseline", "improved model (= baseline)"};
}
}  // namespace

const char* ImprovedModelName(ImprovedModel model) {
  return TextOf(model).name;
}
const char* ImprovedModelLabel(ImprovedModel model) {
  return TextOf(model).label;
}
const char* ImprovedModelDescription(ImprovedModel model) {
  switch (model) {
    case ImprovedModel::kFindings:
      return "the Eq. 9 baseline with the findings modelled: their parameters, the row scales and each sensor's map-error "
             "term fitted to these readings and scans";
    case ImprovedModel::kRefitBaseline:
      return "a refit, not a finding: the same Eq. 9 with the row scales and each sensor's map-error term fitted to these "
             "same readings and scans, no physics added; its smaller error says the map was off at the sensors, not that "
             "a model improved";
    case ImprovedModel::kBaseline:
      break;
  }
  return "Eq. 9 itself (the refit failed)";
}

DiagnosisResult Diagnose(const core::Bundle& bundle, const DiagnoseOptions& options) {
  DiagnosisResult result;
  // Benchmarks' oracle: checked before any work.
  const std::optional<detail::Effect> oracle_effect = detail::ParseOracle(options.oracle);
  result.crusher_id = bundle.crusher.crusher_id;
  result.installed_at = bundle.crusher.installed_at;

  detail::ProblemSetup setup = detail::SetUpProblem(bundle, options, result);
  if (!setup.Diagnosable()) {
    for (const detail::SensorData& s : setup.sensors) {
      SensorNoise n;
      n.sensor_id = s.id;
      n.excluded_because = detail::ExcludedBecause(s, result.data_quality);
      result.sensors.push_back(std::move(n));
    }
    return result;
  }
  const detail::Baseline base = detail::FitBaseline(setup.prob);
  detail::CalibrateNoise(setup, base, result);
  const detail::Problem& prob = setup.prob;
  const std::vector<detail::Fold> folds = detail::BuildFolds(setup, options.holdout_fraction);

  detail::NullModel null = detail::TestMismatch(prob, base, folds);
  if (options.learned_noise_in_hypotheses) {
    // The test's figures stay those of the modelled noise it learned from; the fits use the learned.
    const detail::NullModel first = null;
    detail::ApplyLearnedNoise(setup.prob, first.calibration);
    null = detail::TestMismatch(prob, base, folds);
    null.calibration = first.calibration;
    null.mismatch_z = first.mismatch_z;
    null.mismatch_z_modelled = first.mismatch_z_modelled;
    null.parts = first.parts;
  }
  result.mismatch_z_score = null.mismatch_z;
  if (oracle_effect) result.oracle = detail::MeasureOracle(prob, base, null, *oracle_effect, *options.oracle);
  result.baseline = detail::BaselineMetrics(prob, base, folds);

  const detail::Hypotheses hyp = detail::TestHypotheses(
      prob, base, null, folds, detail::AvailableEffects(setup.fields.has_normal, setup.time.throughput_available),
      options.try_pairs, result);
  const detail::ModelEval* chosen = hyp.Chosen();

  result.findings = detail::RankFindings({bundle, setup, null, hyp, options.scan_craters});
  {
    double last_day = 0;
    for (const detail::Obs& o : prob.obs) last_day = std::max(last_day, o.t);
    result.limits = detail::DetectionLimits(hyp, null.log_n, prob.map_harmonic1_sd, result.findings, last_day);
  }
  result.mismatch_detected = detail::MismatchDetected(result.mismatch_z_score, result.findings);
  result.hypotheses = detail::HypothesesTable(hyp.evals, prob.rows);
  detail::AnnotateHypotheses(result.hypotheses, hyp, null.log_n);
  detail::SummariseNoise(prob, null, folds, result);
  result.sensors = detail::ExplainSensors(setup, base, null, result.data_quality,
                                          result.noise.value("map_pattern_error_source", std::string()));
  result.noise_fit = detail::JudgeNoiseFit(result.noise, result.mismatch_z_score, result.sensors);
  {
    // In the calibrated test's units: its variance is 2 sum(b n), and a sensor's static error costs
    // (error / sd)^2 over the sensors' learned variance scale.
    const detail::MismatchCalibration& cal = null.calibration;
    double dof = 0;
    for (int t = 0; t < 3; ++t) dof += cal.correlation[t] * static_cast<double>(cal.n[t]);
    std::vector<SensorNoise> learned = result.sensors;
    for (SensorNoise& n : learned) n.noise_sd_mm *= std::sqrt(cal.scale[1]);
    detail::AddDetectionLimit(result.noise_fit, result.mismatch_z_score, std::max(1.0, dof), learned);
  }
  // The improved model: the chosen one; with nothing chosen, the refit baseline (row scales fitted
  // to the sensors and scans together, each sensor's map-noise term: the map recalibrated where it
  // was measured, no physics added), unless its fit failed; then Eq. 9 itself.
  const bool use_improved = chosen != nullptr || detail::RefitUsable(null);
  result.improved = use_improved ? detail::ModelMetrics(prob, chosen ? *chosen : null.eval) : result.baseline;
  result.improved_model =
      chosen ? ImprovedModel::kFindings : (use_improved ? ImprovedModel::kRefitBaseline : ImprovedModel::kBaseline);
  const detail::FitResult& model_fit = use_improved ? (chosen ? chosen->full : null.fit) : base.eq9;

  if (result.mismatch_detected) result.regions = detail::FindRegions(bundle, setup, null);
  detail::Predict({bundle, options, setup, base, null, model_fit, use_improved, chosen != nullptr}, result);
  detail::AddExcludedEvidence(result.sensors, result.curves);

  std::stable_sort(result.data_quality.begin(), result.data_quality.end(),
                   [](const DataQualityIssue& a, const DataQualityIssue& b) {
                     return a.sensor_id != b.sensor_id ? a.sensor_id < b.sensor_id : a.from < b.from;
                   });
  return result;
}

}  // namespace lw::diagnosis
