#include "sensor_quality.hpp"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>

namespace lw::diagnosis::detail {
namespace {

struct Segment {
  double level = 0;
  double t_first = 0;
  double t_last = 0;
  size_t count = 0;
  std::vector<size_t> readings;  // indices into the reading list
};

enum class Transition { kNormal, kDropped, kLoss };

__attribute__((format(printf, 1, 2))) std::string Fmt(const char* format, ...) {
  char buffer[160];
  va_list args;
  va_start(args, format);
  std::vsnprintf(buffer, sizeof buffer, format, args);
  va_end(args);
  return buffer;
}

// Groups marked readings into runs (consecutive in time order) and reports each run.
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

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  return v[mid];
}

}  // namespace

SensorAnalysis AnalyseSensor(std::vector<RawReading> readings, double thickness_new_mm) {
  SensorAnalysis a;
  std::stable_sort(readings.begin(), readings.end(),
                   [](const RawReading& x, const RawReading& y) { return x.t_days < y.t_days; });
  readings.erase(
      std::unique(readings.begin(), readings.end(),
                  [](const RawReading& x, const RawReading& y) { return x.t_days == y.t_days && x.value_mm == y.value_mm; }),
      readings.end());
  a.readings = readings;
  const size_t n = readings.size();
  a.used.assign(n, true);
  if (n == 0) return a;
  const double top = std::floor(thickness_new_mm + 1e-6);

  // Dropouts: gaps much longer than the usual reporting period (reported, nothing excluded).
  {
    std::vector<double> gaps;
    for (size_t i = 1; i < n; ++i) {
      const double g = readings[i].t_days - readings[i - 1].t_days;
      if (g > 0) gaps.push_back(g);
    }
    const double typical = Median(gaps);
    const double limit = std::max(8.0 * typical, 1.0);
    for (size_t i = 1; i < n; ++i) {
      const double g = readings[i].t_days - readings[i - 1].t_days;
      if (!gaps.empty() && g > limit) {
        a.issues.push_back({"dropout", readings[i - 1].t_days, readings[i].t_days,
                            Fmt("no reading for %.1f days (usual period %.3f days)", g, typical)});
      }
    }
  }

  // Non-physical values: negative, not finite, or thicker than new.
  std::vector<bool> mark(n, false);
  for (size_t i = 0; i < n; ++i) {
    const double v = readings[i].value_mm;
    if (!std::isfinite(v) || v < 0 || v > top + 1.0) {
      mark[i] = true;
      a.used[i] = false;
    }
  }
  AddRuns(readings, mark, "non_physical", "reading negative or above the as-new thickness", a.issues);

  // Zero while the sensor was far from worn out: a dead or shorted ladder, not wear.
  {
    std::fill(mark.begin(), mark.end(), false);
    double previous = top;
    for (size_t i = 0; i < n; ++i) {
      if (!a.used[i]) continue;
      const double v = readings[i].value_mm;
      if (v < 0.5 && previous >= 3.0) {
        mark[i] = true;
        a.used[i] = false;
      } else {
        previous = v;
      }
    }
    // A zero run with no valid reading after it is a dead sensor.
    size_t last_valid = n;
    for (size_t i = n; i-- > 0;) {
      if (a.used[i]) {
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
    AddRuns(readings, mark, "zero", "reads zero while the liner is far from worn through", a.issues);
    AddRuns(readings, dead, "dead", "reads zero from here on while the liner is far from worn through", a.issues);
  }

  // Spikes: one or two readings away from both neighbours, which agree with each other.
  {
    std::fill(mark.begin(), mark.end(), false);
    std::vector<size_t> u;
    for (size_t i = 0; i < n; ++i)
      if (a.used[i]) u.push_back(i);
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
      if (mark[i]) a.used[i] = false;
    AddRuns(readings, mark, "spike", "isolated reading away from both neighbours", a.issues);
  }

  // Monotone envelope: wear is irreversible. One above the envelope is a flickering loop near the
  // wear face (kept at the envelope); more, or one for a long time, is thickness going up (a fault).
  std::vector<double> envelope(n, 0.0);
  {
    std::vector<bool> flicker(n, false);
    std::vector<bool> up(n, false);
    double env = 1e300;
    size_t i = 0;
    while (i < n) {
      if (!a.used[i]) {
        ++i;
        continue;
      }
      const double v = readings[i].value_mm;
      if (v <= env) {
        env = v;
        envelope[i] = env;
        ++i;
        continue;
      }
      // A block of consecutive used readings above the envelope.
      size_t j = i;
      std::vector<size_t> block;
      while (j < n && (!a.used[j] || readings[j].value_mm > env)) {
        if (a.used[j]) block.push_back(j);
        ++j;
      }
      const double span = readings[block.back()].t_days - readings[block.front()].t_days;
      for (size_t b : block) {
        const double excess = readings[b].value_mm - env;
        const bool long_block = span > 1.0 && block.size() >= 3;
        if (excess <= 1.0 && !long_block) {
          flicker[b] = true;
          envelope[b] = env;
        } else {
          up[b] = true;
          a.used[b] = false;
        }
      }
      i = j;
    }
    // Merge flicker marks within a day of each other into one issue.
    std::vector<QualityIssue> flicker_runs;
    for (size_t k = 0; k < n; ++k) {
      if (!flicker[k]) continue;
      if (!flicker_runs.empty() && readings[k].t_days - flicker_runs.back().to_days < 1.0) {
        flicker_runs.back().to_days = readings[k].t_days;
      } else {
        flicker_runs.push_back(
            {"flicker", readings[k].t_days, readings[k].t_days, "loop near the wear face alternating; monotone envelope kept"});
      }
    }
    a.issues.insert(a.issues.end(), flicker_runs.begin(), flicker_runs.end());
    AddRuns(readings, up, "thickness_up", "thickness went up (a broken loop cannot heal); excluded", a.issues);
  }

  // Segments of constant envelope level.
  std::vector<Segment> segments;
  for (size_t i = 0; i < n; ++i) {
    if (!a.used[i]) continue;
    const double level = envelope[i];
    if (segments.empty() || segments.back().level != level) {
      segments.push_back({level, readings[i].t_days, readings[i].t_days, 0, {}});
    }
    segments.back().t_last = readings[i].t_days;
    segments.back().count += 1;
    segments.back().readings.push_back(i);
  }
  if (segments.empty()) return a;

  // Robust mean rate: median of wear/time over the readings (robust to faults covering < half).
  {
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
      a.rate_mm_per_day = Median(rates);
    } else if (t_end > 0) {
      a.rate_mm_per_day = std::max(0.0, thickness_new_mm - segments.back().level - 0.5) / t_end;
    }
    a.rate_mm_per_day = std::max(a.rate_mm_per_day, 1e-3);
  }
  const double rho = a.rate_mm_per_day;

  // A step spread over a few polls (loops breaking one after another as a piece breaks out: 93, 92,
  // 91, 90, 89 within an hour) leaves brief intermediate levels: fold a run of them into one step
  // when the levels on either side are far further apart than the rate allows in the time between.
  {
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
    segments = std::move(folded);
  }

  // Steps: a level change much faster than the rate allows. Stuck (flat before, then catches up),
  // crack (premature step, then flat until the wear catches up) or material loss (step, then wear
  // continues at the normal rate from the lower level).
  const size_t m = segments.size();
  std::vector<Transition> transition(m, Transition::kNormal);  // transition[s]: from s to s + 1
  std::vector<double> loss_depth(m, 0.0);
  std::vector<bool> classified(m, false);
  auto exclude_segment = [&](const Segment& s, bool keep_first) {
    for (size_t k = keep_first ? 1 : 0; k < s.readings.size(); ++k) a.used[s.readings[k]] = false;
  };
  for (size_t s = 0; s + 1 < m; ++s) {
    const double delta = segments[s].level - segments[s + 1].level;
    const double gap = segments[s + 1].t_first - segments[s].t_last;
    const double expected = rho * gap;
    if (!(delta >= 3.0 && delta - expected >= 2.5 && delta >= 2.0 * expected)) continue;
    const double expected_before = rho * (segments[s].t_last - segments[s].t_first);
    const double expected_after = rho * (segments[s + 1].t_last - segments[s + 1].t_first);
    const bool last_after = (s + 1 == m - 1);
    if (!classified[s] && segments[s].count >= 3 && expected_before >= std::max(2.5, 0.5 * delta)) {
      a.issues.push_back({"stuck", segments[s].t_first, segments[s].t_last,
                          Fmt("no change for %.1f days while ~%.1f mm of wear was expected; then jumped",
                              segments[s].t_last - segments[s].t_first, expected_before)});
      exclude_segment(segments[s], true);
      classified[s] = true;
      transition[s] = Transition::kDropped;
    } else if (expected_after >= std::max(1.5, 0.5 * delta)) {
      a.issues.push_back({"crack", segments[s + 1].t_first, segments[s + 1].t_last,
                          Fmt("premature %.0f mm step, then flat for %.1f days until wear caught up", delta,
                              segments[s + 1].t_last - segments[s + 1].t_first)});
      exclude_segment(segments[s + 1], false);
      classified[s + 1] = true;
      transition[s] = Transition::kDropped;
    } else if (!last_after) {
      transition[s] = Transition::kLoss;
      loss_depth[s] = std::max(0.0, delta - expected);
      a.losses.push_back({0.5 * (segments[s].t_last + segments[s + 1].t_first), loss_depth[s], delta});
    } else {
      a.issues.push_back({"premature_step", segments[s + 1].t_first, segments[s + 1].t_last,
                          Fmt("%.0f mm step at the end of the record, not confirmed by later readings", delta)});
      exclude_segment(segments[s + 1], false);
      classified[s + 1] = true;
      transition[s] = Transition::kDropped;
    }
  }
  // Stuck until the end: flat for long while the rate says several mm should have gone.
  {
    const Segment& last = segments.back();
    if (!classified[m - 1] && last.count >= 3 && last.level > 1.5 && rho * (last.t_last - last.t_first) >= 4.0) {
      a.issues.push_back({"stuck", last.t_first, last.t_last,
                          Fmt("no change for %.1f days while ~%.1f mm of wear was expected", last.t_last - last.t_first,
                              rho * (last.t_last - last.t_first))});
      exclude_segment(last, true);
    }
  }

  // Crossing events.
  auto add_crossings = [&](double level_from, double level_to, double t1, double t2, double offset) {
    const double levels = level_from - level_to;
    if (levels < 1 || t2 < t1) return;
    const int count = static_cast<int>(std::lround(levels));
    for (int j = 0; j < count; ++j) {
      const double level = level_from - j;
      const double wear = thickness_new_mm - level;
      if (wear <= 1e-9) continue;
      const double t = t1 + (j + 0.5) / count * (t2 - t1);
      a.events.push_back({t, wear, (t2 - t1) / (count * std::sqrt(12.0)), offset});
    }
  };
  double offset = 0;
  if (segments[0].level < top && !classified[0]) add_crossings(top, segments[0].level, 0.0, segments[0].t_first, 0.0);
  for (size_t s = 0; s + 1 < m; ++s) {
    if (transition[s] == Transition::kLoss) {
      offset += loss_depth[s];
      continue;
    }
    if (transition[s] == Transition::kDropped) continue;
    add_crossings(segments[s].level, segments[s + 1].level, segments[s].t_last, segments[s + 1].t_first, offset);
  }
  for (size_t i = n; i-- > 0;) {
    if (a.used[i]) {
      a.last_time_days = readings[i].t_days;
      a.last_thickness_mm = envelope[i];
      break;
    }
  }
  std::sort(a.issues.begin(), a.issues.end(),
            [](const QualityIssue& x, const QualityIssue& y) { return x.from_days < y.from_days; });
  return a;
}

}  // namespace lw::diagnosis::detail
