#include "server/server.hpp"

#include "core/file_lock.hpp"
#include "core/log.hpp"
#include "core/sd_notify.hpp"

#include <poll.h>
#include <pthread.h>
#include <time.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <thread>
#include <fstream>
#include <map>
#include <mutex>
#include <set>

#include "core/clock.hpp"
#include "core/time.hpp"
#include "mqtt/messages.hpp"
#include "mqtt/outbox.hpp"
#include "mqtt/mosquitto_link.hpp"
#include "mqtt/topics.hpp"
#include "server/alarms.hpp"
#include "server/diagnosis_runner.hpp"
#include "server/http_api.hpp"
#include "server/ingest.hpp"
#include "server/live_state.hpp"
#include "server/metrics.hpp"
#include "server/notify.hpp"
#include "server/campaigns.hpp"
#include "server/registry.hpp"
#include "server/store.hpp"
#include "server/wear_service.hpp"

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

std::string Stamp() {
  return core::FormatIsoTime(core::TimePoint(std::chrono::seconds(WallMs() / 1000)));
}

// Lines carry topics, sensor ids, times and error text from the broker and REST bodies: the one
// log mechanism (core/log.hpp) escapes them, and rate-limits what outsiders can repeat.
using Logger = core::Logger;

/// The rate-limit kind of an ingest log line: its first word ("rejected", "conflict", "crusher").
std::string IngestLogKind(const std::string& line) {
  return "ingest " + line.substr(0, line.find(' '));
}

constexpr int64_t kMinFreeBytes = 8 << 20;  // SQLite's WAL grows to ~4 MB; docs/server.md

std::string DiskFull(const std::string& db, int64_t free) {
  return "disk full: " + std::to_string(free) + " bytes free for " + db + " (the server needs at least " +
         std::to_string(kMinFreeBytes >> 20) + " MB)";
}

/// Why the database's file system takes no writes now: mounted read-only, or full; empty when it
/// takes them. Both are states an operator fixes without touching the database (a remount, space).
std::string NotWritable(const std::string& db) {
  if (OnReadOnlyFileSystem(db)) return "read-only file system: " + db + " is on a file system mounted read-only";
  if (const int64_t free = FreeBytes(db); free >= 0 && free < kMinFreeBytes) return DiskFull(db, free);
  return {};
}

/// The REST API's context over these parts (both the normal and the read-only start use it).
ApiContext MakeApiContext(const ServerOptions& o, const Registry& registry, LockedStore& read, WearService& wear,
                          const LiveState& live, Ingestor& ingestor, EventBus& events, const TokenStore& tokens) {
  ApiContext ctx;
  ctx.live = &live;
  ctx.registry = &registry;
  ctx.read = &read;
  ctx.wear = &wear;
  ctx.ingestor = &ingestor;
  ctx.events = &events;
  ctx.tokens = &tokens;
  ctx.web_dir = o.web_dir;
  ctx.allowed_hosts = o.allowed_hosts;
  ctx.allowed_hosts.push_back(o.http.substr(0, o.http.rfind(':')));  // the name it was told to listen on
  return ctx;
}

/// Binds --http and starts serving; returns "http://host:port/" (port 0: the one picked).
std::string StartApi(HttpApi& api, const ServerOptions& o) {
  const size_t colon = o.http.rfind(':');
  const int port = api.Bind(o.http.substr(0, colon), std::stoi(o.http.substr(colon + 1)));
  api.Start();
  return "http://" + o.http.substr(0, colon) + ":" + std::to_string(port) + "/";
}

/// A database that cannot be opened for writing because its file system is full or mounted
/// read-only: instead of exiting (and being restarted in a loop), serve what is stored read-only,
/// report /healthz "degraded" with the reason, take nothing from the broker (readings wait there and
/// in the gateways' spools, none is acknowledged; REST writes get 503) and retry every few seconds.
/// Returns true once the database opens for writing, false when stopped first. Any other failure to
/// open is thrown.
bool WaitForWritableDatabase(const ServerOptions& o, const std::atomic<bool>& stop, Logger& log, Registry& registry,
                             const TokenStore& tokens) {
  // On a read-only mount SQLite may open an up-to-date database without writing (and fail at the
  // first commit): the mount decides, not whether an open succeeds.
  const auto writable = [&] {
    if (OnReadOnlyFileSystem(o.db)) return false;
    Store probe(o.db);
    return true;
  };
  std::string reason;
  try {
    if (writable()) return true;
    reason = NotWritable(o.db);
    log(reason + "; serving stored data read-only and taking no readings until it is writable");
  } catch (const std::exception& e) {
    reason = NotWritable(o.db);
    if (reason.empty()) throw;
    log(reason + ": " + e.what() + "; serving stored data read-only and taking no readings until it is writable");
  }
  // The REST reads' connection, and one of the refusing ingestor's own (each Store one thread at a time).
  const auto open_read_only = [&](bool log_failure) {
    try {
      return Store::OpenReadOnly(o.db);
    } catch (const std::exception& e) {
      if (log_failure) log("read-only: " + std::string(e.what()) + "; serving no stored data");
      return std::make_unique<Store>(":memory:");  // empty, in memory: the API answers, nothing on disk
    }
  };
  std::unique_ptr<Store> read_store = open_read_only(true);
  std::vector<std::string> applied;  // the running campaigns' models (docs/campaigns.md), read-only too
  ApplyStoredCampaigns(registry, *read_store, &applied);
  for (const std::string& line : applied) log(line);
  LiveState live(registry);
  live.Rebuild(*read_store);
  LockedStore read(std::move(read_store));
  std::unique_ptr<Store> ingest_store = open_read_only(false);
  Ingestor refusing(*ingest_store, registry, [] { return WallMs() / 1000; });  // its Commit throws: 503, not stored
  WearService wear(registry, live);
  // The measured settings count here too (the CSS and its alarm), estimated without storing.
  read.With([&](Store& s) {
    if (const std::string failed = LoadSettingChecks(s, registry, wear, false); !failed.empty()) log(failed);
  });
  EventBus events;
  std::mutex reason_mutex;
  ServerMetrics metrics(o.db);
  ApiContext ctx = MakeApiContext(o, registry, read, wear, live, refusing, events, tokens);
  ctx.metrics = &metrics;
  ctx.health = [&] {
    std::lock_guard<std::mutex> lock(reason_mutex);
    return nlohmann::ordered_json{
        {"status", "degraded"}, {"reason", reason}, {"broker", "not subscribed (database not writable)"}};
  };
  HttpApi api(ctx);
  log("listening on " + StartApi(api, o) + " (read-only: " + reason + ")");
  for (int tick = 0; !stop; ++tick) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    if (tick % 25 != 24) continue;  // every 5 s
    try {
      if (writable()) {
        log("database " + o.db + " writable again: leaving read-only mode");
        return true;
      }
    } catch (const std::exception&) {
    }
    std::lock_guard<std::mutex> lock(reason_mutex);
    if (std::string now = NotWritable(o.db); !now.empty()) reason = std::move(now);
  }
  return false;
}

/// What the alarm rules of `crusher` look at now (`wear`: its latest state, may be null).
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
        crusher.config.OfThisLiner(s.id, core::TimePoint(std::chrono::seconds(it->second->time_s)), it->second->thickness_mm)) {
      sensor.latest_s = it->second->time_s;
      sensor.battery_mv = it->second->battery_mv;
    }
    in.sensors.push_back(std::move(sensor));
  }
  in.rejected_total = ingestor.CrusherCounters(crusher.config.crusher_id).rejected;
  return in;
}

/// A gateway's retained status (or last will) on `topic`: told to the alarm engine, for a known crusher.
/// Returns false when the message is not one (logged by the caller as any other message would be).
bool TakeGatewayStatus(const mqtt::ParsedTopic& t, const std::string& payload, const Registry& registry, AlarmEngine& alarms,
                       int64_t now_s) {
  std::string error;
  const auto status = mqtt::DecodeStatus(payload, &error);
  if (!status || !registry.Find(t.crusher)) return false;
  int64_t since = now_s;
  if (const auto at = core::ParseIsoTime(status->time))
    since = std::min<int64_t>(now_s, std::chrono::duration_cast<std::chrono::seconds>(at->time_since_epoch()).count());
  alarms.GatewayStatus(t.crusher, status->gateway.empty() ? std::string("gateway") : status->gateway, status->online, since);
  return true;
}

}  // namespace

void RunServer(const ServerOptions& o, const std::atomic<bool>& stop, std::ostream& log_stream) {
  Logger log(log_stream, "linerwatch-server", Stamp);
  if (::geteuid() == 0) {
    log("warning: running as root; run as an unprivileged user (the linerwatch-server package does; docs/deploy.md)");
  }
  std::vector<std::string> errors;
  const auto registry = Registry::Load(o.crusher_dir, &errors);
  for (const auto& e : errors) log("crusher folder skipped: " + e);
  if (registry->All().empty()) {
    throw std::runtime_error("--crusher-dir '" + o.crusher_dir + "': no crusher loaded" +
                             (errors.empty() ? std::string(" (no sub-folder holds a crusher.json)") : ": " + errors.front()));
  }
  for (const Crusher* c : registry->All()) {
    log("crusher " + c->config.crusher_id + ": " + std::to_string(c->config.sensors.size()) + " sensors, map " +
        std::to_string(c->map.face_count()) + " faces, sha256 " + c->map.sha256);
    for (const auto& w : c->validation.warnings) log("crusher " + c->config.crusher_id + ": map: " + w);
  }
  TokenStore tokens;
  if (!o.tokens.empty()) tokens = TokenStore::Load(o.tokens);

  if (!WaitForWritableDatabase(o, stop, log, *registry, tokens)) return;
  // One server per database (two would both ack readings and fight over the wear). Destroyed
  // after the Stores below (declared before them).
  const core::ExclusiveFileLock db_lock(o.db, false, "linerwatch-server (one server per --db)");
  Store write(o.db);
  LockedStore read(std::make_unique<Store>(o.db));
  // Each crusher's running campaign (its relines, docs/campaigns.md) overrides crusher.json's
  // installed_at, thickness and sensors, before anything reads the registry.
  {
    std::vector<std::string> applied;
    ApplyStoredCampaigns(*registry, write, &applied);
    for (const std::string& line : applied) log(line);
  }
  // Per-crusher state (counts, latest readings, wear and forecast inputs), loaded once here and kept
  // up to date by the ingestor as it commits: no request or recompute reads all of a crusher's readings.
  // Each crusher's is loaded the first time it is asked for; the wear worker asks for all of them
  // once as soon as the API is up, so the server answers while they load.
  LiveState live(*registry);
  live.LoadLazily(std::make_unique<Store>(o.db));
  // "now" for validation and commit acks: the simulator's clock file when given (core::Clock: its
  // last good value when the file turns bad, the wall clock before the first).
  const core::Clock clock(o.clock_file);
  Ingestor ingestor(
      write, *registry, [&clock] { return clock.NowMs() / 1000; }, &live);
  for (const std::string& w : ingestor.Warnings()) log(w);
  WearService wear(*registry, live);
  EventBus events;
  // The diagnosis loads every reading of a crusher: on its own connection, so REST reads do not wait for it.
  LockedStore diagnosis_store(std::make_unique<Store>(o.db));
  DiagnosisRunner diagnosis(*registry, diagnosis_store);
  // Relines write campaigns and reload a crusher's state: on a connection of their own.
  LockedStore campaign_store(std::make_unique<Store>(o.db));
  CampaignService campaigns(*registry, campaign_store, live, wear, [&clock] { return clock.NowMs() / 1000; });

  // Alarms (docs/alarms.md): on a connection of their own; evaluated by the wear worker below. Each
  // change goes out as an SSE `alarm` event and, from the MQTT loop, as the retained `.../alarms`.
  LockedStore alarm_store(std::make_unique<Store>(o.db));
  AlarmEngine alarms(*registry, alarm_store);
  std::mutex computed_mutex;
  std::vector<std::pair<std::string, std::string>> computed;        // (crusher, wear summary JSON)
  std::vector<std::pair<std::string, std::string>> alarm_messages;  // (crusher, its open alarms JSON)
  // Notifications of each alarm event (docs/alarms.md, *Notifications*): queued and sent by a
  // thread of their own, so a slow or dead receiver delays neither ingest nor the wear worker.
  std::unique_ptr<Notifier> notifier;
  alarms.OnChange([&](const std::string& c) {
    if (notifier) notifier->Wake();
    const std::vector<AlarmRecord> open = alarms.Open(c);
    log("crusher " + c + ": alarms changed, " + std::to_string(open.size()) + " open");
    std::string message = AlarmsMessage(c, open, clock.NowMs() / 1000);
    events.Publish(c, "alarm", message);
    std::lock_guard<std::mutex> lock(computed_mutex);
    alarm_messages.emplace_back(c, std::move(message));
  });
  std::atomic<bool> alarms_due{false};  // a gateway's status changed: evaluate every crusher's alarms

  std::mutex dirty_mutex;
  std::condition_variable dirty_cv;
  std::set<std::string> dirty;  // crushers whose wear must be recomputed and published
  ServerMetrics metrics(o.db);
  // Created before the wear worker and the API start, which are the only callers of the listener.
  notifier = std::make_unique<Notifier>(
      o.notifications, o.db, [&log](const std::string& line) { log(line); }, &metrics);
  notifier->Start();
  const auto on_committed = [&](const IngestResult& r) {
    metrics.ObserveCommitted(r, clock.NowMs() / 1000);
    std::set<std::string> changed;
    for (const StoredReading& s : r.new_readings) {
      events.PublishLazy(s.crusher, "reading", [payload = s.payload, sensor = s.sensor, time_s = s.time_s] {
        nlohmann::json j = nlohmann::json::parse(payload, nullptr, false);
        if (!j.is_object()) j = nlohmann::json::object();
        j["sensor"] = sensor;
        j["time"] = core::FormatIsoTime(core::TimePoint(std::chrono::seconds(time_s)));
        return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
      });
      changed.insert(s.crusher);
    }
    for (const auto& line : r.log) log.Limited(IngestLogKind(line), line);
    for (const auto& c : changed) {
      wear.MarkChanged(c);
      metrics.WearChanged(c, WallMs());
    }
    {
      std::lock_guard<std::mutex> lock(dirty_mutex);
      dirty.insert(changed.begin(), changed.end());
    }
    if (!changed.empty()) dirty_cv.notify_one();
  };

  mqtt::LinkOptions lo;
  lo.uri = o.broker;
  lo.client_id = o.client_id;
  lo.username = o.username;
  lo.password = o.password;
  lo.tls_ca = o.tls_ca;
  lo.clean_session = false;  // persistent session: the broker queues readings while we are away
  // Readings, and the gateways' retained status (their last will says offline) for the alarms.
  lo.subscriptions = {mqtt::Topics::ReadingsFilter(o.topic_root), mqtt::Topics::StatusFilter(o.topic_root)};
  mqtt::MosquittoLink link(lo);  // read on this thread: docs/performance.md, *Ingest*

  // The wear worker's first pass (every crusher loaded, then computed), for /healthz: until it ends
  // the crusher list says "pending" for crushers it has not reached.
  std::atomic<size_t> startup_loaded{0}, startup_computed{0};
  std::atomic<bool> starting{true};
  ApiContext ctx = MakeApiContext(o, *registry, read, wear, live, ingestor, events, tokens);
  ctx.diagnosis = &diagnosis;
  ctx.starting = &starting;
  ctx.metrics = &metrics;
  ctx.health = [&] {
    const IngestCounters c = ingestor.Counters();
    nlohmann::ordered_json j{{"broker", metrics.broker_connected() ? "connected" : "disconnected"},
                             {"readings_stored", c.stored},
                             {"duplicates", c.duplicates},
                             {"rejected", c.rejected},
                             {"held", c.held},
                             {"crusher_errors", errors}};
    const size_t crushers = registry->All().size();
    j["startup"] = {{"crushers", crushers},
                    {"loaded", startup_loaded.load()},
                    {"computed", startup_computed.load()},
                    {"done", startup_computed.load() >= crushers}};
    // Batches fail (and are not acked) once the disk fills or is remounted read-only: say why
    // before the gateways' spools grow.
    if (std::string why = NotWritable(o.db); !why.empty()) {
      j["status"] = "degraded";
      j["reason"] = std::move(why);
    }
    return j;
  };
  ctx.after_ingest = on_committed;
  ctx.campaigns = &campaigns;
  ctx.alarms = &alarms;
  ctx.after_reline = [&](const std::string& crusher) {  // the new liner's wear, computed and published
    // The dashboard's campaign list reads .../campaigns again at this event (docs/dashboard.md).
    events.Publish(crusher, "campaign", nlohmann::ordered_json({{"crusher", crusher}}).dump());
    metrics.WearChanged(crusher, WallMs());
    {
      std::lock_guard<std::mutex> lock(dirty_mutex);
      dirty.insert(crusher);
    }
    dirty_cv.notify_one();
  };
  HttpApi api(ctx);
  log("listening on " + StartApi(api, o) + " (REST /api/v1, dashboard " +
      (o.web_dir.empty() ? std::string("not built") : o.web_dir) + ")");
  if (tokens.enabled()) log("bearer tokens required on /api");
  // Ready for systemd (Type=notify): database open, crushers loaded, HTTP serving. The broker is
  // connected (and reconnected) by the loop below.
  core::SdNotify("READY=1");

  // Wear is recomputed on its own thread (at most every --wear-interval-ms), so a large map or a
  // long campaign never delays commit acks; this loop only publishes the summaries it hands back.
  std::atomic<bool> worker_stop{false};
  // Every crusher's alarms, at most every kAlarmIntervalMs (silence and offline gateways are
  // matters of time, not of new readings) and when a gateway's status changed; a crusher whose wear
  // was just recomputed is evaluated right after it.
  constexpr int64_t kAlarmIntervalMs = 10'000;
  int64_t last_alarms_ms = 0;
  const auto evaluate_alarms = [&](const std::string& c, const CrusherState* st) {
    const Crusher* crusher = registry->Find(c);
    if (!crusher) return;
    try {
      alarms.Evaluate(c, GatherAlarmInputs(*crusher, live, ingestor, st, clock.NowMs() / 1000));
    } catch (const std::exception& e) {
      log("crusher " + c + ": alarms not evaluated: " + e.what());
    }
  };
  const auto evaluate_all_alarms = [&](bool force) {
    if (!force && !alarms_due.exchange(false) && WallMs() - last_alarms_ms < kAlarmIntervalMs) return;
    last_alarms_ms = WallMs();
    for (const Crusher* c : registry->All()) {
      if (worker_stop) return;
      evaluate_alarms(c->config.crusher_id, wear.Latest(c->config.crusher_id).get());
    }
  };
  std::thread wear_worker([&] {
    pthread_setname_np(pthread_self(), "lw-wear");  // named in top -H, perf and lw_bench_ingest's CPU by thread
    // Once at startup, each crusher's state and then at once its wear and forecast (not published:
    // nothing changed), crusher by crusher, so that each answers as soon as its own pass is done
    // rather than after every state of the fleet is loaded.
    int64_t load_ms = 0, load_cpu_ms = 0;
    for (const Crusher* c : registry->All()) {
      if (worker_stop) return;
      const int64_t start_ms = WallMs(), start_cpu_ms = CpuMs(CLOCK_THREAD_CPUTIME_ID);
      live.LatestUsableTime(c->config.crusher_id);  // loads it
      load_ms += WallMs() - start_ms;
      load_cpu_ms += CpuMs(CLOCK_THREAD_CPUTIME_ID) - start_cpu_ms;
      ++startup_loaded;
      try {
        wear.Get(c->config.crusher_id);
      } catch (const std::exception& e) {
        log("crusher " + c->config.crusher_id + ": wear not computed: " + e.what());
      }
      ++startup_computed;  // also when it failed: the pass has been there (its error is logged)
    }
    log("per-crusher state loaded in " + std::to_string(load_ms) + " ms (" + std::to_string(load_cpu_ms) + " ms CPU)");
    starting = false;  // from now on a request may compute a crusher whose readings changed
    log("wear and forecast of every crusher computed (process CPU since start: " +
        std::to_string(CpuMs(CLOCK_PROCESS_CPUTIME_ID)) + " ms)");
    // The open alarms as stored, retained again (a restart repeats none and loses none), then evaluated.
    for (const Crusher* c : registry->All()) {
      const std::string& id = c->config.crusher_id;
      std::lock_guard<std::mutex> lock(computed_mutex);
      alarm_messages.emplace_back(id, AlarmsMessage(id, alarms.Open(id), clock.NowMs() / 1000));
    }
    evaluate_all_alarms(true);
    int64_t last_ms = 0;
    while (!worker_stop) {
      std::set<std::string> work;
      {
        std::unique_lock<std::mutex> lock(dirty_mutex);
        dirty_cv.wait_for(lock, std::chrono::milliseconds(200), [&] { return worker_stop || !dirty.empty() || alarms_due; });
        if (worker_stop) break;
        if (dirty.empty()) {
          lock.unlock();
          evaluate_all_alarms(false);
          continue;
        }
        const int64_t wait_ms = last_ms + o.wear_interval_ms - WallMs();
        if (wait_ms > 0) {
          lock.unlock();
          std::this_thread::sleep_for(std::chrono::milliseconds(std::min<int64_t>(wait_ms, 200)));
          continue;
        }
        work.swap(dirty);
        for (const std::string& c : work) metrics.WearTaken(c);
      }
      last_ms = WallMs();
      for (const std::string& c : work) {
        std::shared_ptr<const CrusherState> st;
        const auto started = std::chrono::steady_clock::now();
        const auto seconds = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count(); };
        try {
          st = wear.Get(c);
        } catch (const std::exception& e) {
          metrics.WearDone(c, false, seconds(), WallMs());
          log("crusher " + c + ": wear not computed: " + e.what());
          evaluate_alarms(c, nullptr);
          continue;
        }
        metrics.WearDone(c, true, seconds(), WallMs());
        evaluate_alarms(c, st.get());
        if (!st || !st->has_wear) continue;
        std::string summary = mqtt::EncodeWear(WearJson(*st, false));
        events.Publish(c, "wear", summary);
        std::lock_guard<std::mutex> lock(computed_mutex);
        computed.emplace_back(c, std::move(summary));
      }
    }
  });

  // Stops and joins the worker on every way out of this function (an exception too).
  struct JoinWorker {
    std::atomic<bool>& stop;
    std::condition_variable& cv;
    std::thread& thread;
    ~JoinWorker() {
      stop = true;
      cv.notify_all();
      if (thread.joinable()) thread.join();
    }
  } join_worker{worker_stop, dirty_cv, wear_worker};

  int64_t last_stats_ms = WallMs();
  IngestCounters last_counters;
  // Messages on topics that are not readings (the broker sends only what the subscription matches:
  // one of these is a broken broker, a man in the middle or a misconfigured bridge) are ignored and
  // logged, at most kIgnoredLogged lines a minute; the rest are counted in the minute's stats line.
  constexpr int kIgnoredLogged = 10;
  int ignored_logged = 0;
  uint64_t ignored_unlogged = 0;
  const std::string readings_filter = mqtt::Topics::ReadingsFilter(o.topic_root);
  // Drains the link: connection events are logged, reading messages appended to `batch`.
  const auto collect = [&](int64_t now_ms, std::vector<Incoming>* batch) {
    std::vector<mqtt::LinkEvent> polled = link.Poll(now_ms);
    if (batch->capacity() < batch->size() + polled.size()) batch->reserve(2 * (batch->size() + polled.size()));
    for (mqtt::LinkEvent& e : polled) {
      if (e.kind == mqtt::LinkEvent::Kind::kConnected) {
        metrics.SetBrokerConnected(true);
        log("connected to " + o.broker + " as " + o.client_id);
      } else if (e.kind == mqtt::LinkEvent::Kind::kDisconnected) {
        metrics.SetBrokerConnected(false);
        log("broker: " + e.payload);
      } else if (auto t = mqtt::Topics::ParseAny(e.topic, o.topic_root); t && t->kind == mqtt::TopicKind::kReading) {
        batch->push_back({std::move(t->site), std::move(t->crusher), std::move(t->id), std::move(e.topic), std::move(e.payload)});
      } else if (t && t->kind == mqtt::TopicKind::kStatus &&
                 TakeGatewayStatus(*t, e.payload, *registry, alarms, clock.NowMs() / 1000)) {
        alarms_due = true;
        dirty_cv.notify_one();
      } else if (ignored_logged < kIgnoredLogged) {
        ++ignored_logged;
        // Topics are UTF-8 without control characters (the link refuses others); long ones are cut
        // at a character's start.
        std::string topic = e.topic;
        if (topic.size() > 200) {
          size_t cut = 200;
          while (cut > 0 && (static_cast<unsigned char>(topic[cut]) & 0xC0) == 0x80) --cut;
          topic = topic.substr(0, cut) + "... (" + std::to_string(e.topic.size()) + " bytes)";
        }
        log("broker: message on '" + topic + "' ignored (" + std::to_string(e.payload.size()) +
            " bytes): not a reading topic; the server subscribes to " + readings_filter + " only");
      } else {
        ++ignored_unlogged;
      }
    }
  };
  // Commit acks the link refused (not connected) wait here and go
  // first at the next turn, instead of being dropped (the gateway would wait for its republication).
  mqtt::Outbox acks;
  mqtt::Outbox alarm_outbox(10'000);
  uint64_t acks_dropped_logged = 0;
  // Kept from turn to turn with its room: grown from empty at each turn, it moved every message it
  // held (five strings each) at each doubling (3 % of the server's CPU at 7,000 messages a second).
  std::vector<Incoming> batch;
  while (!stop) {
    const int64_t now = WallMs();
    acks.Flush(link);
    metrics.SetAcksDropped(acks.dropped());
    if (acks.dropped() != acks_dropped_logged) {
      log("commit acks waiting for the broker beyond " + std::to_string(acks.size()) + ": dropped the oldest " +
          std::to_string(acks.dropped() - acks_dropped_logged) + " (their gateways republish those records)");
      acks_dropped_logged = acks.dropped();
    }
    batch.clear();
    collect(now, &batch);
    // Group commit: one fsync'ed transaction per batch, so when readings are arriving give the
    // next ones commit_delay_ms to join this one instead of committing them one by one. The whole
    // delay, not until the next message: woken at each arrival, committing then made transactions
    // of ~70 readings at 7,000 a second, and SQLite rewrote each touched page to the WAL every few.
    // Checked every millisecond (a full batch commits at once), not at every arrival: a wake-up
    // per message cost the main loop a poll and a context switch each.
    if (!batch.empty() && o.commit_delay_ms > 0) {
      using Steady = std::chrono::steady_clock;  // a wall-clock step must not stretch the wait
      const Steady::time_point deadline = Steady::now() + std::chrono::milliseconds(o.commit_delay_ms);
      while (batch.size() < static_cast<size_t>(o.batch_max)) {
        const Steady::time_point now_steady = Steady::now();
        if (now_steady >= deadline) break;
        std::this_thread::sleep_for(std::min<Steady::duration>(deadline - now_steady, std::chrono::milliseconds(1)));
        collect(WallMs(), &batch);
      }
    }
    for (size_t start = 0; start < batch.size(); start += static_cast<size_t>(o.batch_max)) {
      const size_t end = std::min(batch.size(), start + static_cast<size_t>(o.batch_max));
      std::vector<Incoming> part(std::make_move_iterator(batch.begin() + static_cast<std::ptrdiff_t>(start)),
                                 std::make_move_iterator(batch.begin() + static_cast<std::ptrdiff_t>(end)));
      IngestResult r;
      try {
        r = ingestor.Ingest(std::move(part));
      } catch (const std::exception& e) {
        // Nothing of the batch is stored and nothing is acked: the gateway republishes it.
        log(std::string("database error, batch not stored (the gateway will resend it): ") + e.what());
        continue;
      }
      const std::string when = core::FormatIsoTime(core::TimePoint(std::chrono::seconds(clock.NowMs() / 1000)));
      for (const Ack& a : r.acks) {
        metrics.CountAcked(a.seqs.size());
        const std::string topic = mqtt::Topics(a.site, a.crusher, o.topic_root).Committed(a.sensor);
        // Seqs are validated to 0..2^32-1 before they are stored or acked.
        for (std::string& m : mqtt::EncodeCommitAcks({a.sensor, {a.seqs.begin(), a.seqs.end()}, when, mqtt::kMaxReadingBatch})) {
          acks.Send(link, {topic, std::move(m), 1, false});
        }
      }
      on_committed(r);
    }
    std::vector<std::pair<std::string, std::string>> ready, ready_alarms;
    {
      std::lock_guard<std::mutex> lock(computed_mutex);
      ready.swap(computed);
      ready_alarms.swap(alarm_messages);
    }
    // Retained wear and alarms go only to the crusher's own site (crusher.json's "site" or the first
    // site heard from), never to a site name a stray publisher made up.
    for (const auto& [c, summary] : ready) {
      if (const auto site = ingestor.SiteOf(c)) link.Publish({mqtt::Topics(*site, c, o.topic_root).Wear(), summary, 1, true});
    }
    // Alarm sets wait in their outbox while the broker is away (never dropped: the latest is sent last).
    alarm_outbox.Flush(link);
    for (auto& [c, message] : ready_alarms) {
      if (const auto site = ingestor.SiteOf(c))
        alarm_outbox.Send(link, {mqtt::Topics(*site, c, o.topic_root).Alarms(), std::move(message), 1, true});
    }
    if (now - last_stats_ms >= 60'000) {
      const IngestCounters c = ingestor.Counters();
      if (c.stored != last_counters.stored || c.rejected != last_counters.rejected || c.duplicates != last_counters.duplicates) {
        log("stored " + std::to_string(c.stored) + ", duplicates " + std::to_string(c.duplicates) + ", rejected " +
            std::to_string(c.rejected) + " since start");
      }
      last_counters = c;
      last_stats_ms = now;
      if (ignored_unlogged > 0) {
        log("broker: " + std::to_string(ignored_unlogged) + " more messages on topics that are not readings ignored");
      }
      ignored_logged = 0;
      ignored_unlogged = 0;
    }
    pollfd pfd{link.wake_fd(), POLLIN, 0};
    ::poll(&pfd, 1, 20);
  }
  log("stopping");
  core::SdNotify("STOPPING=1");
  notifier->Stop();  // before the metrics it counts into go (they are declared after it)
  api.Stop();
  link.Shutdown({}, 2000);
}

}  // namespace lw::server
