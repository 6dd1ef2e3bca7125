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

/// The DEM map model's own standard error at a sensor (relative to its intensity there), its two
/// parts, and why it has that size there (SensorNoise::map_error_why / map_error_detail): its
/// sampling noise (the run's faces scatter between its time windows, averaged by the kernel), or its
/// smoothing's error, located where the map shows it: an edge band (the concave's bottom is its
/// discharge edge, its top the feed) within the kernel's reach (3 sd) whose ring-mean wear is over
/// 1.5 times (or under 1/1.5 of) the sensor height's; raw faces within one kernel sd of the sensor
/// whose mean differs from the smoothed value by more than twice its own noise; else the map's
/// cross-validated smoothing error over the whole liner.
struct MapError {
  double sd_rel = kNaN, sampling_rel = kNaN, smoothing_rel = kNaN;
  std::string why, detail;
};
MapError ExplainMapError(const MapFields& fields, const SensorData& s);

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

/// Adds to each unused sensor's reason (SensorNoise::excluded_because) what its readings show beside
/// what the baseline predicts there (its curve in `curves`, from the other sensors' row scales):
/// a sensor that read no wear where the map predicts some says so with both figures.
void AddExcludedEvidence(std::vector<SensorNoise>& sensors, const std::vector<SensorCurve>& curves);

/// What the mismatch test could have seen (NoiseFit::chi2_to_detect and the rest): from the z found,
/// the refit's degrees of freedom `dof` and the used sensors' noise. A static error at the sensors
/// costs the refit about (error / noise sd)^2 per sensor (its map-error term takes it up against
/// its prior), so the chi-square the threshold needs, spread over the sensors, gives the size.
void AddDetectionLimit(NoiseFit& fit, double mismatch_z, double dof, const std::vector<SensorNoise>& sensors);

/// Adds to each entry of the hypotheses table (`table[k]` is `h.evals[k]`): `verdict` ("chosen",
/// "accepted" or "rejected"), for a rejected one `rejected_because` (each failed test with its value
/// and what it needed, in words) and `failed_tests` ([{"test", "value", "needed"}]), for an accepted
/// one not chosen `not_chosen_because`. `log_n` is the BIC charge per parameter (NullModel::log_n).
void AnnotateHypotheses(nlohmann::ordered_json& table, const Hypotheses& h, double log_n);

}  // namespace lw::diagnosis::detail
