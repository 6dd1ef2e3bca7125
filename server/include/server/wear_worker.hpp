#pragma once
/// The wear worker: one thread that recomputes a crusher's wear and forecast when its readings
/// change (at most every `interval_ms`), evaluates the alarms after it and on a timer, and hands
/// back what is to be retained on MQTT (`.../wear`, `.../alarms`), which the MQTT loop publishes.
/// At start-up it first loads every crusher's state and computes its wear, crusher by crusher.
/// Wear is off the MQTT loop so a large map or a long campaign never delays commit acks.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "core/log.hpp"
#include "mqtt/outbox.hpp"
#include "mqtt/publisher.hpp"
#include "mqtt/topics.hpp"
#include "server/alarms.hpp"
#include "server/campaigns.hpp"
#include "server/events.hpp"
#include "server/health.hpp"
#include "server/ingest.hpp"
#include "server/live_state.hpp"
#include "server/metrics.hpp"
#include "server/registry.hpp"
#include "server/wear_service.hpp"

namespace lw::server {

/// What the alarm rules of `crusher` look at now (`wear`: its latest state, may be null).
AlarmInputs GatherAlarmInputs(const Crusher& crusher, const LiveState& live, const Ingestor& ingestor, const CrusherState* wear,
                              int64_t now_s);

/// Every method is thread-safe unless it says otherwise. The parts outlive the worker.
class WearWorker {
 public:
  struct Parts {
    const Registry& registry;
    LiveState& live;
    WearService& wear;
    AlarmEngine& alarms;
    const Ingestor& ingestor;  ///< alarm inputs (rejections) and each crusher's site
    EventBus& events;          ///< "wear" and "alarm" events
    ServerMetrics& metrics;
    core::Logger& log;
    /// Estimates a crusher's setting checks whose opening was not known, before its wear and, while
    /// some wait, from the worker's loop (none: a read-only server, which writes no check).
    CampaignService* campaigns = nullptr;
  };
  /// `now_s`: the server's "now" (unix seconds) for alarms; `interval_ms`: the least time between
  /// two recomputations (--wear-interval-ms).
  WearWorker(Parts parts, std::function<int64_t()> now_s, int64_t interval_ms);
  /// Stops and joins the thread.
  ~WearWorker();
  WearWorker(const WearWorker&) = delete;
  WearWorker& operator=(const WearWorker&) = delete;

  /// Starts the thread (its start-up pass first). Once.
  void Start();
  /// Stops and joins the thread; its start-up pass ends at the crusher it is at.
  void Stop();

  /// Readings of `crushers` were committed: their wear is recomputed and published.
  void ReadingsChanged(const std::set<std::string>& crushers);
  /// `crusher`'s wear is recomputed and published (a reline: its new liner).
  void Recompute(const std::string& crusher);
  /// A gateway's retained status (or last will), from the MQTT loop: told to the alarm engine, for
  /// a known crusher, and every crusher's alarms evaluated soon. False when the message is not one.
  bool GatewayStatus(const mqtt::ParsedTopic& topic, const std::string& payload);
  /// The alarm engine's change listener: logs, sends the "alarm" event, queues the retained set.
  void AlarmsChanged(const std::string& crusher);

  /// True while the start-up pass runs (ApiContext::starting).
  const std::atomic<bool>* starting() const { return &starting_; }
  StartupProgress Startup() const;

  /// Publishes the wear summaries and alarm sets handed back since the last call, each to its
  /// crusher's own site (crusher.json's "site" or the first heard from), never to a site a stray
  /// publisher made up. Alarm sets wait in an outbox while the broker is away (never dropped: the
  /// latest goes last). One thread only (the MQTT loop's).
  void PublishReady(mqtt::Publisher& link, const std::string& topic_root);

 private:
  void Run();
  void StartupPass();
  void EvaluateAlarms(const std::string& crusher, const CrusherState* state);
  void EvaluateAllAlarms(bool force);
  void ComputeAndHandBack(const std::string& crusher);
  /// Asks the campaigns to estimate `crusher`'s checks not known; true when it did (its wear is to
  /// be computed again). Keeps settings_waiting_.
  bool SettleSettings(const std::string& crusher);
  /// Asks again for the crushers whose checks wait, at most every second: the readings they wait
  /// for may have been committed within a try's minute, with no commit after them.
  void RetrySettings();

  Parts p_;
  std::function<int64_t()> now_s_;
  int64_t interval_ms_;

  std::atomic<bool> stop_{false};
  std::atomic<bool> starting_{true};
  std::atomic<size_t> startup_loaded_{0}, startup_computed_{0};
  std::atomic<bool> alarms_due_{false};  ///< a gateway's status changed: evaluate every crusher's alarms
  int64_t last_alarms_ms_ = 0;           ///< the worker thread's
  // The worker thread's: crushers with a check not known yet, when they were last asked, and each
  // crusher's last failure to estimate (logged once, not at every retry).
  std::set<std::string> settings_waiting_;
  std::chrono::steady_clock::time_point last_settings_{};
  std::map<std::string, std::string> settings_error_;

  std::mutex dirty_mutex_;
  std::condition_variable dirty_cv_;
  std::set<std::string> dirty_;  ///< crushers whose wear must be recomputed and published

  std::mutex ready_mutex_;
  std::vector<std::pair<std::string, std::string>> wear_ready_;    ///< (crusher, wear summary JSON)
  std::vector<std::pair<std::string, std::string>> alarms_ready_;  ///< (crusher, its open alarms JSON)
  mqtt::Outbox alarm_outbox_{10'000};                              ///< PublishReady's thread only

  std::thread thread_;
};

}  // namespace lw::server
