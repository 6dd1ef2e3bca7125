#pragma once
/// Liner campaigns (docs/campaigns.md): a reline closes the running campaign of a crusher (its end,
/// liner life, end-of-life scan and each sensor's last reading) and starts the next, in the
/// database, and the server goes on at once with the new liner's model: live wear, forecast and the
/// stuck and stale rules read only the readings from the new campaign's start, with its thickness
/// and its sensor layout. crusher.json stays the site's description (geometry, map, rows, minimum
/// thickness); once a crusher has campaigns stored, the running one's installed_at, thickness_new_mm
/// and sensors override crusher.json's.
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "core/time.hpp"
#include "server/live_state.hpp"
#include "server/registry.hpp"
#include "server/store.hpp"
#include "server/wear_service.hpp"

namespace lw::server {

/// A refused reline, void or setting check: the HTTP status (400 malformed body, 409 conflicting
/// retry, 422 invalid value, 500 not stored) and a message that names the field. Nothing was changed.
class RelineError : public std::runtime_error {
 public:
  RelineError(int status, const std::string& message) : std::runtime_error(message), status_(status) {}
  int status() const { return status_; }

 private:
  int status_;
};

/// The body of POST .../relines, parsed and checked for form (the values are checked against the
/// crusher by CampaignService::Reline).
struct RelineRequest {
  core::TimePoint time{};
  double thickness_new_mm = 0;
  std::string scan_xyz;                   ///< the old liner's end-of-life scan; empty: none
  std::optional<nlohmann::json> sensors;  ///< the new sensor layout (crusher.json sensor objects); nullopt: the same
};
/// Parses the JSON body. Throws RelineError naming the field.
RelineRequest ParseRelineBody(std::string_view body);

/// The longest reason a void keeps (POST .../relines/{time}/void).
inline constexpr size_t kMaxVoidReasonBytes = 1000;
/// The body of POST .../relines/{time}/void: empty, or {"reason": "..."}; returns the reason (empty:
/// none). Throws RelineError (400) naming the field.
std::string ParseVoidBody(std::string_view body);

/// A campaign event's JSON body (a reline, a setting check): an object nested at most
/// rest::kMaxSmallBodyDepth, every key one of `keys`. Throws RelineError (400) naming what is wrong.
nlohmann::json EventBody(std::string_view body, const std::vector<std::string>& keys);
/// The body's "time": required, ISO-8601 UTC. Throws RelineError (400).
core::TimePoint EventTime(const nlohmann::json& body);

/// The body of POST .../setting/checks: the closed-side setting measured on the crusher.
struct SettingCheckRequest {
  core::TimePoint time{};
  double css_mm = 0;
  std::string note;
};
/// The longest note a setting check keeps.
inline constexpr size_t kMaxSettingNoteBytes = 1000;
/// Parses {"time", "css_mm", "note"?}. Throws RelineError (400) naming the field.
SettingCheckRequest ParseSettingCheckBody(std::string_view body);
/// One measured setting as GET .../setting/checks lists it (docs/wear.md, *Setting*); `installed_at`:
/// the running liner's installation (a check before it measured an earlier liner and does not count).
nlohmann::ordered_json SettingCheckJson(const SettingCheckRecord& check, core::TimePoint installed_at);

/// The concave's opening at `check`'s time under `crusher`'s running liner, from the readings
/// stored up to then, into check->opening_mm and opening_supported: the same estimate as GET
/// .../wear?at=. No reading of the liner yet: 0 within a day of its installation (nothing opened
/// yet), else not known.
void EstimateOpening(Store& store, const Crusher& crusher, SettingCheckRecord* check);
/// Which of the running liner's checks to estimate again: every one (after a reline or a void
/// changed which liner they measured), or those whose opening is not known (at start-up: cheap,
/// usually none; one LoadWindow and wear computation per check).
enum class Reestimate { kAll, kUnknown };
/// The crusher's stored checks, oldest first, with the openings of `which` of its running liner's
/// (at or after installed_at) estimated again from the readings stored now.
std::vector<SettingCheckRecord> EstimateSettingChecks(Store& store, const Crusher& crusher, Reestimate which);
/// The crusher's checks, `which` estimated again, handed to `wear`; with `store_changes` the changed
/// openings are stored too. A failure is returned as text (empty: none): one to store leaves the
/// checks handed on as estimated, one to estimate hands on the running liner's checks as not known.
std::string LoadSettingChecks(Store& store, const Crusher& crusher, WearService& wear, Reestimate which, bool store_changes);
/// At start-up, for every crusher of `registry` (Reestimate::kUnknown); the failures joined by "; ".
std::string LoadSettingChecks(Store& store, const Registry& registry, WearService& wear, bool store_changes);
/// The checks in the form live wear counts them.
std::vector<core::SettingCheck> ToCoreSettingChecks(const std::vector<SettingCheckRecord>& records);

/// `all` without the voided campaigns: the crusher's history as it counts, oldest first.
std::vector<CampaignRecord> Counted(std::vector<CampaignRecord> all);

/// `base` (the crusher's configuration) for campaign `c`: its start as installed_at, its thickness
/// and its sensors. Throws core::InputError naming "sensors" and the rule.
core::CrusherConfig CampaignConfig(const core::CrusherConfig& base, const CampaignRecord& c);

/// At startup, before the registry is shared: every crusher with stored campaigns gets its running
/// campaign's model (Registry::ForCampaign). A campaign that no longer fits the crusher folder
/// (a sensor off a new map) leaves crusher.json's in force; each line of what was done goes to `log`.
void ApplyStoredCampaigns(Registry& registry, Store& store, std::vector<std::string>* log);

/// One campaign as GET .../campaigns lists it (docs/campaigns.md); `now_s` gives the running one's life so far.
nlohmann::ordered_json CampaignJson(const CampaignRecord& c, int64_t now_s);

class CampaignService {
 public:
  /// `store` is a connection of the service's own (it writes campaigns); `now_s` the server's clock.
  /// `log` takes what fails after a reline or void has been stored (a setting check not estimated).
  CampaignService(Registry& registry, LockedStore& store, LiveState& live, WearService& wear, std::function<int64_t()> now_s,
                  std::function<void(const std::string&)> log = {});

  struct Outcome {
    bool created = false;  ///< false: the same reline was stored before (a retry), `campaign` is that one
    CampaignRecord campaign;
  };
  /// Relines `crusher_id` (known to the registry). Relines are handled one at a time. Throws
  /// RelineError (nothing changed) on a value that does not fit the crusher.
  Outcome Reline(const std::string& crusher_id, const RelineRequest& request);
  /// Voids the reline that started the running campaign at `start` (docs/campaigns.md, *Voiding a
  /// reline*): kept, marked voided by `by` (the token's name) now with `reason`; the campaign it
  /// closed runs again, and live wear, the forecast and the rules switch back to it. A void again
  /// returns the voided campaign (created false). Throws RelineError: 404 no reline at `start`, 409
  /// not the running campaign (or the first, which no reline started), 500 not stored.
  Outcome Void(const std::string& crusher_id, core::TimePoint start, const std::string& by, const std::string& reason);
  /// Records the closed-side setting measured on `crusher_id` at request.time (after raising the
  /// mantle, say) by `by` (the token's name), with the concave's opening estimated at that time from
  /// the readings stored up to it; live wear then counts the setting from it (docs/wear.md,
  /// *Setting*) and the setting_open alarm counts its opening from it. The same check again returns
  /// the stored one (created false). Throws RelineError: 404 unknown crusher, 409 another CSS at
  /// that time, 422 a time in the future or before the liner's installation, a CSS out of range,
  /// 500 not stored.
  struct SettingOutcome {
    bool created = false;
    SettingCheckRecord check;
  };
  SettingOutcome CheckSetting(const std::string& crusher_id, const SettingCheckRequest& request, const std::string& by);
  /// What EstimateUnknownSettings found.
  enum class UnknownSettings {
    kNone,       ///< every check of the running liner has its opening (or the crusher is not known)
    kEstimated,  ///< it tried, and every one is known now
    kWaiting,    ///< some are not known yet: the readings do not reach past them, a try within the last
                 ///< minute or on the same readings, a reline running, the try failed (logged), or it
                 ///< tried and the readings do not give the opening: ask again later
  };
  /// The running liner's checks whose opening is not known (their readings had not arrived) are
  /// estimated again from the readings stored by now, once the crusher's readings reach past them, at
  /// most once a minute per crusher, again only when readings arrived since the last try (or it
  /// failed), and never waiting for a reline. The wear worker calls this
  /// before it computes a crusher's wear, and again while the answer is kWaiting.
  UnknownSettings EstimateUnknownSettings(const std::string& crusher_id);
  /// The crusher's measured settings, oldest first (every liner's).
  std::vector<SettingCheckRecord> SettingChecks(const std::string& crusher_id);
  /// Every campaign of the crusher (voided ones too), oldest first; before its first reline, the one crusher.json describes.
  std::vector<CampaignRecord> List(const std::string& crusher_id);
  int64_t Now() const { return now_s_(); }

 private:
  /// The crusher's stored campaigns, or the one crusher.json describes (not stored yet).
  std::vector<CampaignRecord> CampaignsOf(Store& store, const Crusher& crusher) const;

  Registry& registry_;
  LockedStore& store_;
  LiveState& live_;
  WearService& wear_;
  std::function<int64_t()> now_s_;
  std::function<void(const std::string&)> log_;
  std::mutex reline_mutex_;
  /// EstimateUnknownSettings' last try of a crusher: when, on how many stored readings, and what
  /// failed (empty: nothing).
  struct UnknownTry {
    std::optional<std::chrono::steady_clock::time_point> at;
    int64_t readings = 0;
    std::string failure;
  };
  std::map<std::string, UnknownTry> unknown_tried_;  ///< under reline_mutex_
};

}  // namespace lw::server
