#include "server/wear_worker.hpp"

#include <pthread.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <map>

#include "core/clock.hpp"
#include "core/time.hpp"
#include "mqtt/messages.hpp"

namespace lw::server {
namespace {

int64_t WallMs() {
  return core::WallClockMs();
}

/// CPU time of `clock` (CLOCK_PROCESS_CPUTIME_ID, CLOCK_THREAD_CPUTIME_ID) in ms: startup figures
/// that do not depend on what else the machine runs.
int64_t CpuMs(clockid_t clock) {
  timespec t{};
  ::clock_gettime(clock, &t);
  return static_cast<int64_t>(t.tv_sec) * 1000 + t.tv_nsec / 1'000'000;
}

// Every crusher's alarms, at most every kAlarmIntervalMs (silence and offline gateways are
// matters of time, not of new readings) and when a gateway's status changed; a crusher whose wear
// was just recomputed is evaluated right after it.
constexpr int64_t kAlarmIntervalMs = 10'000;
// How often the crushers whose setting checks wait are asked again; a real try (a window read) is
// rate-limited by CampaignService itself.
constexpr std::chrono::seconds kSettingsRetry{1};

}  // namespace

AlarmInputs GatherAlarmInputs(const Crusher& crusher, const LiveState& live, const Ingestor& ingestor, const CrusherState* wear,
                              int64_t now_s) {
  AlarmInputs in;
  in.now_s = now_s;
  in.wear = wear;
  std::map<std::string, const StoredReading*> latest;
  const std::vector<Store::SensorSummary> summaries = live.LatestPerSensor(crusher.config.crusher_id);
  for (const Store::SensorSummary& s : summaries) latest[s.latest.sensor] = &s.latest;
  for (const core::SensorInfo& s : crusher.config.sensors) {
    AlarmInputs::Sensor sensor{s.id, std::nullopt, 0};
    if (const auto it = latest.find(s.id);
        it != latest.end() &&
        crusher.config.OfThisLiner(s.id, core::FromUnixSeconds(it->second->time_s), it->second->thickness_mm)) {
      sensor.latest_s = it->second->time_s;
      sensor.battery_mv = it->second->battery_mv;
    }
    in.sensors.push_back(std::move(sensor));
  }
  in.rejected_total = ingestor.CrusherCounters(crusher.config.crusher_id).rejected;
  return in;
}

WearWorker::WearWorker(Parts parts, std::function<int64_t()> now_s, int64_t interval_ms)
    : p_(parts), now_s_(std::move(now_s)), interval_ms_(interval_ms) {}

WearWorker::~WearWorker() {
  Stop();
}

void WearWorker::Start() {
  thread_ = std::thread([this] { Run(); });
}

void WearWorker::Stop() {
  {
    // Under the lock: the thread checks stop_ in its wait's predicate.
    std::lock_guard<std::mutex> lock(dirty_mutex_);
    stop_ = true;
  }
  dirty_cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void WearWorker::ReadingsChanged(const std::set<std::string>& crushers) {
  if (crushers.empty()) return;
  for (const std::string& c : crushers) {
    p_.wear.MarkChanged(c);
    p_.metrics.WearChanged(c, WallMs());
  }
  {
    std::lock_guard<std::mutex> lock(dirty_mutex_);
    dirty_.insert(crushers.begin(), crushers.end());
  }
  dirty_cv_.notify_one();
}

void WearWorker::Recompute(const std::string& crusher) {
  p_.metrics.WearChanged(crusher, WallMs());
  {
    std::lock_guard<std::mutex> lock(dirty_mutex_);
    dirty_.insert(crusher);
  }
  dirty_cv_.notify_one();
}

bool WearWorker::GatewayStatus(const mqtt::ParsedTopic& t, const std::string& payload) {
  std::string error;
  const auto status = mqtt::DecodeStatus(payload, &error);
  if (!status || !p_.registry.Find(t.crusher)) return false;
  const int64_t now_s = now_s_();
  int64_t since = now_s;
  if (const auto at = core::ParseIsoTime(status->time))
    since = std::min<int64_t>(now_s, std::chrono::duration_cast<std::chrono::seconds>(at->time_since_epoch()).count());
  p_.alarms.GatewayStatus(t.crusher, status->gateway.empty() ? std::string("gateway") : status->gateway, status->online, since);
  alarms_due_ = true;
  dirty_cv_.notify_one();
  return true;
}

void WearWorker::AlarmsChanged(const std::string& c) {
  const std::vector<AlarmRecord> open = p_.alarms.Open(c);
  p_.log("crusher " + c + ": alarms changed, " + std::to_string(open.size()) + " open");
  std::string message = AlarmsMessage(c, open, now_s_());
  p_.events.Publish(c, "alarm", message);
  std::lock_guard<std::mutex> lock(ready_mutex_);
  alarms_ready_.emplace_back(c, std::move(message));
}

StartupProgress WearWorker::Startup() const {
  return {p_.registry.All().size(), startup_loaded_.load(), startup_computed_.load()};
}

void WearWorker::PublishReady(mqtt::Publisher& link, const std::string& topic_root) {
  std::vector<std::pair<std::string, std::string>> wear, alarms;
  {
    std::lock_guard<std::mutex> lock(ready_mutex_);
    wear.swap(wear_ready_);
    alarms.swap(alarms_ready_);
  }
  for (const auto& [c, summary] : wear) {
    if (const auto site = p_.ingestor.SiteOf(c)) link.Publish({mqtt::Topics(*site, c, topic_root).Wear(), summary, 1, true});
  }
  alarm_outbox_.Flush(link);
  for (auto& [c, message] : alarms) {
    if (const auto site = p_.ingestor.SiteOf(c))
      alarm_outbox_.Send(link, {mqtt::Topics(*site, c, topic_root).Alarms(), std::move(message), 1, true});
  }
}

void WearWorker::EvaluateAlarms(const std::string& c, const CrusherState* st) {
  const Crusher* crusher = p_.registry.Find(c);
  if (!crusher) return;
  try {
    p_.alarms.Evaluate(c, GatherAlarmInputs(*crusher, p_.live, p_.ingestor, st, now_s_()));
  } catch (const std::exception& e) {
    p_.log("crusher " + c + ": alarms not evaluated: " + e.what());
  }
}

void WearWorker::EvaluateAllAlarms(bool force) {
  if (!force && !alarms_due_.exchange(false) && WallMs() - last_alarms_ms_ < kAlarmIntervalMs) return;
  last_alarms_ms_ = WallMs();
  for (const Crusher* c : p_.registry.All()) {
    if (stop_) return;
    EvaluateAlarms(c->config.crusher_id, p_.wear.Latest(c->config.crusher_id).get());
  }
}

void WearWorker::StartupPass() {
  // Each crusher's state and then at once its wear and forecast (not published: nothing changed),
  // crusher by crusher, so that each answers as soon as its own pass is done rather than after
  // every state of the fleet is loaded.
  int64_t load_ms = 0, load_cpu_ms = 0;
  for (const Crusher* c : p_.registry.All()) {
    if (stop_) return;
    const int64_t start_ms = WallMs(), start_cpu_ms = CpuMs(CLOCK_THREAD_CPUTIME_ID);
    p_.live.LatestUsableTime(c->config.crusher_id);  // loads it
    load_ms += WallMs() - start_ms;
    load_cpu_ms += CpuMs(CLOCK_THREAD_CPUTIME_ID) - start_cpu_ms;
    ++startup_loaded_;
    try {
      p_.wear.Get(c->config.crusher_id);
    } catch (const std::exception& e) {
      p_.log("crusher " + c->config.crusher_id + ": wear not computed: " + e.what());
    }
    ++startup_computed_;  // also when it failed: the pass has been there (its error is logged)
  }
  p_.log("per-crusher state loaded in " + std::to_string(load_ms) + " ms (" + std::to_string(load_cpu_ms) + " ms CPU)");
  starting_ = false;  // from now on a request may compute a crusher whose readings changed
  p_.log("wear and forecast of every crusher computed (process CPU since start: " +
         std::to_string(CpuMs(CLOCK_PROCESS_CPUTIME_ID)) + " ms)");
  // The open alarms as stored, retained again (a restart repeats none and loses none), then evaluated.
  for (const Crusher* c : p_.registry.All()) {
    const std::string& id = c->config.crusher_id;
    std::lock_guard<std::mutex> lock(ready_mutex_);
    alarms_ready_.emplace_back(id, AlarmsMessage(id, p_.alarms.Open(id), now_s_()));
  }
  EvaluateAllAlarms(true);
}

void WearWorker::ComputeAndHandBack(const std::string& c) {
  std::shared_ptr<const CrusherState> st;
  const auto started = std::chrono::steady_clock::now();
  const auto seconds = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count(); };
  SettleSettings(c);
  try {
    st = p_.wear.Get(c);
  } catch (const std::exception& e) {
    p_.metrics.WearDone(c, false, seconds(), WallMs());
    p_.log("crusher " + c + ": wear not computed: " + e.what());
    EvaluateAlarms(c, nullptr);
    return;
  }
  p_.metrics.WearDone(c, true, seconds(), WallMs());
  EvaluateAlarms(c, st.get());
  if (!st || !st->has_wear) return;
  std::string summary = mqtt::EncodeWear(WearJson(*st, false));
  p_.events.Publish(c, "wear", summary);
  std::lock_guard<std::mutex> lock(ready_mutex_);
  wear_ready_.emplace_back(c, std::move(summary));
}

bool WearWorker::SettleSettings(const std::string& c) {
  if (!p_.campaigns) return false;
  using Unknown = CampaignService::UnknownSettings;
  Unknown found = Unknown::kWaiting;
  std::string error;
  try {
    // A check posted before the readings of its time arrived counts once they have (the
    // setting_open alarm holds till then).
    found = p_.campaigns->EstimateUnknownSettings(c);
  } catch (const std::exception& e) {
    error = e.what();
  }
  // A failure is logged when it first happens and when it changes, not at every retry.
  if (std::string& last = settings_error_[c]; error != last) {
    if (!error.empty()) p_.log("crusher " + c + ": setting checks not estimated: " + error);
    last = error;
  }
  if (found == Unknown::kWaiting) {
    settings_waiting_.insert(c);
    return false;
  }
  settings_waiting_.erase(c);
  if (found != Unknown::kEstimated) return false;
  p_.log("crusher " + c + ": setting checks estimated from the readings now stored");
  return true;
}

void WearWorker::RetrySettings() {
  const auto now = std::chrono::steady_clock::now();
  if (settings_waiting_.empty() || now - last_settings_ < kSettingsRetry) return;
  last_settings_ = now;
  const std::set<std::string> waiting = settings_waiting_;
  for (const std::string& c : waiting) {
    if (stop_) return;
    if (SettleSettings(c)) Recompute(c);  // its wear and alarms count from the opening now known
  }
}

void WearWorker::Run() {
  pthread_setname_np(pthread_self(), "lw-wear");  // named in top -H, perf and lw_bench_ingest's CPU by thread
  StartupPass();
  int64_t last_ms = 0;
  while (!stop_) {
    std::set<std::string> work;
    {
      std::unique_lock<std::mutex> lock(dirty_mutex_);
      dirty_cv_.wait_for(lock, std::chrono::milliseconds(200), [&] { return stop_ || !dirty_.empty() || alarms_due_; });
      if (stop_) break;
      if (dirty_.empty()) {
        lock.unlock();
        RetrySettings();
        EvaluateAllAlarms(false);
        continue;
      }
      const int64_t wait_ms = last_ms + interval_ms_ - WallMs();
      if (wait_ms > 0) {
        lock.unlock();
        std::this_thread::sleep_for(std::chrono::milliseconds(std::min<int64_t>(wait_ms, 200)));
        continue;
      }
      work.swap(dirty_);
      for (const std::string& c : work) p_.metrics.WearTaken(c);
    }
    last_ms = WallMs();
    for (const std::string& c : work) ComputeAndHandBack(c);
    // Also when some crusher is always dirty (a busy fleet): a silent crusher's waiting checks and
    // its silence alarms are matters of time (both limit their own rate).
    RetrySettings();
    EvaluateAllAlarms(false);
  }
}

}  // namespace lw::server
