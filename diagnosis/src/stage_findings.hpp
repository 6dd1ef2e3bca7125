#pragma once
/// Diagnosis stage 6, findings: the chosen model's effects ranked by their own contribution, with
/// confidence and explanation; material loss seen by sensors and scans (scan_craters.hpp); an "unexplained" finding when the
/// mismatch is real and no effect explains it; the hypotheses table, the noise summary and the
/// chosen model's error metrics.
#include <optional>
#include <vector>

#include "diagnosis/diagnose.hpp"
#include "explanations.hpp"
#include "model_fit.hpp"
#include "stage_hypotheses.hpp"
#include "stage_mismatch.hpp"
#include "stage_setup.hpp"

namespace lw::diagnosis::detail {

/// How the refit baseline's relative residual relates to the fields (evidence in every finding).
struct ResidualEvidence {
  double corr_normal = 0;  ///< with normal stress
  double corr_depth = 0;   ///< with worn depth
};
ResidualEvidence BaselineResidualEvidence(const Problem& prob, const NullModel& null);

/// Confidence of a chosen model from its gains and the best score of a model without its effects.
double Confidence(const ModelEval& ev, double runner_up_score);

/// One finding per effect of the chosen model, strongest contribution first; none without a chosen model.
std::vector<Finding> ModelFindings(const Hypotheses& h, const ModelEval& null_eval, const ExplainContext& context, size_t n_obs);

/// The "unexplained" finding of a real mismatch (z above the threshold) no effect explains.
Finding UnexplainedFinding(double mismatch_z, const std::vector<ModelEval>& evals);

/// Every model tried, as the JSON "hypotheses" array.
nlohmann::ordered_json HypothesesTable(const std::vector<ModelEval>& evals, size_t rows);

/// The refit baseline's chi-square per data kind, per observation, the mismatch z and the folds' names.
void SummariseNoise(const Problem& prob, const NullModel& null, const std::vector<Fold>& folds, DiagnosisResult& result);

/// A model's error in mm on all observations (intensity error applied) and held out.
ErrorSummary ModelMetrics(const Problem& prob, const ModelEval& ev);

struct FindingsInput {
  const core::Bundle& bundle;
  const ProblemSetup& setup;
  const NullModel& null;
  const Hypotheses& hypotheses;
  bool scan_craters = true;  ///< DiagnoseOptions::scan_craters
};

/// The whole findings list, by confidence (model findings and material loss, or the unexplained one).
std::vector<Finding> RankFindings(const FindingsInput& in);

/// A mismatch is reported when the chi-square excess is real or anything was found.
bool MismatchDetected(double mismatch_z, const std::vector<Finding>& findings);

}  // namespace lw::diagnosis::detail
