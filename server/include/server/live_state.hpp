#pragma once
/// Per-crusher state kept in memory as readings are committed, so that no request and no wear
/// recompute reads every stored reading of a crusher: per sensor the reading count, the latest
/// reading, and the readings global wear and the forecast use (the forecast's fit window of usable
/// readings, the latest usable reading at each laser scan's date, and the record lows the stuck rule
/// reads before the window). Rebuilt once at startup from the store with indexed queries (per
/// sensor: a count, the window, a few look-ups, and one pass over its readings for the record lows).
///
/// The wear inputs are the readings ComputeCrusherState needs to give exactly the result it gives on
/// every stored reading (tests/unit/server/test_live_state.cpp proves the equality).
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "server/registry.hpp"
#include "server/store.hpp"

namespace lw::server {

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

  /// As Store::LatestPerSensor (latest by time then seq, any flags; payload left empty), ordered
  /// by sensor. Empty for an unknown crusher.
  std::vector<Store::SensorSummary> LatestPerSensor(const std::string& crusher) const;
  /// Readings stored for `crusher` (as Store::CountReadings).
  int64_t CountReadings(const std::string& crusher) const;
  /// Time of the latest usable (not fault) reading; nullopt before the first.
  std::optional<int64_t> LatestUsableTime(const std::string& crusher) const;
  /// The readings wear and forecast are computed from, ordered by sensor, time, seq (payload empty):
  /// ComputeCrusherState on them equals ComputeCrusherState on every stored reading.
  std::vector<StoredReading> WearInputs(const std::string& crusher) const;

 private:
  struct Point {
    int64_t time_s;
    int64_t seq;
    double thickness_mm;
    int64_t loops_intact;
    int64_t flags;
  };
  struct SensorState {
    int64_t count = 0;
    std::optional<StoredReading> latest;       ///< by (time, seq), any flags
    std::optional<int64_t> last_usable_s;      ///< newest usable reading's time
    std::deque<Point> window;                  ///< usable readings the forecast may fit, by (time, seq)
    std::vector<std::optional<Point>> anchor;  ///< per scan: latest usable at or before its date (thinnest at that time)
    /// Record lows of the usable readings, by time: each new lowest whole-mm thickness when first
    /// read (the thinnest reading of that time). The stuck rule's view of the days before the window
    /// (core::StuckRule); at most one per loop, whatever the readings.
    std::vector<Point> lows;
    /// The newest usable reading a loop above the lowest: when the sensor's value has not changed
    /// since before the window, its run began after this (a loop that read intact again).
    std::optional<Point> above;
  };
  struct CrusherLive {
    const Crusher* crusher = nullptr;
    mutable std::mutex mutex;  ///< per crusher: copying one crusher's inputs never holds up another's
    bool loaded = false;       ///< guarded by mutex
    std::map<std::string, SensorState> sensors;
    std::optional<int64_t> last_usable_s;
  };

  /// The caller holds c.mutex.
  void AddLocked(CrusherLive& c, const StoredReading& r);
  /// A usable reading into s.lows and s.above; `newest` the sensor's newest usable reading before it.
  static void AddToRun(SensorState& s, const Point& p, const std::optional<Point>& newest);
  /// Reads `c`'s state from `store` into `out` (not shared yet: no lock needed).
  void LoadFrom(Store& store, const Crusher& crusher, CrusherLive& out) const;
  /// nullptr for a crusher not in the registry; otherwise loaded (lazily, see LoadLazily).
  const CrusherLive* Find(const std::string& crusher) const;
  /// Earliest time the forecast's window may reach back to, for a sensor whose newest usable
  /// reading is at `last_s` (with a day's margin: the fit selects its own window from what it gets).
  int64_t WindowStart(const Crusher& c, int64_t last_s) const;

  const Registry& registry_;
  /// One per registry crusher, made once (never added to); mutable: a lazy load is no visible change.
  mutable std::map<std::string, CrusherLive> crushers_;
  mutable std::mutex order_;               ///< see CommitGuard(); taken before any crusher's mutex
  mutable std::unique_ptr<Store> loader_;  ///< lazy loads (guarded by order_)
};

}  // namespace lw::server
