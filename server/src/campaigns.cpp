#include "server/campaigns.hpp"

#include <chrono>
#include <algorithm>
#include <cmath>

#include "core/bundle.hpp"
#include "core/wear_map.hpp"
#include "mqtt/messages.hpp"
#include "server/ingest.hpp"
#include "server/rest.hpp"  // kMaxSmallBodyDepth

namespace lw::server {
namespace {

using nlohmann::json;
using nlohmann::ordered_json;

/// `config`'s sensors as crusher.json sensor objects (core::CrusherConfigJson's, so they read back the same).
json SensorsJson(const core::CrusherConfig& config) {
  return json::parse(core::CrusherConfigJson(config))["sensors"];
}

/// The campaign crusher.json describes: before a crusher's first reline, its only one.
CampaignRecord FolderCampaign(const core::CrusherConfig& config) {
  CampaignRecord c;
  c.start_s = core::ToUnixSeconds(config.installed_at);
  c.thickness_new_mm = config.thickness_new_mm;
  c.sensors_json = SensorsJson(config).dump();
  c.final_readings_json = "[]";
  return c;
}

/// Each sensor's last reading of the liner `config` describes, up to `end_s` (usable readings only:
/// a fault or a previous liner's is not its last thickness), as a JSON array.
std::string FinalReadings(Store& store, const core::CrusherConfig& config, int64_t end_s) {
  json out = json::array();
  for (const core::SensorInfo& s : config.sensors) {
    std::optional<StoredReading> last;
    store.Walk(config.crusher_id, s.id, core::ToUnixSeconds(config.LinerStart()), end_s, true, [&](const StoredReading& r) {
      if (!UsableForWear(config, r)) return true;
      last = r;
      return false;
    });
    if (last) {
      out.push_back({{"sensor", s.id},
                     {"time", core::FormatIsoSeconds(last->time_s)},
                     {"thickness_mm", last->thickness_mm},
                     {"seq", last->seq}});
    }
  }
  return out.dump();
}

/// Refuses a new liner thickness the crusher cannot have (422 naming thickness_new_mm).
void CheckThickness(const core::CrusherConfig& config, double mm) {
  const double band = config.thinnest_area.band_half_width_mm;
  if (!std::isfinite(mm) || !(mm > config.thickness_min_mm) || mm > core::kMaxThicknessMm || mm < band) {
    throw RelineError(422, "\"thickness_new_mm\" " + json(mm).dump() + " must be above the crusher's thickness_min_mm (" +
                               json(config.thickness_min_mm).dump() + "), at least thinnest_area.band_half_width_mm (" +
                               json(band).dump() + ") and at most " + json(core::kMaxThicknessMm).dump() + " mm");
  }
}

/// The model of the last of `counted` (the crusher's campaigns not voided, oldest first; two or
/// more) over the folder's model, with the one before it as the prior (its end-of-life scan, else
/// its scans in the folder).
std::unique_ptr<Crusher> RunningModel(const Crusher& folder, const std::vector<CampaignRecord>& counted) {
  const CampaignRecord& before = counted[counted.size() - 2];
  return Registry::ForCampaign(folder, CampaignConfig(folder.config, counted.back()), before.final_scan,
                               core::FromUnixSeconds(before.start_s));
}

}  // namespace

std::vector<CampaignRecord> Counted(std::vector<CampaignRecord> all) {
  std::erase_if(all, [](const CampaignRecord& c) { return c.voided_s.has_value(); });
  return all;
}

std::string ParseVoidBody(std::string_view text) {
  if (text.find_first_not_of(" \t\r\n") == std::string_view::npos) return "";
  if (mqtt::JsonNestingDepth(text) > rest::kMaxSmallBodyDepth) throw RelineError(400, "body is nested too deeply");
  json body;
  std::string error;
  if (!mqtt::ParseJsonNamingField(text, &body, &error)) throw RelineError(400, "body is not valid JSON: " + error);
  if (!body.is_object()) throw RelineError(400, "body must be a JSON object {\"reason\"} or empty");
  for (const auto& [key, value] : body.items())
    if (key != "reason") throw RelineError(400, "unknown field \"" + key + "\" (reason)");
  if (!body.contains("reason") || body["reason"].is_null()) return "";
  if (!body["reason"].is_string()) throw RelineError(400, "\"reason\" must be a string");
  std::string reason = body["reason"].get<std::string>();
  if (reason.size() > kMaxVoidReasonBytes)
    throw RelineError(400, "\"reason\" is longer than " + std::to_string(kMaxVoidReasonBytes) + " bytes");
  return reason;
}

json EventBody(std::string_view text, const std::vector<std::string>& keys) {
  if (mqtt::JsonNestingDepth(text) > rest::kMaxSmallBodyDepth) throw RelineError(400, "body is nested too deeply");
  json body;
  std::string error;
  if (!mqtt::ParseJsonNamingField(text, &body, &error)) throw RelineError(400, "body is not valid JSON: " + error);
  std::string list;
  for (const std::string& k : keys) list += (list.empty() ? "" : ", ") + k;
  if (!body.is_object()) throw RelineError(400, "body must be a JSON object (" + list + ")");
  for (const auto& [key, value] : body.items()) {
    if (std::find(keys.begin(), keys.end(), key) == keys.end())
      throw RelineError(400, "unknown field \"" + key + "\" (" + list + ")");
  }
  return body;
}

core::TimePoint EventTime(const json& body) {
  if (!body.contains("time") || !body["time"].is_string()) throw RelineError(400, "\"time\" is required: an ISO-8601 UTC time");
  const auto time = core::ParseIsoTime(body["time"].get<std::string>());
  if (!time) throw RelineError(400, "\"time\" '" + body["time"].get<std::string>() + "' is not an ISO-8601 UTC time");
  return *time;
}

RelineRequest ParseRelineBody(std::string_view text) {
  const json body = EventBody(text, {"time", "thickness_new_mm", "scan_xyz", "sensors"});
  RelineRequest r;
  r.time = EventTime(body);
  if (!body.contains("thickness_new_mm") || !body["thickness_new_mm"].is_number())
    throw RelineError(400, "\"thickness_new_mm\" is required: the new liner's thickness in mm");
  r.thickness_new_mm = body["thickness_new_mm"].get<double>();
  if (body.contains("scan_xyz") && !body["scan_xyz"].is_null()) {
    if (!body["scan_xyz"].is_string()) throw RelineError(400, "\"scan_xyz\" must be a string of 'x y z' lines");
    r.scan_xyz = body["scan_xyz"].get<std::string>();
    try {
      core::ParseScanPoints(r.scan_xyz, "scan_xyz");
    } catch (const core::InputError& e) {
      throw RelineError(422, e.what());
    }
  }
  if (body.contains("sensors") && !body["sensors"].is_null()) {
    if (!body["sensors"].is_array() || body["sensors"].empty())
      throw RelineError(400, "\"sensors\" must be a non-empty array of crusher.json sensor objects");
    r.sensors = body["sensors"];
  }
  return r;
}

core::CrusherConfig CampaignConfig(const core::CrusherConfig& base, const CampaignRecord& c) {
  core::CrusherConfig config = base;
  config.installed_at = core::FromUnixSeconds(c.start_s);
  config.thickness_new_mm = c.thickness_new_mm;
  json sensors;
  try {
    sensors = json::parse(c.sensors_json);
  } catch (const json::exception& e) {
    throw core::InputError("sensors", 0, std::string("not valid JSON: ") + e.what());
  }
  core::ParseSensors(sensors, "sensors", &config);
  return config;
}

void ApplyStoredCampaigns(Registry& registry, Store& store, std::vector<std::string>* log) {
  for (const Crusher* c : registry.All()) {
    const std::vector<CampaignRecord> all = store.Campaigns(c->config.crusher_id);
    if (all.empty()) continue;
    const std::string id = c->config.crusher_id;
    const std::vector<CampaignRecord> stored = Counted(all);
    if (stored.size() <= 1) {
      log->push_back("crusher " + id + ": every reline in the database is voided; crusher.json's installed_at, " +
                     "thickness_new_mm and sensors apply");
      continue;
    }
    const CampaignRecord& running = stored.back();
    try {
      registry.Replace(RunningModel(*c, stored));
      log->push_back("crusher " + id + ": campaign " + std::to_string(stored.size()) + " (from " +
                     core::FormatIsoSeconds(running.start_s) +
                     ", the database's) sets installed_at, thickness_new_mm and sensors over crusher.json's");
    } catch (const std::exception& e) {
      log->push_back("crusher " + id + ": the database's running campaign does not fit the crusher folder (" + e.what() +
                     "); crusher.json's installed_at, thickness_new_mm and sensors apply");
    }
  }
}

ordered_json CampaignJson(const CampaignRecord& c, int64_t now_s) {
  const json sensors = json::parse(c.sensors_json, nullptr, false);
  const json finals = json::parse(c.final_readings_json, nullptr, false);
  const int64_t until = c.end_s ? *c.end_s : std::max(now_s, c.start_s);
  const bool voided = c.voided_s.has_value();
  ordered_json j = {{"start", core::FormatIsoSeconds(c.start_s)},
                    {"end", c.end_s ? ordered_json(core::FormatIsoSeconds(*c.end_s)) : ordered_json(nullptr)},
                    {"running", !c.end_s && !voided},
                    {"thickness_new_mm", c.thickness_new_mm},
                    {"has_scan", !c.final_scan.empty()},
                    // A voided campaign was never a liner's life.
                    {"life_days", voided ? ordered_json(nullptr)
                                         : ordered_json(std::round(static_cast<double>(until - c.start_s) / 864.0) / 100.0)},
                    {"sensor_count", sensors.is_array() ? sensors.size() : 0},
                    {"sensors", sensors.is_array() ? sensors : json::array()},
                    {"final_readings", finals.is_array() ? finals : json::array()},
                    {"voided", voided}};
  if (voided) {
    j["voided_at"] = core::FormatIsoSeconds(*c.voided_s);
    j["voided_by"] = c.voided_by;
    j["void_reason"] = c.void_reason;
  }
  return j;
}

CampaignService::CampaignService(Registry& registry, LockedStore& store, LiveState& live, WearService& wear,
                                 std::function<int64_t()> now_s, std::function<void(const std::string&)> log)
    : registry_(registry), store_(store), live_(live), wear_(wear), now_s_(std::move(now_s)), log_(std::move(log)) {
  // Failing to store an opening is not fatal: the checks count as estimated, and are estimated again next start.
  const std::string failed = store_.With([&](Store& s) { return LoadSettingChecks(s, registry_, wear_, true); });
  if (!failed.empty() && log_) log_(failed);
}

std::vector<CampaignRecord> CampaignService::CampaignsOf(Store& store, const Crusher& crusher) const {
  std::vector<CampaignRecord> stored = store.Campaigns(crusher.config.crusher_id);
  if (stored.empty()) stored.push_back(FolderCampaign(crusher.config));
  return stored;
}

std::vector<CampaignRecord> CampaignService::List(const std::string& crusher_id) {
  const Crusher* crusher = registry_.Find(crusher_id);
  if (!crusher) return {};
  return store_.With([&](Store& s) { return CampaignsOf(s, *crusher); });
}

CampaignService::Outcome CampaignService::Reline(const std::string& crusher_id, const RelineRequest& request) {
  std::lock_guard<std::mutex> one_at_a_time(reline_mutex_);
  const Crusher* crusher = registry_.Find(crusher_id);
  if (!crusher) throw RelineError(404, "unknown crusher '" + crusher_id + "'");
  const int64_t time_s = core::ToUnixSeconds(request.time), now = now_s_();
  const std::string when = core::FormatIsoTime(request.time);
  const std::vector<CampaignRecord> campaigns = Counted(store_.With([&](Store& s) { return CampaignsOf(s, *crusher); }));
  // A retry of a reline already stored (its time is the start of a campaign a reline began)
  // returns that campaign: campaigns not voided are keyed by (crusher, start).
  for (size_t k = 1; k < campaigns.size(); ++k) {  // the first is the folder's: no reline started it
    const CampaignRecord& c = campaigns[k];
    if (c.start_s != time_s) continue;
    if (std::fabs(c.thickness_new_mm - request.thickness_new_mm) > 1e-9) {
      throw RelineError(409, "\"time\" " + when + " is the start of a campaign already stored with thickness_new_mm " +
                                 json(c.thickness_new_mm).dump() + ", not " + json(request.thickness_new_mm).dump());
    }
    return {false, c};
  }
  CampaignRecord closed = campaigns.back();
  if (time_s <= closed.start_s) {
    throw RelineError(
        422, "\"time\" " + when + " is not after the running campaign's start (" + core::FormatIsoSeconds(closed.start_s) + ")");
  }
  if (time_s > now) throw RelineError(422, "\"time\" " + when + " is in the future (now " + core::FormatIsoSeconds(now) + ")");
  CheckThickness(crusher->config, request.thickness_new_mm);
  CampaignRecord next;
  next.start_s = time_s;
  next.thickness_new_mm = request.thickness_new_mm;
  json sensors = request.sensors ? *request.sensors : SensorsJson(crusher->config);
  if (!request.sensors) {
    for (json& s : sensors) s["thickness_new_mm"] = request.thickness_new_mm;  // the same boards' layout, a new liner
  }
  next.sensors_json = sensors.dump();
  next.final_readings_json = "[]";
  next.created_s = now;
  std::unique_ptr<Crusher> model;
  try {
    core::CrusherConfig config = CampaignConfig(crusher->config, next);
    next.sensors_json = SensorsJson(config).dump();  // as read: each sensor's thickness and id resolved
    model = Registry::ForCampaign(*crusher, std::move(config), request.scan_xyz, core::FromUnixSeconds(closed.start_s));
  } catch (const core::InputError& e) {
    throw RelineError(422, std::string("\"sensors\": ") + e.rule());
  }
  closed.end_s = time_s;
  closed.final_scan = request.scan_xyz;
  if (closed.created_s == 0) closed.created_s = now;
  store_.With([&](Store& s) {
    closed.final_readings_json = FinalReadings(s, crusher->config, time_s);
    try {
      s.Reline(crusher_id, closed, next);
    } catch (const std::exception& e) {
      throw RelineError(500, std::string("not stored: ") + e.what());
    }
    // Stored: serve the new liner from now on (its readings only: the window is loaded again).
    const Crusher& current = *model;
    registry_.Replace(std::move(model));
    live_.Replace(current, s);
    // A check at or after the reline's time measured the new liner: its opening is estimated again.
    if (const std::string failed = LoadSettingChecks(s, current, wear_, Reestimate::kAll, true); !failed.empty() && log_)
      log_(failed);
  });
  wear_.Reset(crusher_id);
  return {true, next};
}

CampaignService::Outcome CampaignService::Void(const std::string& crusher_id, core::TimePoint start, const std::string& by,
                                               const std::string& reason) {
  std::lock_guard<std::mutex> one_at_a_time(reline_mutex_);
  if (!registry_.Find(crusher_id)) throw RelineError(404, "unknown crusher '" + crusher_id + "'");
  const int64_t start_s = core::ToUnixSeconds(start);
  const std::string when = core::FormatIsoTime(start);
  const std::vector<CampaignRecord> all = store_.With([&](Store& s) { return s.Campaigns(crusher_id); });
  const std::vector<CampaignRecord> counted = Counted(all);
  const auto at = std::find_if(counted.begin(), counted.end(), [&](const CampaignRecord& c) { return c.start_s == start_s; });
  if (at == counted.end()) {
    // A retry of a void already stored returns that campaign, unchanged.
    for (auto it = all.rbegin(); it != all.rend(); ++it)
      if (it->start_s == start_s) return {false, *it};
    throw RelineError(404, "no reline of crusher '" + crusher_id + "' at " + when + " (GET .../campaigns lists them)");
  }
  if (at == counted.begin())
    throw RelineError(409,
                      "the campaign from " + when + " began with crusher.json's installed_at, not a reline: nothing to void");
  if (at + 1 != counted.end()) {
    throw RelineError(409, "the campaign from " + when + " is not the running one: void the later reline at " +
                               core::FormatIsoSeconds(counted.back().start_s) + " first");
  }
  CampaignRecord voided = *at;
  const CampaignRecord& reopened = *(at - 1);
  voided.voided_s = now_s_();
  voided.voided_by = by;
  voided.void_reason = reason;
  voided.reline_scan = reopened.final_scan;  // the scan the mistaken reline carried, kept with it
  const std::vector<CampaignRecord> after(counted.begin(), at);
  // The first campaign reopened is the folder's own model, as before the first reline.
  const Crusher& folder = registry_.Folder(crusher_id);
  std::unique_ptr<Crusher> model;
  try {
    if (after.size() >= 2) model = RunningModel(folder, after);
  } catch (const core::InputError& e) {
    throw RelineError(409, "the campaign from " + core::FormatIsoSeconds(reopened.start_s) +
                               " no longer fits the crusher folder (" + e.what() + "): not voided");
  }
  store_.With([&](Store& s) {
    try {
      s.VoidReline(voided, reopened.id);
    } catch (const std::exception& e) {
      throw RelineError(500, std::string("not stored: ") + e.what());
    }
    // Stored: the reopened campaign's liner is served again (its readings from its start on).
    const Crusher& current = model ? *model : folder;
    if (model)
      registry_.Replace(std::move(model));
    else
      registry_.Restore(crusher_id);
    live_.Replace(current, s);
    // The voided campaign's checks measured the reopened liner: their openings are estimated again.
    if (const std::string failed = LoadSettingChecks(s, current, wear_, Reestimate::kAll, true); !failed.empty() && log_)
      log_(failed);
  });
  wear_.Reset(crusher_id);
  return {true, voided};
}

}  // namespace lw::server
