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
#include "server/registry.hpp"
#include "server/store.hpp"

namespace lw::server {

struct CrusherState {
  const Crusher* crusher = nullptr;
  bool has_wear = false;
  core::TimePoint time{};                    ///< latest reading used
  std::vector<StoredReading> used;           ///< the reading each sensor's wear came from
  std::vector<core::SensorWear> sensor_wear;
  core::Reconstruction reconstruction;
  std::shared_ptr<const ScannedPlan> scan;   ///< the scan applied (nullptr: the map alone)
  std::vector<core::SensorForecast> sensor_forecasts;
  std::vector<core::RowForecast> row_forecasts;
  int64_t version = 0;
};

/// Computes the state from a crusher's stored readings (fault readings are left out).
CrusherState ComputeCrusherState(const Crusher& crusher, const std::vector<StoredReading>& readings);

/// The wear JSON of docs/server.md (GET .../wear and the retained MQTT `.../wear`, without faces).
nlohmann::ordered_json WearJson(const CrusherState& state, bool with_faces);
nlohmann::ordered_json ForecastJson(const CrusherState& state);

class WearService {
 public:
  /// `read` is a read connection guarded by `read_mutex` (shared with REST handlers).
  WearService(const Registry& registry, Store& read, std::mutex& read_mutex);
  /// Readings of `crusher` changed: the next Get() recomputes.
  void MarkChanged(const std::string& crusher);
  /// Current state (recomputed if readings changed since). nullptr for an unknown crusher.
  std::shared_ptr<const CrusherState> Get(const std::string& crusher);

 private:
  struct Entry {
    int64_t version = 1;
    std::shared_ptr<const CrusherState> state;
  };
  const Registry& registry_;
  Store& read_;
  std::mutex& read_mutex_;
  std::mutex compute_mutex_;  ///< one computation at a time (held while computing)
  std::mutex mutex_;          ///< guards entries_ (held briefly: MarkChanged never waits for a computation)
  std::map<std::string, Entry> entries_;
};

}  // namespace lw::server
