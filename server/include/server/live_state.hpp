#pragma once
/// Per-crusher state kept in memory as readings are committed, so that no request and no wear
/// recompute reads every stored reading of a crusher: per sensor the reading count and the latest
/// reading, and the crusher's reading window (estimate::ReadingWindow: the readings global wear and
/// the forecast use). Rebuilt once at startup from the store with indexed queries (per sensor: a
/// count, the window's walks).
///
/// The wear inputs are the readings estimate::Estimate needs to give exactly the result it gives on
/// every stored reading (tests/unit/server/test_live_state.cpp proves the equality).
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "estimate/window.hpp"
#include "server/registry.hpp"
#include "server/store.hpp"

namespace lw::server {

/// One sensor's readings up to `to_s` from `store` into `window` (estimate::ReadingWindow::Load
/// over the store's time index).
void LoadSensorWindow(Store& store, const Crusher& crusher, const std::string& sensor, int64_t to_s,
                      estimate::ReadingWindow* window);
/// The crusher's reading window of its stored readings up to `to_s`: the live state's at startup,
/// and a past time's (GET .../wear?at=TIME).
estimate::ReadingWindow LoadWindow(Store& store, const Crusher& crusher, int64_t to_s);

class LiveState {
 public:
  explicit LiveState(const Registry& registry);

  /// Loads every registry crusher's state from `store` now (replacing what was held). Startup only.
  void Rebuild(Store& store);
  /// Loads each crusher's state from `store` (a connection of its own) the first time it is asked
  /// for, instead of all at once: the server answers while the states load (its wear worker asks
  /// for every crusher once at startup). Call before anything else uses this object.
  void LoadLazily(std::unique_ptr<Store> store);

  /// The committer holds this from its commit until it has called Add(), so that a crusher being
  /// loaded sees each commit either in the database or through Add(), never both or neither.
  std::unique_lock<std::mutex> CommitGuard() { return std::unique_lock<std::mutex>(order_); }
  /// Readings just committed (new ones only: not duplicates or conflicts). Crushers not loaded yet
  /// skip them (their load reads them from the database).
  void Add(const std::vector<StoredReading>& committed);

  /// A reline made `crusher` the current model of its crusher_id (Registry::Replace): its state is
  /// loaded again from `store` now, through the new model (only the new liner's readings count for
  /// wear), with commits held off meanwhile (CommitGuard), so none is lost or counted twice.
  void Replace(const Crusher& crusher, Store& store);

  /// As Store::LatestPerSensor (latest by time then seq, any flags; payload left empty), ordered
  /// by sensor. Empty for an unknown crusher.
  std::vector<Store::SensorSummary> LatestPerSensor(const std::string& crusher) const;
  /// Readings stored for `crusher` (as Store::CountReadings).
  int64_t CountReadings(const std::string& crusher) const;
  /// Time of the latest usable (not fault) reading; nullopt before the first.
  std::optional<int64_t> LatestUsableTime(const std::string& crusher) const;
  /// Whether `crusher`'s state is loaded (false for an unknown crusher), without loading it: a
  /// summary of many crushers asks this first, so that no request loads one (the wear worker loads
  /// every crusher at startup).
  bool Loaded(const std::string& crusher) const;
  /// The readings wear and forecast are computed from (the window's), ordered by sensor, time, seq:
  /// estimate::Estimate on them equals estimate::Estimate on every stored reading.
  std::vector<estimate::Sample> WearSamples(const std::string& crusher) const;
  /// The same as stored readings (payload empty): ComputeCrusherState on them equals
  /// ComputeCrusherState on every stored reading.
  std::vector<StoredReading> WearInputs(const std::string& crusher) const;

 private:
  struct SensorCounts {
    int64_t count = 0;
    std::optional<StoredReading> latest;  ///< by (time, seq), any flags
  };
  struct CrusherLive {
    explicit CrusherLive(const Crusher* c) : crusher(c), window(*c) {}
    const Crusher* crusher;    ///< guarded by mutex (a reline replaces it)
    mutable std::mutex mutex;  ///< per crusher: copying one crusher's inputs never holds up another's
    bool loaded = false;       ///< guarded by mutex
    std::map<std::string, SensorCounts> sensors;
    estimate::ReadingWindow window;
  };

  /// The caller holds c.mutex.
  void AddLocked(CrusherLive& c, const StoredReading& r);
  /// Reads `c`'s state from `store` into `out` (not shared yet: no lock needed).
  void LoadFrom(Store& store, const Crusher& crusher, CrusherLive& out) const;
  /// nullptr for a crusher not in the registry; otherwise loaded (lazily, see LoadLazily).
  const CrusherLive* Find(const std::string& crusher) const;

  const Registry& registry_;
  /// One per registry crusher, made once (never added to); mutable: a lazy load is no visible change.
  mutable std::map<std::string, CrusherLive> crushers_;
  mutable std::mutex order_;               ///< see CommitGuard(); taken before any crusher's mutex
  mutable std::unique_ptr<Store> loader_;  ///< lazy loads (guarded by order_)
};

}  // namespace lw::server
