#pragma once
/// Per-sensor data quality: finds faults (never physics), cleans the series and turns it into
/// loop-crossing events, the sensor's exact observations of wear.
#include <optional>
#include <string>
#include <vector>

namespace lw::diagnosis::detail {

struct RawReading {
  double t_days = 0;
  double value_mm = 0;
};

/// "The surface passed loop level L at about t": wear = thickness_new - L exactly (1 mm ladder),
/// time uncertain within the reporting interval that saw the change.
struct CrossingEvent {
  double t_days = 0;
  double wear_mm = 0;
  double sigma_t_days = 0;
  double offset_mm = 0;  ///< material lost before this event (subtracted from wear for the wear model)
};

struct QualityIssue {
  std::string issue;
  double from_days = 0;
  double to_days = 0;
  std::string detail;
};

/// A sudden, permanent loss of material at the sensor (spall), after which wear continues at the
/// normal rate from the lower level: a physics finding, not a fault.
struct LossEvent {
  double t_days = 0;
  double depth_mm = 0;
  double step_mm = 0;
};

struct SensorAnalysis {
  std::vector<RawReading> readings;  ///< sorted by time
  std::vector<bool> used;            ///< per reading: false when excluded as a fault
  std::vector<CrossingEvent> events;
  std::vector<QualityIssue> issues;
  std::vector<LossEvent> losses;
  double rate_mm_per_day = 0;  ///< robust mean wear rate
  double last_time_days = 0;
  double last_thickness_mm = 0;  ///< envelope value at the last used reading
};

/// Analyses one sensor's readings (any order). `thickness_new_mm` is the as-new reading.
SensorAnalysis AnalyseSensor(std::vector<RawReading> readings, double thickness_new_mm);

}  // namespace lw::diagnosis::detail
