#pragma once
// A crusher folder made by the campaign generator (crusher.json, wear_map.vtk, readings.csv) in a
// scratch directory, and helpers to turn its readings into reading messages (docs/mqtt.md).
#include <nlohmann/json.hpp>

#include <algorithm>
#include <climits>
#include <memory>
#include <string>
#include <vector>

#include "core/bundle.hpp"
#include "core/reconstruction.hpp"
#include "core/scan_correction.hpp"
#include "core/thinnest_area.hpp"
#include "core/wear_map.hpp"  // Sha256Hex
#include "server/api_context.hpp"
#include "server/ingest.hpp"
#include "server/registry.hpp"
#include "server/rest.hpp"
#include "sim/campaign.hpp"
#include "support/mosquitto_fixture.hpp"

namespace lw::test {

/// `r` with its JSON in r.json also when the resource sent JSON serialized ahead (a state's wear
/// and forecast bodies, server::CrusherState): what a client parses from the response.
inline server::rest::Response WithJson(server::rest::Response r) {
  if (r.raw && r.raw->content_type == "application/json") r.json = nlohmann::ordered_json::parse(r.raw->content);
  return r;
}

struct CrusherFolder {
  TempDirectory dir{"lw-server-test"};
  std::string crushers;  // the --crusher-dir
  std::string folder;    // crushers/demo
  core::Bundle bundle;   // as loaded back from the folder

  /// `scan_day` < 0: the generator's default (the last day).
  explicit CrusherFolder(double days = 30, uint64_t seed = 7, double scan_day = -1) {
    sim::CampaignSpec spec;
    spec.days = days;
    spec.scan_day = scan_day;
    crushers = dir.File("crushers");
    folder = crushers + "/demo";
    sim::GenerateCampaign(spec, seed).WriteBundle(folder);
    bundle = core::LoadBundle(folder);
  }
  std::string id() const { return bundle.crusher.crusher_id; }
};

/// The time (unix s) of the bundle's latest reading: readings.csv is not in time order, so its last
/// row is not the latest (and an ingest "now" before a reading by more than
/// server::kFutureSlackS holds it).
inline int64_t LatestReadingS(const core::Bundle& b) {
  int64_t latest = INT64_MIN;
  for (const core::Reading& r : b.readings) latest = std::max<int64_t>(latest, r.time.time_since_epoch().count());
  return latest;
}

/// The bundle's readings as reading messages with per-sensor seqs 1, 2, ... (file order by time).
inline std::vector<server::Incoming> Messages(const core::Bundle& b, const std::string& site = "site1") {
  std::vector<server::Incoming> out;
  std::map<std::string, int64_t> seq;
  for (const core::Reading& r : b.readings) {
    const nlohmann::json j = {{"sensor", r.sensor_id},
                              {"seq", ++seq[r.sensor_id]},
                              {"time", core::FormatIsoTime(r.time)},
                              {"thickness_mm", r.thickness_mm},
                              {"loops_intact", static_cast<int>(r.thickness_mm)},
                              {"flags", 0},
                              {"battery_mv", 3550}};
    out.push_back({site, b.crusher.crusher_id, r.sensor_id,
                   "linerwatch/v1/" + site + "/" + b.crusher.crusher_id + "/sensors/" + r.sensor_id + "/reading", j.dump()});
  }
  return out;
}

/// Live wear as the server and `linerwatch reconstruct` compute it offline from the bundle: the map
/// model, corrected by the newest scan when the bundle has one (docs/server.md), at time `at`.
inline core::Reconstruction OfflineLiveWear(const core::Bundle& b, core::TimePoint at) {
  core::ReconstructionPlan plan = core::PrepareReconstruction(b.crusher, b.map);
  if (const core::Scan* scan = core::LatestScanAt(b.scans, core::TimePoint::max()))
    core::ApplyScan(plan, core::ProjectScanToFaces(b.map, *scan), core::FreshSensorWearAt(b.crusher, b.readings, scan->date));
  return core::Reconstruct(plan,
                           core::SensorWearFrom(b.crusher, b.readings, core::LiveReadingIndices(b.crusher, b.readings, at)));
}

/// The thinnest areas of OfflineLiveWear (core::FindThinnestAreas on the same plan and readings).
inline core::ThinnestAreas OfflineThinnestAreas(const core::Bundle& b, core::TimePoint at) {
  core::ReconstructionPlan plan = core::PrepareReconstruction(b.crusher, b.map);
  if (const core::Scan* scan = core::LatestScanAt(b.scans, core::TimePoint::max()))
    core::ApplyScan(plan, core::ProjectScanToFaces(b.map, *scan), core::FreshSensorWearAt(b.crusher, b.readings, scan->date));
  const std::vector<size_t> live = core::LiveReadingIndices(b.crusher, b.readings, at);
  std::vector<core::Reading> used;
  for (const size_t i : live) used.push_back(b.readings[i]);
  return core::FindThinnestAreas(plan, core::Reconstruct(plan, core::SensorWearFrom(b.crusher, b.readings, live)), used);
}

/// A server's worth of parts over the crusher folder `crushers` (a fresh database in a scratch
/// directory) and the ApiContext over them: what HttpApi and rest::Resources serve from.
struct ServerParts {
  static constexpr const char* kReadToken = "reader-secret";
  static constexpr const char* kWriteToken = "writer-secret";

  TempDirectory dir{"lw-api"};
  std::string db_path;  ///< the database: in `dir`, or the one given (a restart on the same file)
  std::unique_ptr<server::Registry> registry;
  server::Store write{db_path};
  server::LockedStore read{std::make_unique<server::Store>(db_path)};
  server::LockedStore campaign_store{std::make_unique<server::Store>(db_path)};
  server::LockedStore alarm_store{std::make_unique<server::Store>(db_path)};
  std::unique_ptr<server::LiveState> live;
  std::unique_ptr<server::Ingestor> ingestor;
  std::unique_ptr<server::WearService> wear;
  server::EventBus events;
  std::unique_ptr<server::DiagnosisRunner> diagnosis;
  std::unique_ptr<server::CampaignService> campaigns;
  std::unique_ptr<server::AlarmEngine> alarms;  ///< evaluated by the test (the server's wear worker does it)
  std::vector<std::string> campaign_log;        ///< what ApplyStoredCampaigns did at "startup"
  server::TokenStore tokens;
  server::ApiContext ctx;

  /// `with_tokens`: tokens "reader" (kReadToken, read) and "writer" (kWriteToken, read and write).
  /// Readings posted through the API mark the wear changed and publish a `reading` event.
  /// `db`: the database file to open (empty: a fresh one in `dir`), as a server restarted on it would.
  ServerParts(const std::string& crushers, bool with_tokens, const std::string& web_dir = "", const std::string& db = "")
      : db_path(db.empty() ? dir.File("db.sqlite") : db) {
    std::vector<std::string> errors;
    registry = server::Registry::Load(crushers, &errors);
    server::ApplyStoredCampaigns(*registry, write, &campaign_log);
    live = std::make_unique<server::LiveState>(*registry);
    read.With([&](server::Store& s) { live->Rebuild(s); });
    ingestor = std::make_unique<server::Ingestor>(
        write, *registry, [] { return int64_t{4'000'000'000}; }, live.get());
    wear = std::make_unique<server::WearService>(*registry, *live);
    diagnosis = std::make_unique<server::DiagnosisRunner>(*registry, read);
    campaigns =
        std::make_unique<server::CampaignService>(*registry, campaign_store, *live, *wear, [] { return int64_t{4'000'000'000}; });
    alarms = std::make_unique<server::AlarmEngine>(*registry, alarm_store);
    alarms->OnChange([this](const std::string& c) { events.Publish(c, "alarm", server::AlarmsMessage(c, alarms->Open(c), 0)); });
    if (with_tokens) {
      tokens.Add({"reader", core::Sha256Hex(kReadToken), true, false});
      tokens.Add({"writer", core::Sha256Hex(kWriteToken), true, true});
    }
    ctx.registry = registry.get();
    ctx.read = &read;
    ctx.wear = wear.get();
    ctx.live = live.get();
    ctx.ingestor = ingestor.get();
    ctx.events = &events;
    ctx.diagnosis = diagnosis.get();
    ctx.campaigns = campaigns.get();
    ctx.alarms = alarms.get();
    ctx.tokens = &tokens;
    ctx.web_dir = web_dir;
    ctx.after_ingest = [this](const server::IngestResult& r) {
      for (const auto& s : r.new_readings) {
        wear->MarkChanged(s.crusher);
        events.Publish(s.crusher, "reading", nlohmann::json{{"sensor", s.sensor}, {"seq", s.seq}}.dump());
      }
    };
  }
};

}  // namespace lw::test
