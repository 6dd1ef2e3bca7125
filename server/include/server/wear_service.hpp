#pragma once
/// Live global wear per crusher: Eq. 9 reconstruction from each sensor's latest usable reading and
/// the remaining-life forecast, recomputed when readings changed, shared read-only with REST/MQTT.
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/forecast.hpp"
#include "core/reconstruction.hpp"
#include "core/thinnest_area.hpp"
#include "server/live_state.hpp"
#include "server/registry.hpp"
#include "server/store.hpp"

namespace lw::server {

struct CrusherState {
  const Crusher* crusher = nullptr;
  bool has_wear = false;
  core::TimePoint time{};           ///< latest reading used
  std::vector<StoredReading> used;  ///< the reading each sensor's wear came from
  std::vector<core::SensorWear> sensor_wear;
  std::vector<std::string> stale;  ///< sensors whose latest reading is too old to set a scale
  std::vector<std::string> stuck;  ///< sensors reporting one value while their row wears (core::StuckRule)
  core::Reconstruction reconstruction;
  core::ThinnestAreas areas;                ///< the thinnest areas the data support (liner, rows)
  std::shared_ptr<const ScannedPlan> scan;  ///< the scan applied (nullptr: the map alone)
  std::vector<core::SensorForecast> sensor_forecasts;
  std::vector<core::RowForecast> row_forecasts;
  int64_t version = 0;
};

/// Computes the state from a crusher's stored readings (fault readings are left out). With the
/// state published before (`previous`), reline dates hold still within their band
/// (core::HoldRowForecasts).
CrusherState ComputeCrusherState(const Crusher& crusher, const std::vector<StoredReading>& readings,
                                 const CrusherState* previous = nullptr);

/// The wear JSON of docs/server.md (GET .../wear and the retained MQTT `.../wear`, without faces).
nlohmann::ordered_json WearJson(const CrusherState& state, bool with_faces);
nlohmann::ordered_json ForecastJson(const CrusherState& state);
/// Per-face wear as CSV (`?format=csv`): face,row,z_m,theta_deg,remaining_mm,remaining_sd_mm,wear_mm
/// (the mm columns empty when no sensor gives a row scale).
std::string WearCsv(const CrusherState& state);

class WearService {
 public:
  /// Computes from `live`'s wear inputs (never from a scan of the stored readings).
  WearService(const Registry& registry, const LiveState& live);
  /// Readings of `crusher` changed: the next Get() recomputes.
  void MarkChanged(const std::string& crusher);
  /// Current state (recomputed if readings changed since; waits for a computation of this crusher
  /// already under way, never for another crusher's). nullptr for an unknown crusher.
  std::shared_ptr<const CrusherState> Get(const std::string& crusher);
  /// The state computed last, without computing or waiting (only a crusher never computed yet is
  /// computed): for summaries of many crushers such as the crusher list. After new readings it is
  /// the previous state until the next Get() (the wear worker's, within --wear-interval-ms).
  std::shared_ptr<const CrusherState> Latest(const std::string& crusher);

 private:
  struct Entry {
    int64_t version = 1;
    std::shared_ptr<const CrusherState> state;
    std::mutex compute;  ///< one computation of this crusher at a time (held while computing)
  };
  /// Recomputes `e` if stale; the caller holds e.compute.
  std::shared_ptr<const CrusherState> ComputeLocked(const Crusher& crusher, Entry& e);
  Entry& EntryOf(const std::string& crusher);

  const Registry& registry_;
  const LiveState& live_;
  std::mutex mutex_;  ///< guards the entries' version and state (held briefly: never during a computation)
  std::map<std::string, Entry> entries_;
};

}  // namespace lw::server
