#include "estimate/window.hpp"

#include <algorithm>
#include <cmath>

#include "core/forecast.hpp"
#include "core/time.hpp"
#include "estimate/model.hpp"

namespace lw::estimate {
namespace {

/// At the same time the thinner reading counts (wear only goes one way), then the lower seq: the
/// reading core::LatestReadingIndices picks from readings ordered by time and seq.
bool BetterAtSameTime(double thickness, int64_t seq, double best_thickness, int64_t best_seq) {
  return thickness < best_thickness || (thickness == best_thickness && seq < best_seq);
}

bool Later(const Point& a, const Point& b) {
  return a.time_s < b.time_s || (a.time_s == b.time_s && a.seq < b.seq);
}

/// `p` into `lows` (record lows by time: each new lowest whole-mm thickness when first read, the
/// thinnest reading of that time; core::StuckRule) wherever it falls in time: late readings too.
void AddLow(std::vector<Point>& lows, const Point& p) {
  auto it = std::lower_bound(lows.begin(), lows.end(), p.time_s, [](const Point& a, int64_t t) { return a.time_s < t; });
  if (it != lows.end() && it->time_s == p.time_s) {
    if (!BetterAtSameTime(p.thickness_mm, p.seq, it->thickness_mm, it->seq)) return;
    *it = p;
  } else {
    if (it != lows.begin() && !(std::floor(p.thickness_mm) < std::floor(std::prev(it)->thickness_mm))) return;
    it = lows.insert(it, p);
  }
  // The later lows that are not a loop below it are no longer record lows.
  const double loop = std::floor(p.thickness_mm);
  const auto end = std::find_if(it + 1, lows.end(), [&](const Point& a) { return std::floor(a.thickness_mm) < loop; });
  lows.erase(it + 1, end);
}

}  // namespace

bool IsFaultReading(int64_t flags, int64_t loops_intact) {
  constexpr int64_t kAllOpen = 1 << 3, kSpiStuck = 1 << 4;
  if (flags & kSpiStuck) return true;
  return (flags & kAllOpen) && loops_intact > 0;
}

bool UsableForWear(const core::CrusherConfig& crusher, const std::string& sensor, const Point& p) {
  return !IsFaultReading(p.flags, p.loops_intact) && crusher.OfThisLiner(sensor, core::FromUnixSeconds(p.time_s), p.thickness_mm);
}

ReadingWindow::ReadingWindow(const CrusherModel& model) : model_(&model) {}

int64_t ReadingWindow::WindowStart(int64_t last_s) const {
  const core::ForecastOptions o;  // the options Estimate()'s forecasts use
  const int64_t installed = core::ToUnixSeconds(model_->config.installed_at);
  const double t_last = static_cast<double>(last_s - installed) / 86400.0;
  const double window = std::max(o.window_min_days, o.window_fraction * std::max(0.0, t_last));
  // A day's margin: the forecast selects its own window from what it is given, so a superset is exact.
  return installed + static_cast<int64_t>(std::floor((t_last - window - 1.0) * 86400.0));
}

void ReadingWindow::AddToRun(SensorWindow& s, const Point& p, const std::optional<Point>& newest) {
  if (!s.lows.empty()) {  // by whole loops, as the rule reads them
    const double lowest = std::floor(s.lows.back().thickness_mm), loop = std::floor(p.thickness_mm);
    if (loop > lowest) {
      if (!s.above || p.time_s > s.above->time_s) s.above = p;
    } else if (loop < lowest) {
      s.above = newest;  // every earlier reading is above the new lowest: the newest of them
    }
  }
  AddLow(s.lows, p);
}

bool ReadingWindow::Add(const std::string& sensor, const Point& p) {
  if (!UsableForWear(model_->config, sensor, p)) return false;  // a fault, or a previous liner's (before a reline)
  const std::vector<ModelScan>& scans = model_->scans;
  SensorWindow& s = sensors_[sensor];
  if (s.anchor.size() != scans.size()) s.anchor.resize(scans.size());
  AddToRun(s, p, s.window.empty() ? std::nullopt : std::optional<Point>(s.window.back()));
  if (!last_usable_s_ || p.time_s > *last_usable_s_) last_usable_s_ = p.time_s;
  if (!s.last_usable_s || p.time_s > *s.last_usable_s) s.last_usable_s = p.time_s;
  const int64_t start = WindowStart(*s.last_usable_s);
  // At the end but for late readings.
  if (p.time_s >= start) s.window.insert(std::upper_bound(s.window.begin(), s.window.end(), p, Later), p);
  while (!s.window.empty() && s.window.front().time_s < start) s.window.pop_front();
  for (size_t k = 0; k < scans.size(); ++k) {
    if (p.time_s > core::ToUnixSeconds(scans[k].scan.date)) continue;
    std::optional<Point>& a = s.anchor[k];
    if (!a || p.time_s > a->time_s || (p.time_s == a->time_s && BetterAtSameTime(p.thickness_mm, p.seq, a->thickness_mm, a->seq)))
      a = p;
  }
  return true;
}

void ReadingWindow::Load(const std::string& sensor, int64_t to_s, const Walk& walk) {
  const core::CrusherConfig& config = model_->config;
  const std::vector<ModelScan>& scans = model_->scans;
  const int64_t liner_start = core::ToUnixSeconds(config.LinerStart());  // earlier readings: a previous liner's
  SensorWindow& s = sensors_[sensor];
  s.anchor.resize(scans.size());
  // Newest first, to the newest usable reading.
  walk(liner_start, to_s, true, [&](const Point& p) {
    if (!UsableForWear(config, sensor, p)) return true;
    s.last_usable_s = p.time_s;
    return false;
  });
  if (!s.last_usable_s) return;
  if (!last_usable_s_ || *s.last_usable_s > *last_usable_s_) last_usable_s_ = s.last_usable_s;
  const int64_t start = WindowStart(*s.last_usable_s);
  std::optional<Point> newest;
  walk(liner_start, to_s, false, [&](const Point& p) {
    if (!UsableForWear(config, sensor, p)) return true;
    if (p.time_s >= start) s.window.push_back(p);
    AddToRun(s, p, newest);
    newest = p;
    return true;
  });
  for (size_t k = 0; k < scans.size(); ++k) {
    std::optional<Point>& a = s.anchor[k];
    walk(liner_start, std::min(to_s, core::ToUnixSeconds(scans[k].scan.date)), true, [&](const Point& p) {
      if (a && p.time_s < a->time_s) return false;  // past the newest usable time at or before the scan
      if (!UsableForWear(config, sensor, p)) return true;
      if (!a || BetterAtSameTime(p.thickness_mm, p.seq, a->thickness_mm, a->seq)) a = p;
      return true;
    });
  }
}

void ReadingWindow::AppendSensor(const std::string& sensor, const SensorWindow& s, std::vector<Sample>* out) const {
  const size_t first = out->size();
  const auto emit = [&](const Point& p) {
    Sample r;
    static_cast<Point&>(r) = p;
    r.sensor = sensor;
    out->push_back(std::move(r));
  };
  for (const Point& p : s.window) emit(p);
  bool extra = false;
  const auto emit_extra = [&](const Point& p, size_t from) {
    if (std::any_of(out->begin() + static_cast<std::ptrdiff_t>(from), out->end(),
                    [&](const Sample& r) { return r.seq == p.seq; }))
      return;
    emit(p);
    extra = true;
  };
  for (const auto& a : s.anchor)
    if (a) emit_extra(*a, first);
  // The record lows and the newest reading above the lowest, before the window (the window holds
  // the others; only an anchor can be one of them).
  const size_t anchors_from = first + s.window.size();
  for (const Point& p : s.lows)
    if (s.window.empty() || p.time_s < s.window.front().time_s) emit_extra(p, anchors_from);
  if (s.above && (s.window.empty() || s.above->time_s < s.window.front().time_s)) emit_extra(*s.above, anchors_from);
  if (extra) std::sort(out->begin() + static_cast<std::ptrdiff_t>(first), out->end(), Later);
}

std::vector<Sample> ReadingWindow::Readings() const {
  std::vector<Sample> out;
  // Reserved at once: the copies are this function's cost, not the vector's growth.
  size_t total = 0;
  for (const auto& entry : sensors_)
    total += entry.second.window.size() + entry.second.anchor.size() + entry.second.lows.size() + 1;
  out.reserve(total);
  for (const auto& [sensor, s] : sensors_) AppendSensor(sensor, s, &out);
  return out;
}

}  // namespace lw::estimate
