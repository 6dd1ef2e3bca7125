#pragma once
/// The steps of AnalyseSensor() (sensor_quality.hpp), each with its typed result: fault detection,
/// the monotone envelope, level segments and the robust wear rate, steps (stuck, crack, material
/// loss) and loop-crossing events.
#include <string>
#include <vector>

#include "sensor_quality.hpp"

namespace lw::diagnosis::detail {

/// printf into a std::string of at most 159 characters (the data-quality details).
__attribute__((format(printf, 1, 2))) std::string IssueFmt(const char* format, ...);
/// Reports each run of consecutive marked readings as one issue.
void AddRuns(const std::vector<RawReading>& readings, const std::vector<bool>& mark, const std::string& issue,
             const std::string& detail, std::vector<QualityIssue>& issues);

/// Readings sorted by time (stable), exact duplicates dropped.
std::vector<RawReading> SortReadings(std::vector<RawReading> readings);

// --- Fault detection (sensor_faults.cpp) ---------------------------------------------------------
struct FaultDetection {
  std::vector<bool> used;            ///< per reading: false when excluded as a fault
  std::vector<QualityIssue> issues;  ///< dropout, non_physical, zero, dead, spike (in that order)
};
/// Gaps much longer than the usual reporting period (nothing excluded).
std::vector<QualityIssue> Dropouts(const std::vector<RawReading>& readings);
/// Negative, not finite, or above the as-new ladder top + 1: excluded.
void MarkNonPhysical(const std::vector<RawReading>& readings, double top, FaultDetection& f);
/// Zero while far from worn out: "zero" runs, or "dead" when no valid reading follows. Excluded.
void MarkZeros(const std::vector<RawReading>& readings, double top, FaultDetection& f);
/// One or two readings away from both (agreeing) neighbours. Excluded.
void MarkSpikes(const std::vector<RawReading>& readings, FaultDetection& f);
/// All of the above; `top` is the as-new reading (floored thickness).
FaultDetection DetectFaults(const std::vector<RawReading>& readings, double top);

// --- Envelope and segments (sensor_envelope.cpp) ---------------------------------------------------
struct Envelope {
  std::vector<double> level;         ///< per reading: the monotone envelope (0 where not used)
  std::vector<QualityIssue> issues;  ///< flicker, thickness_up
};
/// Wear is irreversible: a reading above the envelope is a flickering loop (kept at the envelope)
/// when alone and small, else thickness going up (excluded from `used`).
Envelope MonotoneEnvelope(const std::vector<RawReading>& readings, std::vector<bool>& used);

struct Segment {
  double level = 0;
  double t_first = 0;
  double t_last = 0;
  size_t count = 0;
  std::vector<size_t> readings;  ///< indices into the reading list
};
/// Runs of used readings at one envelope level.
std::vector<Segment> LevelSegments(const std::vector<RawReading>& readings, const std::vector<bool>& used,
                                   const std::vector<double>& envelope);
/// Robust mean wear rate (mm/day, at least 1e-3): median of wear/time over the readings.
double RobustRate(const std::vector<RawReading>& readings, const std::vector<Segment>& segments, double thickness_new_mm);

// --- Steps and events (sensor_steps.cpp) -----------------------------------------------------------
/// Folds runs of brief intermediate levels (a step spread over a few polls) into the step.
std::vector<Segment> FoldBriefLevels(const std::vector<Segment>& segments, double rho);

enum class Transition { kNormal, kDropped, kLoss };

struct StepAnalysis {
  std::vector<Transition> transition;  ///< transition[s]: from segment s to s + 1
  std::vector<double> loss_depth;      ///< per transition: material lost (kLoss)
  std::vector<bool> classified;        ///< per segment: excluded as stuck/crack/premature
  std::vector<QualityIssue> issues;    ///< stuck, crack, premature_step (in segment order)
  std::vector<LossEvent> losses;
};
/// Level changes much faster than `rho` allows: stuck, crack, material loss or premature step;
/// then a segment stuck until the end. Excluded readings are cleared in `used`.
StepAnalysis ClassifySteps(const std::vector<Segment>& segments, double rho, std::vector<bool>& used);

/// Loop-crossing events between segments (spread evenly over the gap), with material lost before.
std::vector<CrossingEvent> CrossingEvents(const std::vector<Segment>& segments, const StepAnalysis& steps, double top,
                                          double thickness_new_mm);

}  // namespace lw::diagnosis::detail
