#include "server/server.hpp"

#include "core/file_lock.hpp"
#include "core/log.hpp"
#include "core/sd_notify.hpp"

#include <unistd.h>

#include <chrono>
#include <mutex>
#include <set>
#include <thread>

#include "core/clock.hpp"
#include "core/time.hpp"
#include "mqtt/mosquitto_link.hpp"
#include "mqtt/topics.hpp"
#include "server/alarms.hpp"
#include "server/campaigns.hpp"
#include "server/diagnosis_runner.hpp"
#include "server/health.hpp"
#include "server/http_api.hpp"
#include "server/ingest.hpp"
#include "server/live_state.hpp"
#include "server/metrics.hpp"
#include "server/mqtt_ingest.hpp"
#include "server/notify.hpp"
#include "server/registry.hpp"
#include "server/sse_events.hpp"
#include "server/store.hpp"
#include "server/wear_service.hpp"
#include "server/wear_worker.hpp"

namespace lw::server {
namespace {

int64_t WallMs() {
  return core::WallClockMs();
}

std::string Stamp() {
  return core::FormatIsoSeconds(WallMs() / 1000);
}

// Lines carry topics, sensor ids, times and error text from the broker and REST bodies: the one
// log mechanism (core/log.hpp) escapes them, and rate-limits what outsiders can repeat.
using Logger = core::Logger;

/// The rate-limit kind of an ingest log line: its first word ("rejected", "conflict", "crusher").
std::string IngestLogKind(const std::string& line) {
  return "ingest " + line.substr(0, line.find(' '));
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

/// The crushers of --crusher-dir, each logged (its skipped folders in `*errors`); throws when none loads.
std::unique_ptr<Registry> LoadRegistry(const ServerOptions& o, Logger& log, std::vector<std::string>* errors) {
  auto registry = Registry::Load(o.crusher_dir, errors);
  for (const auto& e : *errors) log("crusher folder skipped: " + e);
  if (registry->All().empty()) {
    throw std::runtime_error("--crusher-dir '" + o.crusher_dir + "': no crusher loaded" +
                             (errors->empty() ? std::string(" (no sub-folder holds a crusher.json)") : ": " + errors->front()));
  }
  for (const Crusher* c : registry->All()) {
    log("crusher " + c->config.crusher_id + ": " + std::to_string(c->config.sensors.size()) + " sensors, map " +
        std::to_string(c->map.face_count()) + " faces, sha256 " + c->map.sha256);
    for (const auto& w : c->validation.warnings) log("crusher " + c->config.crusher_id + ": map: " + w);
  }
  return registry;
}

/// Each crusher's running campaign (its relines, docs/campaigns.md) overrides crusher.json's
/// installed_at, thickness and sensors: applied before anything reads the registry.
void ApplyCampaigns(Registry& registry, Store& store, Logger& log) {
  std::vector<std::string> applied;
  ApplyStoredCampaigns(registry, store, &applied);
  for (const std::string& line : applied) log(line);
}

mqtt::LinkOptions BrokerLinkOptions(const ServerOptions& o) {
  mqtt::LinkOptions lo;
  lo.uri = o.broker;
  lo.client_id = o.client_id;
  lo.username = o.username;
  lo.password = o.password;
  lo.tls_ca = o.tls_ca;
  lo.clean_session = false;  // persistent session: the broker queues readings while we are away
  // Readings, and the gateways' retained status (their last will says offline) for the alarms.
  lo.subscriptions = {mqtt::Topics::ReadingsFilter(o.topic_root), mqtt::Topics::StatusFilter(o.topic_root)};
  return lo;
}

}  // namespace

void RunServer(const ServerOptions& o, const std::atomic<bool>& stop, std::ostream& log_stream) {
  Logger log(log_stream, "linerwatch-server", Stamp);
  if (::geteuid() == 0) {
    log("warning: running as root; run as an unprivileged user (the linerwatch-server package does; docs/deploy.md)");
  }
  std::vector<std::string> errors;
  const auto registry = LoadRegistry(o, log, &errors);
  TokenStore tokens;
  if (!o.tokens.empty()) tokens = TokenStore::Load(o.tokens);

  if (!WaitForWritableDatabase(o, stop, log, *registry, tokens)) return;
  // One server per database (two would both ack readings and fight over the wear). Destroyed
  // after the Stores below (declared before them).
  const core::ExclusiveFileLock db_lock(o.db, false, "linerwatch-server (one server per --db)");
  Store write(o.db);
  LockedStore read(std::make_unique<Store>(o.db));
  ApplyCampaigns(*registry, write, log);
  // Per-crusher state (counts, latest readings, wear and forecast inputs), loaded once here and kept
  // up to date by the ingestor as it commits: no request or recompute reads all of a crusher's readings.
  // Each crusher's is loaded the first time it is asked for; the wear worker asks for all of them
  // once as soon as the API is up, so the server answers while they load.
  LiveState live(*registry);
  live.LoadLazily(std::make_unique<Store>(o.db));
  // "now" for validation, commit acks and alarms: the simulator's clock file when given
  // (core::Clock: its last good value when the file turns bad, the wall clock before the first).
  const core::Clock clock(o.clock_file);
  const auto now_s = [&clock] { return clock.NowMs() / 1000; };
  Ingestor ingestor(write, *registry, now_s, &live);
  for (const std::string& w : ingestor.Warnings()) log(w);
  WearService wear(*registry, live);
  EventBus events;
  // The diagnosis loads every reading of a crusher, relines write campaigns and reload a crusher's
  // state, alarms (docs/alarms.md) are stored: each on a connection of its own, so REST reads do not wait.
  LockedStore diagnosis_store(std::make_unique<Store>(o.db));
  DiagnosisRunner diagnosis(*registry, diagnosis_store);
  LockedStore campaign_store(std::make_unique<Store>(o.db));
  CampaignService campaigns(*registry, campaign_store, live, wear, now_s,
                            [&log](const std::string& line) { log.Limited("setting checks", line); });
  LockedStore alarm_store(std::make_unique<Store>(o.db));
  AlarmEngine alarms(*registry, alarm_store);
  ServerMetrics metrics(o.db);
  // Notifications of each alarm event (docs/alarms.md, *Notifications*): queued and sent by a
  // thread of their own, so a slow or dead receiver delays neither ingest nor the wear worker.
  // Started before the wear worker and the API, the only callers of the alarm listener.
  Notifier notifier(
      o.notifications, o.db, [&log](const std::string& line) { log(line); }, &metrics);
  notifier.Start();
  // Joined on every way out of this function (an exception too), after the link's shutdown.
  WearWorker worker({*registry, live, wear, alarms, ingestor, events, metrics, log, &campaigns}, now_s, o.wear_interval_ms);
  alarms.OnChange([&](const std::string& c) {
    notifier.Wake();
    worker.AlarmsChanged(c);
  });
  const auto on_committed = [&](const IngestResult& r) {
    metrics.ObserveCommitted(r, now_s());
    PublishReadingEvents(events, r.new_readings);
    for (const auto& line : r.log) log.Limited(IngestLogKind(line), line);
    std::set<std::string> changed;
    for (const StoredReading& s : r.new_readings) changed.insert(s.crusher);
    worker.ReadingsChanged(changed);
  };
  mqtt::MosquittoLink link(BrokerLinkOptions(o));  // read on this thread: docs/performance.md, *Ingest*

  ApiContext ctx = MakeApiContext(o, *registry, read, wear, live, ingestor, events, tokens);
  ctx.diagnosis = &diagnosis;
  ctx.starting = worker.starting();
  ctx.metrics = &metrics;
  ctx.health = [&] {
    return HealthJson({ingestor.Counters(), metrics.broker_connected(), errors, worker.Startup(), NotWritable(o.db)});
  };
  ctx.after_ingest = on_committed;
  ctx.campaigns = &campaigns;
  ctx.alarms = &alarms;
  ctx.after_reline = [&](const std::string& crusher) {  // the new liner's wear, computed and published
    // The dashboard's campaign list reads .../campaigns again at this event (docs/dashboard.md).
    events.Publish(crusher, "campaign", CampaignEventData(crusher));
    worker.Recompute(crusher);
  };
  HttpApi api(ctx);
  log("listening on " + StartApi(api, o) + " (REST /api/v1, dashboard " +
      (o.web_dir.empty() ? std::string("not built") : o.web_dir) + ")");
  if (tokens.enabled()) log("bearer tokens required on /api");
  // Ready for systemd (Type=notify): database open, crushers loaded, HTTP serving. The broker is
  // connected (and reconnected) by the loop below.
  core::SdNotify("READY=1");
  worker.Start();

  MqttIngestLoop::Hooks hooks{
      .status = [&](const mqtt::ParsedTopic& t, const std::string& payload) { return worker.GatewayStatus(t, payload); },
      .committed = on_committed,
      .publish = [&](mqtt::Publisher& to) { worker.PublishReady(to, o.topic_root); }};
  MqttIngestLoop({o.broker, o.client_id, o.topic_root, o.batch_max, o.commit_delay_ms}, link, ingestor, metrics, log, now_s,
                 std::move(hooks))
      .Run(stop);
  log("stopping");
  core::SdNotify("STOPPING=1");
  notifier.Stop();  // a delivery under way is cancelled (it stays pending)
  api.Stop();
  link.Shutdown({}, 2000);
}

}  // namespace lw::server
