#pragma once
/// Alarms (docs/alarms.md): per crusher, the rules of core::AlarmConfig (crusher.json's "alarms",
/// overridden over REST) evaluated by the wear worker on the crusher's latest wear, its sensors'
/// latest readings, its gateways' status and its rejected readings. Each alarm is raised past its
/// rule's threshold and cleared only back past it by the hysteresis, goes active -> acknowledged ->
/// cleared, and is stored in SQLite with its audit trail as it changes: a restart finds the open
/// alarms again and raises none of them twice.
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/bundle.hpp"
#include "server/registry.hpp"
#include "server/store.hpp"
#include "server/wear_service.hpp"

namespace lw::server {

/// What the rules of one crusher look at, at one time (gathered by the wear worker, server/wear_worker.hpp).
struct AlarmInputs {
  int64_t now_s = 0;
  const CrusherState* wear = nullptr;  ///< the latest wear (nullptr or !has_wear: the wear rules hold)
  struct Sensor {
    std::string id;
    std::optional<int64_t> latest_s;  ///< time of its latest reading; nullopt: none yet
    int64_t battery_mv = 0;           ///< of that reading (0: not reported)
  };
  std::vector<Sensor> sensors;  ///< every sensor of the crusher's current liner
  int64_t rejected_total = 0;   ///< its readings rejected since the server started (a running count)
};

class AlarmEngine {
 public:
  /// Loads the open alarms and the REST rule overrides of the registry's crushers from `store`
  /// (a connection of the engine's own).
  AlarmEngine(const Registry& registry, LockedStore& store);

  /// Called with the crusher's id after its alarms changed (a raise, a clear, an acknowledgement),
  /// on the thread that changed them, outside the engine's lock. Set before the engine is shared.
  void OnChange(std::function<void(const std::string& crusher)> listener) { listener_ = std::move(listener); }

  /// Evaluates every rule of `crusher` on `in`; stores each raise and clear. Returns whether any
  /// alarm changed. Throws std::runtime_error on a database error (nothing of that alarm stored).
  bool Evaluate(const std::string& crusher, const AlarmInputs& in);

  /// A gateway's `gateway/status` (retained, or its last will) under `crusher`'s topics, saying it
  /// is online or offline since `since_s`.
  void GatewayStatus(const std::string& crusher, const std::string& gateway, bool online, int64_t since_s);

  enum class Ack { kAcknowledged, kAlreadyAcknowledged, kUnknown, kCleared };
  /// Acknowledges alarm `id` of `crusher` by `by` (the token's name) at `now_s`; `*out` is the alarm
  /// after it (unless kUnknown). Acknowledging an acknowledged alarm changes nothing.
  Ack Acknowledge(const std::string& crusher, int64_t id, const std::string& by, int64_t now_s, AlarmRecord* out);

  /// Alarms of `crusher`, newest first: open ones and those cleared since `cleared_since_s`, in
  /// `state` (empty: any).
  std::vector<AlarmRecord> List(const std::string& crusher, const std::string& state, int64_t cleared_since_s, int limit);
  /// The alarms of `crusher` not cleared, oldest first (the retained MQTT message).
  std::vector<AlarmRecord> Open(const std::string& crusher) const;
  std::vector<AlarmAuditEntry> Audit(int64_t id);

  /// `crusher`'s rules: crusher.json's with the REST override over them.
  core::AlarmConfig Rules(const std::string& crusher) const;
  /// Sets rules of `crusher` from `body` (an "alarms" object: only the keys it names change, over
  /// earlier REST changes), stored with an audit entry by `by`. Throws core::InputError naming the
  /// key (nothing changed). Returns the rules now in force.
  core::AlarmConfig UpdateRules(const std::string& crusher, const nlohmann::json& body, const std::string& by, int64_t now_s);

 private:
  /// One rule's verdict on one subject: past the threshold (raise), back past it by the hysteresis
  /// (clear), or between the two or without data (hold: an open alarm stays, none is raised).
  enum class Verdict { kRaise, kHold, kClear };
  struct Finding {
    std::string rule, subject;
    Verdict verdict = Verdict::kHold;
    std::optional<double> value, threshold;
    std::string detail;
  };
  std::vector<Finding> Findings(const Crusher& crusher, const core::AlarmConfig& rules, const AlarmInputs& in);
  /// The rules on the wear: thinnest_area, reline_due and overdue per row, unsupported.
  static void WearFindings(const core::CrusherConfig& cfg, const core::AlarmConfig& rules, const CrusherState& wear,
                           int64_t now_s, std::vector<Finding>* out);
  /// The rules on the sensors' latest readings: sensor_silent, battery_low.
  static void SensorFindings(const core::CrusherConfig& cfg, const core::AlarmConfig& rules, const AlarmInputs& in,
                             std::vector<Finding>* out);
  /// Rejected readings of `crusher` in the hour before `now_s` (from the running counts seen).
  double RejectedLastHour(const std::string& crusher, int64_t now_s, int64_t total);
  bool Apply(const core::CrusherConfig& config, const core::AlarmConfig& rules, const std::vector<Finding>& findings,
             int64_t now_s);
  core::AlarmConfig RulesLocked(const std::string& crusher) const;

  const Registry& registry_;
  LockedStore& store_;
  std::function<void(const std::string&)> listener_;
  mutable std::mutex mutex_;                              ///< guards everything below
  std::map<std::string, std::vector<AlarmRecord>> open_;  ///< crusher -> alarms not cleared
  std::map<std::string, nlohmann::json> overrides_;       ///< crusher -> REST "alarms" object
  struct Gateway {
    bool online = true;
    int64_t since_s = 0;
  };
  std::map<std::string, std::map<std::string, Gateway>> gateways_;                ///< crusher -> gateway -> status
  std::map<std::string, std::deque<std::pair<int64_t, int64_t>>> rejected_seen_;  ///< crusher -> (time, running count)
};

/// An alarm as REST and MQTT show it: {"id", "rule", "subject", "severity", "state", "since",
/// "detail", "value", "threshold", "acknowledged_at", "acknowledged_by", "cleared_at"} and, when
/// given, "audit": [{"time", "action", "by", "detail"}].
nlohmann::ordered_json AlarmJson(const AlarmRecord& alarm, const std::vector<AlarmAuditEntry>* audit = nullptr);
/// The retained `.../alarms` message: {"crusher", "time", "alarms": [the open alarms, AlarmJson]}.
std::string AlarmsMessage(const std::string& crusher, const std::vector<AlarmRecord>& open, int64_t now_s);

}  // namespace lw::server
