#include "server/live_state.hpp"

#include <algorithm>
#include <climits>

#include "core/time.hpp"
#include "server/ingest.hpp"

namespace lw::server {
void LoadSensorWindow(Store& store, const Crusher& crusher, const std::string& sensor, int64_t to_s,
                      estimate::ReadingWindow* window) {
  window->Load(sensor, to_s,
               [&](int64_t from_s, int64_t until_s, bool newest_first, const std::function<bool(const estimate::Point&)>& visit) {
                 store.Walk(crusher.config.crusher_id, sensor, from_s, until_s, newest_first,
                            [&](const StoredReading& r) { return visit(PointOf(r)); });
               });
}

estimate::ReadingWindow LoadWindow(Store& store, const Crusher& crusher, int64_t to_s) {
  estimate::ReadingWindow window(crusher);
  for (const std::string& sensor : store.SensorsOf(crusher.config.crusher_id))
    LoadSensorWindow(store, crusher, sensor, to_s, &window);
  return window;
}

LiveState::LiveState(const Registry& registry) : registry_(registry) {
  for (const Crusher* c : registry_.All()) {
    CrusherLive& live = crushers_.try_emplace(c->config.crusher_id, c).first->second;
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
  CrusherLive fresh(c.crusher);
  if (loader_) LoadFrom(*loader_, *c.crusher, fresh);
  std::lock_guard<std::mutex> lock(c.mutex);
  c.sensors = std::move(fresh.sensors);
  c.window = std::move(fresh.window);
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
    c.window = estimate::ReadingWindow(*c.crusher);
  }
}

void LiveState::AddLocked(CrusherLive& c, const StoredReading& r) {
  SensorCounts& s = c.sensors[r.sensor];
  ++s.count;
  if (!s.latest || r.time_s > s.latest->time_s || (r.time_s == s.latest->time_s && r.seq > s.latest->seq)) {
    // Without its payload (not kept here): not copied only to be cleared.
    s.latest = StoredReading{r.crusher,      r.sensor, r.seq,        r.time_s,     r.thickness_mm,
                             r.loops_intact, r.flags,  r.battery_mv, r.received_s, {}};
  }
  c.window.Add(r.sensor, PointOf(r));  // only if usable for wear (estimate::UsableForWear)
}

void LiveState::Add(const std::vector<StoredReading>& committed) {
  CrusherLive* c = nullptr;
  std::unique_lock<std::mutex> lock;
  const std::string* id = nullptr;  // c's crusher id (the map's key: a reline never changes it)
  for (const StoredReading& r : committed) {
    if (!c || r.crusher != *id) {  // batches come mostly crusher by crusher
      const auto it = crushers_.find(r.crusher);
      if (it == crushers_.end()) continue;
      if (lock.owns_lock()) lock.unlock();
      c = &it->second;
      id = &it->first;
      lock = std::unique_lock<std::mutex>(c->mutex);
    }
    if (c->loaded) AddLocked(*c, r);
  }
}

void LiveState::Rebuild(Store& store) {
  std::lock_guard<std::mutex> order(order_);
  for (auto& [id, live] : crushers_) {
    CrusherLive c(live.crusher);  // loaded here, then swapped in
    LoadFrom(store, *live.crusher, c);
    std::lock_guard<std::mutex> lock(live.mutex);
    live.sensors = std::move(c.sensors);
    live.window = std::move(c.window);
    live.loaded = true;
  }
}

void LiveState::Replace(const Crusher& crusher, Store& store) {
  const auto it = crushers_.find(crusher.config.crusher_id);
  if (it == crushers_.end()) return;
  std::lock_guard<std::mutex> order(order_);
  CrusherLive fresh(&crusher);
  LoadFrom(store, crusher, fresh);
  CrusherLive& live = it->second;
  std::lock_guard<std::mutex> lock(live.mutex);
  live.crusher = &crusher;
  live.sensors = std::move(fresh.sensors);
  live.window = std::move(fresh.window);
  live.loaded = true;
}

void LiveState::LoadFrom(Store& store, const Crusher& crusher, CrusherLive& c) const {
  const std::string& id = crusher.config.crusher_id;
  for (const std::string& sensor : store.SensorsOf(id)) {
    SensorCounts& s = c.sensors[sensor];
    s.count = store.CountReadings(id, sensor);
    s.latest = store.Latest(id, sensor);
    LoadSensorWindow(store, crusher, sensor, INT64_MAX, &c.window);
  }
}

bool LiveState::Loaded(const std::string& crusher) const {
  const auto it = crushers_.find(crusher);
  if (it == crushers_.end()) return false;
  std::lock_guard<std::mutex> lock(it->second.mutex);
  return it->second.loaded;
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
  return c->window.LatestUsableTime();
}

std::vector<estimate::Sample> LiveState::WearSamples(const std::string& crusher) const {
  const CrusherLive* c = Find(crusher);
  if (!c) return {};
  std::lock_guard<std::mutex> lock(c->mutex);
  return c->window.Readings();
}

std::vector<StoredReading> LiveState::WearInputs(const std::string& crusher) const {
  std::vector<StoredReading> out;
  for (estimate::Sample& s : WearSamples(crusher)) {
    StoredReading r;
    r.crusher = crusher;
    r.sensor = std::move(s.sensor);
    r.seq = s.seq;
    r.time_s = s.time_s;
    r.thickness_mm = s.thickness_mm;
    r.loops_intact = s.loops_intact;
    r.flags = s.flags;
    out.push_back(std::move(r));
  }
  return out;
}

}  // namespace lw::server
