// AnalyseSensor()'s monotone envelope, level segments and robust wear rate (sensor_steps.hpp).
#include <algorithm>

#include "core/median.hpp"
#include "sensor_steps.hpp"

namespace lw::diagnosis::detail {
namespace {

// Merges flicker marks within a day of each other into one issue.
std::vector<QualityIssue> FlickerRuns(const std::vector<RawReading>& readings, const std::vector<bool>& flicker) {
  std::vector<QualityIssue> flicker_runs;
  for (size_t k = 0; k < readings.size(); ++k) {
    if (!flicker[k]) continue;
    if (!flicker_runs.empty() && readings[k].t_days - flicker_runs.back().to_days < 1.0) {
      flicker_runs.back().to_days = readings[k].t_days;
    } else {
      flicker_runs.push_back(
          {"flicker", readings[k].t_days, readings[k].t_days, "loop near the wear face alternating; monotone envelope kept"});
    }
  }
  return flicker_runs;
}

}  // namespace

Envelope MonotoneEnvelope(const std::vector<RawReading>& readings, std::vector<bool>& used) {
  const size_t n = readings.size();
  Envelope e;
  e.level.assign(n, 0.0);
  std::vector<bool> flicker(n, false);
  std::vector<bool> up(n, false);
  double env = 1e300;
  size_t i = 0;
  while (i < n) {
    if (!used[i]) {
      ++i;
      continue;
    }
    const double v = readings[i].value_mm;
    if (v <= env) {
      env = v;
      e.level[i] = env;
      ++i;
      continue;
    }
    // A block of consecutive used readings above the envelope.
    size_t j = i;
    std::vector<size_t> block;
    while (j < n && (!used[j] || readings[j].value_mm > env)) {
      if (used[j]) block.push_back(j);
      ++j;
    }
    const double span = readings[block.back()].t_days - readings[block.front()].t_days;
    for (size_t b : block) {
      const double excess = readings[b].value_mm - env;
      const bool long_block = span > 1.0 && block.size() >= 3;
      if (excess <= 1.0 && !long_block) {
        flicker[b] = true;
        e.level[b] = env;
      } else {
        up[b] = true;
        used[b] = false;
      }
    }
    i = j;
  }
  e.issues = FlickerRuns(readings, flicker);
  AddRuns(readings, up, "thickness_up", "thickness went up (a broken loop cannot heal); excluded", e.issues);
  return e;
}

std::vector<Segment> LevelSegments(const std::vector<RawReading>& readings, const std::vector<bool>& used,
                                   const std::vector<double>& envelope) {
  std::vector<Segment> segments;
  for (size_t i = 0; i < readings.size(); ++i) {
    if (!used[i]) continue;
    const double level = envelope[i];
    if (segments.empty() || segments.back().level != level) {
      segments.push_back({level, readings[i].t_days, readings[i].t_days, 0, {}});
    }
    segments.back().t_last = readings[i].t_days;
    segments.back().count += 1;
    segments.back().readings.push_back(i);
  }
  return segments;
}

double RobustRate(const std::vector<RawReading>& readings, const std::vector<Segment>& segments, double thickness_new_mm) {
  // Median of wear/time over the readings: robust to faults covering < half.
  double rate = 0;
  std::vector<double> rates;
  const double t_end = segments.back().t_last;
  for (const Segment& s : segments) {
    for (size_t idx : s.readings) {
      const double t = readings[idx].t_days;
      const double w = thickness_new_mm - s.level - 0.5;
      if (t >= std::max(0.5, 0.1 * t_end) && w >= 1.0) rates.push_back(w / t);
    }
  }
  if (!rates.empty()) {
    rate = core::UpperMedian(rates);
  } else if (t_end > 0) {
    rate = std::max(0.0, thickness_new_mm - segments.back().level - 0.5) / t_end;
  }
  return std::max(rate, 1e-3);
}

}  // namespace lw::diagnosis::detail
