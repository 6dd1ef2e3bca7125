// AnalyseSensor()'s fault detection (sensor_steps.hpp): dropouts, non-physical values, zeros and
// dead sensors, spikes. Faults are never physics.
#include <algorithm>
#include <cmath>

#include "core/median.hpp"
#include "core/reconstruction.hpp"
#include "sensor_steps.hpp"

namespace lw::diagnosis::detail {

std::vector<QualityIssue> Dropouts(const std::vector<RawReading>& readings) {
  const size_t n = readings.size();
  std::vector<QualityIssue> issues;
  std::vector<double> gaps;
  for (size_t i = 1; i < n; ++i) {
    const double g = readings[i].t_days - readings[i - 1].t_days;
    if (g > 0) gaps.push_back(g);
  }
  const double typical = core::UpperMedian(gaps);
  const core::Staleness rule;  // the live map's rule for a sensor too old to set a scale
  const double limit = std::max(rule.periods * typical, rule.min_days);
  for (size_t i = 1; i < n; ++i) {
    const double g = readings[i].t_days - readings[i - 1].t_days;
    if (!gaps.empty() && g > limit) {
      issues.push_back({"dropout", readings[i - 1].t_days, readings[i].t_days,
                        IssueFmt("no reading for %.1f days (usual period %.3f days)", g, typical)});
    }
  }
  return issues;
}

void MarkNonPhysical(const std::vector<RawReading>& readings, double top, FaultDetection& f) {
  const size_t n = readings.size();
  std::vector<bool> mark(n, false);
  for (size_t i = 0; i < n; ++i) {
    const double v = readings[i].value_mm;
    if (!std::isfinite(v) || v < 0 || v > top + 1.0) {
      mark[i] = true;
      f.used[i] = false;
    }
  }
  AddRuns(readings, mark, "non_physical", "reading negative or above the as-new thickness", f.issues);
}

void MarkZeros(const std::vector<RawReading>& readings, double top, FaultDetection& f) {
  const size_t n = readings.size();
  std::vector<bool> mark(n, false);
  double previous = top;
  for (size_t i = 0; i < n; ++i) {
    if (!f.used[i]) continue;
    const double v = readings[i].value_mm;
    if (v < 0.5 && previous >= 3.0) {
      mark[i] = true;
      f.used[i] = false;
    } else {
      previous = v;
    }
  }
  // A zero run with no valid reading after it is a dead sensor.
  size_t last_valid = n;
  for (size_t i = n; i-- > 0;) {
    if (f.used[i]) {
      last_valid = i;
      break;
    }
  }
  std::vector<bool> dead(n, false);
  for (size_t i = 0; i < n; ++i) {
    if (mark[i] && (last_valid == n || i > last_valid)) {
      dead[i] = true;
      mark[i] = false;
    }
  }
  AddRuns(readings, mark, "zero", "reads zero while the liner is far from worn through", f.issues);
  AddRuns(readings, dead, "dead", "reads zero from here on while the liner is far from worn through", f.issues);
}

void MarkSpikes(const std::vector<RawReading>& readings, FaultDetection& f) {
  const size_t n = readings.size();
  std::vector<bool> mark(n, false);
  std::vector<size_t> u;
  for (size_t i = 0; i < n; ++i)
    if (f.used[i]) u.push_back(i);
  for (size_t k = 1; k + 1 < u.size(); ++k) {
    const double prev = readings[u[k - 1]].value_mm;
    const double v = readings[u[k]].value_mm;
    for (size_t width = 1; width <= 2 && k + width < u.size(); ++width) {
      const double next = readings[u[k + width]].value_mm;
      if (std::fabs(prev - next) > 1.0) continue;
      bool all_off = true;
      for (size_t w = 0; w < width; ++w) {
        const double x = readings[u[k + w]].value_mm;
        if (std::fabs(x - prev) < 2.0 || std::fabs(x - next) < 2.0 || (x - prev) * (x - next) <= 0 || std::fabs(x - v) > 1.0)
          all_off = false;
      }
      if (all_off) {
        for (size_t w = 0; w < width; ++w) mark[u[k + w]] = true;
        break;
      }
    }
  }
  for (size_t i = 0; i < n; ++i)
    if (mark[i]) f.used[i] = false;
  AddRuns(readings, mark, "spike", "isolated reading away from both neighbours", f.issues);
}

FaultDetection DetectFaults(const std::vector<RawReading>& readings, double top) {
  FaultDetection f;
  f.used.assign(readings.size(), true);
  f.issues = Dropouts(readings);
  MarkNonPhysical(readings, top, f);
  MarkZeros(readings, top, f);
  MarkSpikes(readings, f);
  return f;
}

}  // namespace lw::diagnosis::detail
