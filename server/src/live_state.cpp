#include "server/live_state.hpp"

#include <algorithm>
#include <climits>
#include <cmath>

#include "core/forecast.hpp"
#include "core/time.hpp"
#include "server/ingest.hpp"

namespace lw::server {
namespace {

int64_t Unix(core::TimePoint t) {
  return t.time_since_epoch().count();
}

/// At the same time the thinner reading counts (wear only goes one way), then the lower seq: the
/// reading core::LatestReadingIndices picks from readings ordered by time and seq.
bool BetterAtSameTime(double thickness, int64_t seq, double best_thickness, int64_t best_seq) {
  return thickness < best_thickness || (thickness == best_thickness && seq < best_seq);
}

/// `p` into `lows` (record lows by time: each new lowest whole-mm thickness when first read, the
/// thinnest reading of that time; core::StuckRule) wherever it falls in time: late readings too.
template <typename P>
void AddLow(std::vector<P>& lows, const P& p) {
  auto it = std::lower_bound(lows.begin(), lows.end(), p.time_s, [](const P& a, int64_t t) { return a.time_s < t; });
  if (it != lows.end() && it->time_s == p.time_s) {
    if (!BetterAtSameTime(p.thickness_mm, p.seq, it->thickness_mm, it->seq)) return;
    *it = p;
  } else {
    if (it != lows.begin() && !(std::floor(p.thickness_mm) < std::floor(std::prev(it)->thickness_mm))) return;
    it = lows.insert(it, p);
  }
  // The later lows that are not a loop below it are no longer record lows.
  const double loop = std::floor(p.thickness_mm);
  const auto end = std::find_if(it + 1, lows.end(), [&](const P& a) { return std::floor(a.thickness_mm) < loop; });
  lows.erase(it + 1, end);
}

}  // namespace

LiveState::LiveState(const Registry& registry) : registry_(registry) {
  for (const Crusher* c : registry_.All()) {
    CrusherLive& live = crushers_[c->config.crusher_id];
    live.crusher = c;
    live.loaded = true;  // an empty database, until Rebuild() or LoadLazily()
  }
}

const LiveState::CrusherLive* LiveState::Find(const std::string& crusher) const {
  const auto it = crushers_.find(crusher);
  if (it == crushers_.end()) return nullptr;
  CrusherLive& c = it->second;
  {
    std::lock_guard<std::mutex> lock(c.mutex);
    if (c.loaded) return &c;
  }
  // First use: load it, with commits held off (CommitGuard) so that none is both read and added.
  std::lock_guard<std::mutex> order(order_);
  {
    std::lock_guard<std::mutex> lock(c.mutex);
    if (c.loaded) return &c;  // loaded by another thread meanwhile
  }
  CrusherLive fresh;
  if (loader_) LoadFrom(*loader_, *c.crusher, fresh);
  std::lock_guard<std::mutex> lock(c.mutex);
  c.sensors = std::move(fresh.sensors);
  c.last_usable_s = fresh.last_usable_s;
  c.loaded = true;
  return &c;
}

void LiveState::LoadLazily(std::unique_ptr<Store> store) {
  std::lock_guard<std::mutex> order(order_);
  loader_ = std::move(store);
  for (auto& [id, c] : crushers_) {
    std::lock_guard<std::mutex> lock(c.mutex);
    c.loaded = false;
    c.sensors.clear();
    c.last_usable_s.reset();
  }
}

int64_t LiveState::WindowStart(const Crusher& c, int64_t last_s) const {
  const core::ForecastOptions o;  // the options ComputeCrusherState's forecasts use
  const int64_t installed = Unix(c.config.installed_at);
  const double t_last = static_cast<double>(last_s - installed) / 86400.0;
  const double window = std::max(o.window_min_days, o.window_fraction * std::max(0.0, t_last));
  // A day's margin: the forecast selects its own window from what it is given, so a superset is exact.
  return installed + static_cast<int64_t>(std::floor((t_last - window - 1.0) * 86400.0));
}

void LiveState::AddToRun(SensorState& s, const Point& p, const std::optional<Point>& newest) {
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

void LiveState::AddLocked(CrusherLive& c, const StoredReading& r) {
  SensorState& s = c.sensors[r.sensor];
  if (s.anchor.size() != c.crusher->scans.size()) s.anchor.resize(c.crusher->scans.size());
  ++s.count;
  if (!s.latest || r.time_s > s.latest->time_s || (r.time_s == s.latest->time_s && r.seq > s.latest->seq)) {
    // Without its payload (not kept here): not copied only to be cleared.
    s.latest = StoredReading{r.crusher,      r.sensor, r.seq,        r.time_s,     r.thickness_mm,
                             r.loops_intact, r.flags,  r.battery_mv, r.received_s, {}};
  }
  if (!UsableForWear(c.crusher->config, r)) return;  // a fault, or a previous liner's (before a reline)
  const Point p{r.time_s, r.seq, r.thickness_mm, r.loops_intact, r.flags};
  AddToRun(s, p, s.window.empty() ? std::nullopt : std::optional<Point>(s.window.back()));
  if (!c.last_usable_s || r.time_s > *c.last_usable_s) c.last_usable_s = r.time_s;
  if (!s.last_usable_s || r.time_s > *s.last_usable_s) s.last_usable_s = r.time_s;
  const int64_t start = WindowStart(*c.crusher, *s.last_usable_s);
  if (r.time_s >= start) {
    const auto later = [](const Point& a, const Point& b) {
      return a.time_s < b.time_s || (a.time_s == b.time_s && a.seq < b.seq);
    };
    s.window.insert(std::upper_bound(s.window.begin(), s.window.end(), p, later), p);  // at the end but for late readings
  }
  while (!s.window.empty() && s.window.front().time_s < start) s.window.pop_front();
  for (size_t k = 0; k < c.crusher->scans.size(); ++k) {
    if (r.time_s > Unix(c.crusher->scans[k].scan.date)) continue;
    std::optional<Point>& a = s.anchor[k];
    if (!a || r.time_s > a->time_s || (r.time_s == a->time_s && BetterAtSameTime(p.thickness_mm, p.seq, a->thickness_mm, a->seq)))
      a = p;
  }
}

void LiveState::Add(const std::vector<StoredReading>& committed) {
  CrusherLive* c = nullptr;
  std::unique_lock<std::mutex> lock;
  for (const StoredReading& r : committed) {
    if (!c || r.crusher != c->crusher->config.crusher_id) {  // batches come mostly crusher by crusher
      const auto it = crushers_.find(r.crusher);
      if (it == crushers_.end()) continue;
      c = &it->second;
      lock = std::unique_lock<std::mutex>(c->mutex);
    }
    if (c->loaded) AddLocked(*c, r);
  }
}

void LiveState::Rebuild(Store& store) {
  std::lock_guard<std::mutex> order(order_);
  for (auto& [id, live] : crushers_) {
    CrusherLive c;  // loaded here, then swapped in
    LoadFrom(store, *live.crusher, c);
    std::lock_guard<std::mutex> lock(live.mutex);
    live.sensors = std::move(c.sensors);
    live.last_usable_s = c.last_usable_s;
    live.loaded = true;
  }
}

void LiveState::LoadFrom(Store& store, const Crusher& c_crusher, CrusherLive& c) const {
  {
    const Crusher* crusher = &c_crusher;
    const std::string& id = crusher->config.crusher_id;
    const int64_t liner_start = Unix(crusher->config.LinerStart());  // earlier readings: a previous liner's
    for (const std::string& sensor : store.SensorsOf(id)) {
      SensorState& s = c.sensors[sensor];
      s.anchor.resize(crusher->scans.size());
      s.count = store.CountReadings(id, sensor);
      s.latest = store.Latest(id, sensor);
      // Newest first, to the newest usable reading.
      store.Walk(id, sensor, liner_start, INT64_MAX, true, [&](const StoredReading& r) {
        if (!UsableForWear(crusher->config, r)) return true;
        s.last_usable_s = r.time_s;
        return false;
      });
      if (!s.last_usable_s) continue;
      if (!c.last_usable_s || *s.last_usable_s > *c.last_usable_s) c.last_usable_s = s.last_usable_s;
      const int64_t start = WindowStart(*crusher, *s.last_usable_s);
      std::optional<Point> newest;
      store.Walk(id, sensor, liner_start, INT64_MAX, false, [&](const StoredReading& r) {
        if (!UsableForWear(crusher->config, r)) return true;
        const Point p{r.time_s, r.seq, r.thickness_mm, r.loops_intact, r.flags};
        if (r.time_s >= start) s.window.push_back(p);
        AddToRun(s, p, newest);
        newest = p;
        return true;
      });
      for (size_t k = 0; k < crusher->scans.size(); ++k) {
        std::optional<Point>& a = s.anchor[k];
        store.Walk(id, sensor, liner_start, Unix(crusher->scans[k].scan.date), true, [&](const StoredReading& r) {
          if (a && r.time_s < a->time_s) return false;  // past the newest usable time at or before the scan
          if (!UsableForWear(crusher->config, r)) return true;
          if (!a || BetterAtSameTime(r.thickness_mm, r.seq, a->thickness_mm, a->seq)) {
            a = Point{r.time_s, r.seq, r.thickness_mm, r.loops_intact, r.flags};
          }
          return true;
        });
      }
    }
  }
}

std::vector<Store::SensorSummary> LiveState::LatestPerSensor(const std::string& crusher) const {
  std::vector<Store::SensorSummary> out;
  const CrusherLive* c = Find(crusher);
  if (!c) return out;
  std::lock_guard<std::mutex> lock(c->mutex);
  for (const auto& [sensor, s] : c->sensors) {
    if (s.latest) out.push_back({*s.latest, s.count});
  }
  return out;
}

int64_t LiveState::CountReadings(const std::string& crusher) const {
  const CrusherLive* c = Find(crusher);
  if (!c) return 0;
  std::lock_guard<std::mutex> lock(c->mutex);
  int64_t n = 0;
  for (const auto& [sensor, s] : c->sensors) n += s.count;
  return n;
}

std::optional<int64_t> LiveState::LatestUsableTime(const std::string& crusher) const {
  const CrusherLive* c = Find(crusher);
  if (!c) return std::nullopt;
  std::lock_guard<std::mutex> lock(c->mutex);
  return c->last_usable_s;
}

std::vector<StoredReading> LiveState::WearInputs(const std::string& crusher) const {
  std::vector<StoredReading> out;
  const CrusherLive* c = Find(crusher);
  if (!c) return out;
  std::lock_guard<std::mutex> lock(c->mutex);
  size_t total = 0;  // reserved at once: the copies are this function's cost, not the vector's growth
  for (const auto& entry : c->sensors)
    total += entry.second.window.size() + entry.second.anchor.size() + entry.second.lows.size() + 1;
  out.reserve(total);
  for (const auto& entry : c->sensors) {
    const std::string& sensor = entry.first;  // not a structured binding: clang 14 cannot capture one
    const auto& s = entry.second;
    const size_t first = out.size();
    const auto emit = [&](const Point& p) {
      StoredReading r;
      r.crusher = crusher;
      r.sensor = sensor;
      r.seq = p.seq;
      r.time_s = p.time_s;
      r.thickness_mm = p.thickness_mm;
      r.loops_intact = p.loops_intact;
      r.flags = p.flags;
      out.push_back(std::move(r));
    };
    for (const Point& p : s.window) emit(p);
    bool extra = false;
    const auto emit_extra = [&](const Point& p, size_t from) {
      if (std::any_of(out.begin() + static_cast<std::ptrdiff_t>(from), out.end(),
                      [&](const StoredReading& r) { return r.seq == p.seq; }))
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
    if (extra) {
      std::sort(out.begin() + static_cast<std::ptrdiff_t>(first), out.end(), [](const StoredReading& a, const StoredReading& b) {
        return a.time_s < b.time_s || (a.time_s == b.time_s && a.seq < b.seq);
      });
    }
  }
  return out;
}

}  // namespace lw::server
