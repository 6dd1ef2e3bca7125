// Measured closed-side settings (docs/wear.md, *Setting*): an operator raises the mantle and
// measures the CSS; the server keeps the measurement with the concave's opening it estimated at that
// time, and counts the setting from it.
#include <chrono>
#include <cmath>
#include <optional>

#include "core/time.hpp"
#include "server/campaigns.hpp"

namespace lw::server {
namespace {

using nlohmann::json;
using nlohmann::ordered_json;

/// How far ahead of the server's clock a check's time may be (a measuring person's watch).
constexpr int64_t kClockSlackS = 300;
/// The widest closed-side setting accepted, mm (primary gyratories set 100-250 mm).
constexpr double kMaxCssMm = 1000;

/// A check with no reading of the liner up to it still knows its opening this long after the
/// installation: nothing has opened yet.
constexpr int64_t kNewLinerS = 86400;
/// The least time between two tries to estimate a crusher's not-known checks.
constexpr std::chrono::seconds kUnknownRetry{60};

core::SettingCheck ToCore(const SettingCheckRecord& r) {
  return {core::FromUnixSeconds(r.time_s), r.css_mm, r.opening_mm.value_or(std::nan("")), r.by, r.opening_supported};
}

}  // namespace

SettingCheckRequest ParseSettingCheckBody(std::string_view text) {
  const json body = EventBody(text, {"time", "css_mm", "note"});
  SettingCheckRequest r;
  r.time = EventTime(body);
  if (!body.contains("css_mm") || !body["css_mm"].is_number())
    throw RelineError(400, "\"css_mm\" is required: the closed-side setting measured, in mm");
  r.css_mm = body["css_mm"].get<double>();
  if (body.contains("note") && !body["note"].is_null()) {
    if (!body["note"].is_string()) throw RelineError(400, "\"note\" must be a string");
    r.note = body["note"].get<std::string>();
    if (r.note.size() > kMaxSettingNoteBytes)
      throw RelineError(400, "\"note\" is longer than " + std::to_string(kMaxSettingNoteBytes) + " bytes");
  }
  return r;
}

std::vector<core::SettingCheck> ToCoreSettingChecks(const std::vector<SettingCheckRecord>& records) {
  std::vector<core::SettingCheck> out;
  out.reserve(records.size());
  for (const SettingCheckRecord& r : records) out.push_back(ToCore(r));
  return out;
}

ordered_json SettingCheckJson(const SettingCheckRecord& c, core::TimePoint installed_at) {
  const auto iso = [](int64_t s) { return core::FormatIsoSeconds(s); };
  return {{"time", iso(c.time_s)},
          {"css_mm", c.css_mm},
          {"opening_mm", c.opening_mm ? ordered_json(std::round(*c.opening_mm * 100) / 100) : ordered_json(nullptr)},
          {"opening_supported", c.opening_supported},
          {"counts", core::FromUnixSeconds(c.time_s) >= installed_at},
          {"by", c.by},
          {"note", c.note},
          {"recorded", iso(c.recorded_s)}};
}

void EstimateOpening(Store& store, const Crusher& crusher, SettingCheckRecord* check) {
  const core::TimePoint at = core::FromUnixSeconds(check->time_s);
  const estimate::ReadingWindow window = LoadWindow(store, crusher, check->time_s);
  estimate::EstimateOptions wear_only;
  wear_only.forecast = false;  // the opening is the concave's wear then; no reline date is asked for
  const CrusherState then = ComputeCrusherState(crusher, window.Readings(), at, nullptr, {}, wear_only);
  check->opening_mm.reset();
  check->opening_supported = false;
  if (!then.has_wear) {
    if (at - crusher.config.installed_at <= std::chrono::seconds(kNewLinerS)) {
      check->opening_mm = 0.0;
      check->opening_supported = true;
    }
  } else if (std::isfinite(then.setting.opening_mm)) {
    check->opening_mm = then.setting.opening_mm;
    check->opening_supported = then.setting.ring.supported;
  }
}

std::vector<SettingCheckRecord> EstimateSettingChecks(Store& store, const Crusher& crusher, Reestimate which) {
  std::vector<SettingCheckRecord> all = store.SettingChecks(crusher.config.crusher_id);
  for (SettingCheckRecord& c : all) {
    if (core::FromUnixSeconds(c.time_s) < crusher.config.installed_at) continue;  // an earlier liner's
    if (which == Reestimate::kAll || !c.opening_mm) EstimateOpening(store, crusher, &c);
  }
  return all;
}

std::string LoadSettingChecks(Store& store, const Crusher& crusher, WearService& wear, Reestimate which, bool store_changes) {
  const std::string& id = crusher.config.crusher_id;
  std::vector<SettingCheckRecord> all;
  try {
    all = EstimateSettingChecks(store, crusher, which);
  } catch (const std::exception& e) {
    // The running liner's checks may have been counted under another liner (a reline or void just
    // changed it): they hold the setting_open alarm (opening not known) rather than count wrongly.
    // A try for the unknown ones only (Reestimate::kUnknown) keeps the known openings as they are.
    if (which == Reestimate::kUnknown)
      return id + ": setting checks not known not estimated (" + e.what() + "); tried again later";
    std::vector<core::SettingCheck> held = wear.SettingChecks(id);
    for (core::SettingCheck& c : held)
      if (c.time >= crusher.config.installed_at) c.opening_mm = std::nan("");
    wear.SetSettingChecks(id, std::move(held));
    return id + ": setting checks not estimated (" + e.what() + "); the running liner's count as not known until estimated again";
  }
  wear.SetSettingChecks(id, ToCoreSettingChecks(all));
  if (!store_changes || all.empty()) return {};
  try {
    store.UpdateSettingCheckOpenings(all);
  } catch (const std::exception& e) {
    return id + ": setting checks' openings not stored (" + e.what() + "); counted as estimated";
  }
  return {};
}

std::string LoadSettingChecks(Store& store, const Registry& registry, WearService& wear, bool store_changes) {
  std::string failed;
  for (const Crusher* c : registry.All())
    if (std::string e = LoadSettingChecks(store, *c, wear, Reestimate::kUnknown, store_changes); !e.empty())
      failed += (failed.empty() ? "" : "; ") + e;
  return failed;
}

CampaignService::SettingOutcome CampaignService::CheckSetting(const std::string& crusher_id, const SettingCheckRequest& request,
                                                              const std::string& by) {
  std::lock_guard<std::mutex> one_at_a_time(reline_mutex_);  // against a reline replacing the model meanwhile
  const Crusher* crusher = registry_.Find(crusher_id);
  if (!crusher) throw RelineError(404, "unknown crusher '" + crusher_id + "'");
  const int64_t time_s = core::ToUnixSeconds(request.time);
  const std::string when = core::FormatIsoTime(request.time);
  if (!std::isfinite(request.css_mm) || !(request.css_mm > 0) || request.css_mm > kMaxCssMm)
    throw RelineError(
        422, "\"css_mm\" " + json(request.css_mm).dump() + " must be above 0 and at most " + json(kMaxCssMm).dump() + " mm");
  if (time_s > now_s_() + kClockSlackS) throw RelineError(422, "\"time\" " + when + " is in the future");
  if (request.time < crusher->config.installed_at)
    throw RelineError(422, "\"time\" " + when + " is before the running liner's installation (" +
                               core::FormatIsoTime(crusher->config.installed_at) + "): it measured the liner before");
  SettingCheckRecord record{crusher_id, time_s, request.css_mm, std::nullopt, false, by, request.note, now_s_()};
  std::vector<SettingCheckRecord> all;
  bool created = false;
  try {
    store_.With([&](Store& s) {  // one hold of the store: no reline or void between the estimate and the insert
      EstimateOpening(s, *crusher, &record);
      created = s.AddSettingCheck(record);
      all = s.SettingChecks(crusher_id);
    });
  } catch (const std::runtime_error& e) {
    throw RelineError(500, std::string("not stored: ") + e.what());
  }
  SettingOutcome out{created, record};
  // Handed on whether stored now or before: a retry after a 500 that had stored the row still
  // reaches the live wear.
  wear_.SetSettingChecks(crusher_id, ToCoreSettingChecks(all));
  if (!created) {
    for (const SettingCheckRecord& c : all)
      if (c.time_s == time_s) out.check = c;
    if (std::abs(out.check.css_mm - request.css_mm) > 1e-9)
      throw RelineError(409, "a setting of " + json(out.check.css_mm).dump() + " mm is already recorded at " + when + " (by " +
                                 out.check.by + ")");
    return out;
  }
  return out;
}

CampaignService::UnknownSettings CampaignService::EstimateUnknownSettings(const std::string& crusher_id) {
  // What is not known is read without the reline lock (the registry and the wear service are
  // thread-safe): the wear worker calls this for every crusher it computes, and a reline holds
  // the lock for seconds.
  const Crusher* seen = registry_.Find(crusher_id);
  if (!seen) return UnknownSettings::kNone;
  std::optional<core::TimePoint> oldest;
  for (const core::SettingCheck& c : wear_.SettingChecks(crusher_id))
    if (c.time >= seen->config.installed_at && !std::isfinite(c.opening_mm)) oldest = std::min(oldest.value_or(c.time), c.time);
  if (!oldest) return UnknownSettings::kNone;
  // Not before the crusher's readings reach past the check: a backfill in progress would give an
  // opening from part of the readings, which is then kept.
  const std::optional<int64_t> latest = live_.LatestUsableTime(crusher_id);
  if (!latest || core::FromUnixSeconds(*latest) <= *oldest) return UnknownSettings::kWaiting;
  std::unique_lock<std::mutex> one_at_a_time(reline_mutex_, std::try_to_lock);  // a reline's model stays the one estimated with
  if (!one_at_a_time.owns_lock()) return UnknownSettings::kWaiting;
  const Crusher* crusher = registry_.Find(crusher_id);
  if (!crusher) return UnknownSettings::kNone;
  // Each try reads the window up to every unknown check: not on every commit of a busy crusher,
  // and not again on the same readings unless the last try failed (a check that stays not known,
  // no sensor setting a scale then, costs nothing while no reading arrives).
  const auto now = std::chrono::steady_clock::now();
  const int64_t readings = live_.CountReadings(crusher_id);  // older readings arriving late count too
  UnknownTry& tried = unknown_tried_[crusher_id];
  if (tried.at && (now - *tried.at < kUnknownRetry || (tried.failure.empty() && tried.readings == readings)))
    return UnknownSettings::kWaiting;
  tried.at = now;
  tried.readings = readings;
  const std::string failed =
      store_.With([&](Store& s) { return LoadSettingChecks(s, *crusher, wear_, Reestimate::kUnknown, true); });
  if (failed != tried.failure && !failed.empty() && log_) log_(failed);  // once, not at every retry
  tried.failure = failed;
  for (const core::SettingCheck& c : wear_.SettingChecks(crusher_id))
    if (c.time >= crusher->config.installed_at && !std::isfinite(c.opening_mm)) return UnknownSettings::kWaiting;
  return UnknownSettings::kEstimated;
}

std::vector<SettingCheckRecord> CampaignService::SettingChecks(const std::string& crusher_id) {
  if (!registry_.Find(crusher_id)) return {};
  return store_.With([&](Store& s) { return s.SettingChecks(crusher_id); });
}

}  // namespace lw::server
