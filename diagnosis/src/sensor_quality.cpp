// AnalyseSensor(): the steps of sensor_steps.hpp in order, and their shared helpers.
#include "sensor_quality.hpp"

#include <algorithm>
#include <cmath>
#include <cstdarg>

#include "sensor_steps.hpp"
#include "text_format.hpp"

namespace lw::diagnosis::detail {

std::string IssueFmt(const char* format, ...) {
  va_list args;
  va_start(args, format);
  std::string s = VFormat(159, format, args);
  va_end(args);
  return s;
}

void AddRuns(const std::vector<RawReading>& readings, const std::vector<bool>& mark, const std::string& issue,
             const std::string& detail, std::vector<QualityIssue>& issues) {
  size_t i = 0;
  while (i < mark.size()) {
    if (!mark[i]) {
      ++i;
      continue;
    }
    size_t j = i;
    while (j + 1 < mark.size() && mark[j + 1]) ++j;
    issues.push_back({issue, readings[i].t_days, readings[j].t_days, detail});
    i = j + 1;
  }
}

std::vector<RawReading> SortReadings(std::vector<RawReading> readings) {
  std::stable_sort(readings.begin(), readings.end(),
                   [](const RawReading& x, const RawReading& y) { return x.t_days < y.t_days; });
  readings.erase(
      std::unique(readings.begin(), readings.end(),
                  [](const RawReading& x, const RawReading& y) { return x.t_days == y.t_days && x.value_mm == y.value_mm; }),
      readings.end());
  return readings;
}

SensorAnalysis AnalyseSensor(std::vector<RawReading> readings_in, double thickness_new_mm) {
  SensorAnalysis a;
  a.readings = SortReadings(std::move(readings_in));
  const std::vector<RawReading>& readings = a.readings;
  const size_t n = readings.size();
  a.used.assign(n, true);
  if (n == 0) return a;
  const double top = std::floor(thickness_new_mm + 1e-6);

  FaultDetection faults = DetectFaults(readings, top);
  a.used = std::move(faults.used);
  a.issues = std::move(faults.issues);
  const Envelope envelope = MonotoneEnvelope(readings, a.used);
  a.issues.insert(a.issues.end(), envelope.issues.begin(), envelope.issues.end());

  std::vector<Segment> segments = LevelSegments(readings, a.used, envelope.level);
  if (segments.empty()) return a;
  a.rate_mm_per_day = RobustRate(readings, segments, thickness_new_mm);
  const double rho = a.rate_mm_per_day;
  segments = FoldBriefLevels(segments, rho);
  StepAnalysis steps = ClassifySteps(segments, rho, a.used);
  a.issues.insert(a.issues.end(), steps.issues.begin(), steps.issues.end());
  a.losses = std::move(steps.losses);
  a.events = CrossingEvents(segments, steps, top, thickness_new_mm);

  for (size_t i = n; i-- > 0;) {
    if (a.used[i]) {
      a.last_time_days = readings[i].t_days;
      a.last_thickness_mm = envelope.level[i];
      break;
    }
  }
  std::sort(a.issues.begin(), a.issues.end(),
            [](const QualityIssue& x, const QualityIssue& y) { return x.from_days < y.from_days; });
  return a;
}

}  // namespace lw::diagnosis::detail
