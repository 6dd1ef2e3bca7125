// AnalyseSensor()'s steps (stuck, crack, material loss, premature step) and loop-crossing events
// (sensor_steps.hpp).
#include "sensor_steps.hpp"

#include <algorithm>
#include <cmath>

namespace lw::diagnosis::detail {
namespace {

void ExcludeSegment(const Segment& s, bool keep_first, std::vector<bool>& used) {
  for (size_t k = keep_first ? 1 : 0; k < s.readings.size(); ++k) used[s.readings[k]] = false;
}

// Classifies the step from segment s to s + 1 (already known to be much faster than the rate).
void ClassifyStep(const std::vector<Segment>& segments, size_t s, double rho, std::vector<bool>& used, StepAnalysis& a) {
  const size_t m = segments.size();
  const double delta = segments[s].level - segments[s + 1].level;
  const double gap = segments[s + 1].t_first - segments[s].t_last;
  const double expected = rho * gap;
  const double expected_before = rho * (segments[s].t_last - segments[s].t_first);
  const double expected_after = rho * (segments[s + 1].t_last - segments[s + 1].t_first);
  const bool last_after = (s + 1 == m - 1);
  if (!a.classified[s] && segments[s].count >= 3 && expected_before >= std::max(2.5, 0.5 * delta)) {
    a.issues.push_back({"stuck", segments[s].t_first, segments[s].t_last,
                        IssueFmt("no change for %.1f days while ~%.1f mm of wear was expected; then jumped",
                                 segments[s].t_last - segments[s].t_first, expected_before)});
    ExcludeSegment(segments[s], true, used);
    a.classified[s] = true;
    a.transition[s] = Transition::kDropped;
  } else if (expected_after >= std::max(1.5, 0.5 * delta)) {
    a.issues.push_back({"crack", segments[s + 1].t_first, segments[s + 1].t_last,
                        IssueFmt("premature %.0f mm step, then flat for %.1f days until wear caught up", delta,
                                 segments[s + 1].t_last - segments[s + 1].t_first)});
    ExcludeSegment(segments[s + 1], false, used);
    a.classified[s + 1] = true;
    a.transition[s] = Transition::kDropped;
  } else if (!last_after) {
    a.transition[s] = Transition::kLoss;
    a.loss_depth[s] = std::max(0.0, delta - expected);
    a.losses.push_back({0.5 * (segments[s].t_last + segments[s + 1].t_first), a.loss_depth[s], delta});
  } else {
    a.issues.push_back({"premature_step", segments[s + 1].t_first, segments[s + 1].t_last,
                        IssueFmt("%.0f mm step at the end of the record, not confirmed by later readings", delta)});
    ExcludeSegment(segments[s + 1], false, used);
    a.classified[s + 1] = true;
    a.transition[s] = Transition::kDropped;
  }
}

}  // namespace

std::vector<Segment> FoldBriefLevels(const std::vector<Segment>& segments, double rho) {
  // A step spread over a few polls (loops breaking one after another as a piece breaks out: 93, 92,
  // 91, 90, 89 within an hour) leaves brief intermediate levels: fold a run of them into one step
  // when the levels on either side are far further apart than the rate allows in the time between.
  auto brief = [&](const Segment& g) { return g.count <= 2 && rho * (g.t_last - g.t_first) < 0.5; };
  std::vector<Segment> folded;
  size_t k = 0;
  while (k < segments.size()) {
    folded.push_back(segments[k]);
    size_t j = k + 1;
    while (j + 1 < segments.size() && brief(segments[j])) ++j;  // segments k+1 .. j-1 are brief
    if (j > k + 1 && j < segments.size()) {
      const double delta = segments[k].level - segments[j].level;
      const double gap = segments[j].t_first - segments[k].t_last;
      if (delta >= 3.0 && delta - rho * gap >= 2.5) {
        k = j;  // the brief levels in between are part of the step
        continue;
      }
    }
    ++k;
  }
  return folded;
}

StepAnalysis ClassifySteps(const std::vector<Segment>& segments, double rho, std::vector<bool>& used) {
  // Steps: a level change much faster than the rate allows. Stuck (flat before, then catches up),
  // crack (premature step, then flat until the wear catches up) or material loss (step, then wear
  // continues at the normal rate from the lower level).
  const size_t m = segments.size();
  StepAnalysis a;
  a.transition.assign(m, Transition::kNormal);
  a.loss_depth.assign(m, 0.0);
  a.classified.assign(m, false);
  for (size_t s = 0; s + 1 < m; ++s) {
    const double delta = segments[s].level - segments[s + 1].level;
    const double gap = segments[s + 1].t_first - segments[s].t_last;
    const double expected = rho * gap;
    if (!(delta >= 3.0 && delta - expected >= 2.5 && delta >= 2.0 * expected)) continue;
    ClassifyStep(segments, s, rho, used, a);
  }
  // Stuck until the end: flat for long while the rate says several mm should have gone.
  const Segment& last = segments.back();
  if (!a.classified[m - 1] && last.count >= 3 && last.level > 1.5 && rho * (last.t_last - last.t_first) >= 4.0) {
    a.issues.push_back({"stuck", last.t_first, last.t_last,
                        IssueFmt("no change for %.1f days while ~%.1f mm of wear was expected", last.t_last - last.t_first,
                                 rho * (last.t_last - last.t_first))});
    ExcludeSegment(last, true, used);
  }
  return a;
}

std::vector<CrossingEvent> CrossingEvents(const std::vector<Segment>& segments, const StepAnalysis& steps, double top,
                                          double thickness_new_mm) {
  std::vector<CrossingEvent> events;
  auto add_crossings = [&](double level_from, double level_to, double t1, double t2, double offset) {
    const double levels = level_from - level_to;
    if (levels < 1 || t2 < t1) return;
    const int count = static_cast<int>(std::lround(levels));
    for (int j = 0; j < count; ++j) {
      const double level = level_from - j;
      const double wear = thickness_new_mm - level;
      if (wear <= 1e-9) continue;
      const double t = t1 + (j + 0.5) / count * (t2 - t1);
      events.push_back({t, wear, (t2 - t1) / (count * std::sqrt(12.0)), offset});
    }
  };
  const size_t m = segments.size();
  double offset = 0;
  if (segments[0].level < top && !steps.classified[0]) add_crossings(top, segments[0].level, 0.0, segments[0].t_first, 0.0);
  for (size_t s = 0; s + 1 < m; ++s) {
    if (steps.transition[s] == Transition::kLoss) {
      offset += steps.loss_depth[s];
      continue;
    }
    if (steps.transition[s] == Transition::kDropped) continue;
    add_crossings(segments[s].level, segments[s + 1].level, segments[s].t_last, segments[s + 1].t_first, offset);
  }
  return events;
}

}  // namespace lw::diagnosis::detail
