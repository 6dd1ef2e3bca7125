#pragma once
/// Diagnosis stage 9, what the outputs say about the decisions (docs/diagnosis.md, "Reading the
/// report"): why each sensor was left out, each used sensor's baseline residual beside the noise the
/// mismatch test allows there (and where that noise comes from), whether the noise model fits the
/// data at all, and which acceptance test each rejected hypothesis failed and by how much. Nothing
/// here changes a statistic or a decision; it explains them.
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "diagnosis/diagnose.hpp"
#include "stage_baseline.hpp"
#include "stage_hypotheses.hpp"
#include "stage_mismatch.hpp"
#include "stage_setup.hpp"

namespace lw::diagnosis::detail {

/// Why the fit left a configured sensor out, in words; empty when it is used.
std::string ExcludedBecause(const SensorData& s, const std::vector<DataQualityIssue>& data_quality);

/// Every configured sensor (configuration order): used or why not; for a used one its latest loop
/// crossing's residual against the Eq. 9 baseline `base` and the noise model's standard deviation
/// there, part by part. `tau_source`: where the map's pattern error was measured
/// (`noise.map_pattern_error_source`).
std::vector<SensorNoise> ExplainSensors(const ProblemSetup& setup, const Baseline& base, const NullModel& null,
                                        const std::vector<DataQualityIssue>& data_quality, const std::string& tau_source);

/// What the noise model says about the data (NoiseFit), from the summary `noise` (SummariseNoise),
/// the mismatch z and the sensors' noise (ExplainSensors). Does not fit: chi-square per sensor event
/// or per scan cell below 0.25 (the modelled noise sd more than twice the data's scatter), or z below
/// -4 (the mirror of the mismatch threshold). Blind: the map's pattern error, or the noise sd at the
/// median used sensor, above 50 % of the predicted wear.
NoiseFit JudgeNoiseFit(const nlohmann::ordered_json& noise, double mismatch_z, const std::vector<SensorNoise>& sensors);

/// Adds to each entry of the hypotheses table (`table[k]` is `h.evals[k]`): `verdict` ("chosen",
/// "accepted" or "rejected"), for a rejected one `rejected_because` (each failed test with its value
/// and what it needed, in words) and `failed_tests` ([{"test", "value", "needed"}]), for an accepted
/// one not chosen `not_chosen_because`. `log_n` is the BIC charge per parameter (NullModel::log_n).
void AnnotateHypotheses(nlohmann::ordered_json& table, const Hypotheses& h, double log_n);

}  // namespace lw::diagnosis::detail
