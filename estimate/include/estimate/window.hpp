#pragma once
/// The readings live wear is estimated from, and the one rule of which readings count. A
/// ReadingWindow holds, per sensor, what Estimate() needs to give exactly the result it gives on
/// every reading: the forecast's fit window of usable readings, the latest usable reading at each
/// laser scan's date, and the record lows the stuck rule reads before the window (core::StuckRule).
/// The server keeps one per crusher in memory as readings are committed (server/live_state.hpp)
/// and loads one from its store for a past time (GET .../wear?at=TIME); a bundle's readings go
/// into one as they are (tests/unit/server/test_live_state.cpp proves the equality).
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/bundle.hpp"

namespace lw::estimate {

struct CrusherModel;

/// A stored reading without its sensor id: what the rule and the window read of it.
struct Point {
  int64_t seq = 0;
  int64_t time_s = 0;  ///< unix seconds, when the sample was taken
  double thickness_mm = 0;
  int64_t loops_intact = 0;
  int64_t flags = 0;
};

/// A reading of one sensor.
struct Sample : Point {
  std::string sensor;
};

/// Readings stored but not used for wear: SPI stuck, or every loop open while the board still
/// holds loops intact (a cut cable). Every loop open with none intact is a consumed sensor: real wear.
bool IsFaultReading(int64_t flags, int64_t loops_intact);

/// Whether a reading measures this liner's wear: not a fault (IsFaultReading) and of this liner,
/// not a previous one's (core::CrusherConfig::OfThisLiner; docs/server.md, Relining).
bool UsableForWear(const core::CrusherConfig& crusher, const std::string& sensor, const Point& p);

class ReadingWindow {
 public:
  explicit ReadingWindow(const CrusherModel& model);

  /// One reading, in any order (late ones too); false when it is not usable (UsableForWear), which
  /// leaves the window as it was.
  bool Add(const std::string& sensor, const Point& p);

  /// Visits one sensor's readings with time in [from_s, to_s], oldest first (newest first when
  /// `newest_first`), until `visit` returns false: a store's time index.
  using Walk =
      std::function<void(int64_t from_s, int64_t to_s, bool newest_first, const std::function<bool(const Point&)>& visit)>;
  /// Loads one sensor's readings up to `to_s` through `walk`, as Add() of each would, reading only
  /// what the window keeps (a walk to the newest usable, the window, one per scan). The sensor must
  /// not be in the window yet.
  void Load(const std::string& sensor, int64_t to_s, const Walk& walk);

  /// Time of the newest usable reading; nullopt before the first.
  std::optional<int64_t> LatestUsableTime() const { return last_usable_s_; }
  /// The readings Estimate() reads, ordered by sensor, time, seq.
  std::vector<Sample> Readings() const;

 private:
  struct SensorWindow {
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
  /// A usable reading into s.lows and s.above; `newest` the sensor's newest usable reading before it.
  static void AddToRun(SensorWindow& s, const Point& p, const std::optional<Point>& newest);
  /// Earliest time the forecast's window may reach back to, for a sensor whose newest usable
  /// reading is at `last_s` (with a day's margin: the fit selects its own window from what it gets).
  int64_t WindowStart(int64_t last_s) const;
  void AppendSensor(const std::string& sensor, const SensorWindow& s, std::vector<Sample>* out) const;

  const CrusherModel* model_;
  std::map<std::string, SensorWindow> sensors_;
  std::optional<int64_t> last_usable_s_;
};

}  // namespace lw::estimate
