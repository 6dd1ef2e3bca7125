#pragma once
/// Live global wear per crusher (estimate::Estimate over the live state's reading window),
/// recomputed when readings changed, shared read-only with REST/MQTT; and its JSON and CSV.
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "estimate/estimate.hpp"
#include "server/live_state.hpp"
#include "server/registry.hpp"
#include "server/store.hpp"

namespace lw::server {

/// A crusher's wear as published: estimate::Estimate's result, for which crusher and when.
struct CrusherState : estimate::WearEstimate {
  const Crusher* crusher = nullptr;
  std::optional<core::TimePoint> at;  ///< the past time asked for (GET .../wear?at=TIME); nullopt: live
  int64_t version = 0;
  /// The JSON bodies of GET .../wear (with and without faces) and .../forecast, serialized once as
  /// the state is computed (by the wear worker, ahead of any request): a request only sends them.
  /// Empty for a past time's state (GET .../wear?at=), which a request computes anyway.
  std::string wear_body, wear_body_no_faces, forecast_body;
};

/// Computes the state from a crusher's stored readings (fault readings are left out). With the
/// state published before (`previous`), reline dates hold still within their band
/// (core::HoldRowForecasts).
CrusherState ComputeCrusherState(const Crusher& crusher, const std::vector<StoredReading>& readings,
                                 const CrusherState* previous = nullptr);
/// The same from the readings of a reading window (the live state's, or LoadWindow's), at `at`: the
/// readings and scans up to it (nullopt: now, the newest scan whatever its date). The setting is
/// counted from the latest of `checks` (measured settings) up to `at` since the liner's installation.
/// `options`: estimate::Estimate's (a setting check's opening asks for no forecast).
CrusherState ComputeCrusherState(const Crusher& crusher, const std::vector<estimate::Sample>& readings,
                                 std::optional<core::TimePoint> at, const CrusherState* previous = nullptr,
                                 const std::vector<core::SettingCheck>& checks = {},
                                 const estimate::EstimateOptions& options = {});

/// The wear JSON of docs/server.md (GET .../wear and the retained MQTT `.../wear`, without faces);
/// "at" when the state is a past time's.
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
  /// `crusher` was relined: the next Get() recomputes on the new liner alone, without holding the
  /// old liner's reline dates (no previous state); Latest() is nullptr until then.
  void Reset(const std::string& crusher);
  /// Current state (recomputed if readings changed since; waits for a computation of this crusher
  /// already under way, never for another crusher's). nullptr for an unknown crusher.
  std::shared_ptr<const CrusherState> Get(const std::string& crusher);
  /// The state computed last, without computing or waiting: for summaries of many crushers such as
  /// the crusher list. After new readings it is the previous state until the next Get() (the wear
  /// worker's, within --wear-interval-ms); nullptr for a crusher never computed yet (at startup,
  /// until the wear worker's first pass reaches it), so no request computes one.
  std::shared_ptr<const CrusherState> Latest(const std::string& crusher);
  /// The crusher's measured settings (docs/wear.md, *Setting*): the next Get() counts the setting
  /// from the latest of them.
  void SetSettingChecks(const std::string& crusher, std::vector<core::SettingCheck> checks);
  std::vector<core::SettingCheck> SettingChecks(const std::string& crusher);

 private:
  struct Entry {
    int64_t version = 1;
    std::shared_ptr<const CrusherState> state;
    std::vector<core::SettingCheck> checks;
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
