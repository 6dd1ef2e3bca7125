#include "server/alarms.hpp"

#include <cmath>
#include <cstdio>
#include <set>

#include "core/reconstruction.hpp"
#include "core/time.hpp"

namespace lw::server {
namespace {

using ordered_json = nlohmann::ordered_json;

std::string Fixed(double v, int decimals = 1) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

/// A low value is bad (a thickness, a battery): raise below `threshold`, clear at or above
/// threshold + hysteresis, hold between.
template <class Verdict>
Verdict Low(double value, const core::AlarmRule& r) {
  if (value < r.threshold) return Verdict::kRaise;
  return value >= r.threshold + r.hysteresis ? Verdict::kClear : Verdict::kHold;
}

/// A high value is bad (hours silent, rejections an hour): raise above `threshold`, clear at or
/// below threshold - hysteresis, hold between.
template <class Verdict>
Verdict High(double value, const core::AlarmRule& r) {
  if (value > r.threshold) return Verdict::kRaise;
  return value <= r.threshold - r.hysteresis ? Verdict::kClear : Verdict::kHold;
}

}  // namespace

AlarmEngine::AlarmEngine(const Registry& registry, LockedStore& store) : registry_(registry), store_(store) {
  store_.With([&](Store& s) {
    for (AlarmRecord& a : s.OpenAlarms()) open_[a.crusher].push_back(std::move(a));
    for (const Crusher* c : registry_.All()) {
      const std::string& id = c->config.crusher_id;
      if (const auto text = s.AlarmRules(id)) overrides_[id] = nlohmann::json::parse(*text, nullptr, false);
    }
  });
}

core::AlarmConfig AlarmEngine::RulesLocked(const std::string& crusher) const {
  const Crusher* c = registry_.Find(crusher);
  if (!c) throw std::out_of_range("no crusher '" + crusher + "'");
  const auto it = overrides_.find(crusher);
  if (it == overrides_.end() || !it->second.is_object()) return c->config.alarms;
  try {
    return core::ParseAlarmConfig(it->second, c->config.alarms, "alarm rules");
  } catch (const core::InputError&) {  // stored by an older server with other rules: crusher.json's
    return c->config.alarms;
  }
}

core::AlarmConfig AlarmEngine::Rules(const std::string& crusher) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return RulesLocked(crusher);
}

core::AlarmConfig AlarmEngine::UpdateRules(const std::string& crusher, const nlohmann::json& body, const std::string& by,
                                           int64_t now_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  const Crusher* c = registry_.Find(crusher);
  if (!c) throw std::out_of_range("no crusher '" + crusher + "'");
  if (!body.is_object()) throw core::InputError("alarm rules", 0, "the body must be an \"alarms\" object");
  nlohmann::json merged = overrides_.count(crusher) ? overrides_[crusher] : nlohmann::json::object();
  for (const auto& [rule, settings] : body.items()) {
    if (!merged.contains(rule) || !merged[rule].is_object() || !settings.is_object()) merged[rule] = nlohmann::json::object();
    if (settings.is_object()) {
      merged[rule].update(settings);
    } else {
      merged[rule] = settings;  // refused by the parse below, naming the rule
    }
  }
  core::AlarmConfig rules = core::ParseAlarmConfig(merged, c->config.alarms, "alarm rules");
  store_.With([&](Store& s) { s.SaveAlarmRules(crusher, merged.dump(), {0, now_s, "rules", by, crusher + ": " + body.dump()}); });
  overrides_[crusher] = std::move(merged);
  return rules;
}

void AlarmEngine::GatewayStatus(const std::string& crusher, const std::string& gateway, bool online, int64_t since_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  Gateway& g = gateways_[crusher][gateway];
  if (g.online != online || g.since_s == 0) g = {online, since_s};
}

double AlarmEngine::RejectedLastHour(const std::string& crusher, int64_t now_s, int64_t total) {
  auto& seen = rejected_seen_[crusher];
  if (!seen.empty() && total < seen.back().second) seen.clear();  // a new count (never: it only grows)
  seen.emplace_back(now_s, total);
  // Keep one count from an hour ago or more as the base; drop older ones.
  while (seen.size() > 1 && seen[1].first <= now_s - 3600) seen.pop_front();
  return static_cast<double>(total - seen.front().second);
}

void AlarmEngine::WearFindings(const core::CrusherConfig& cfg, const core::AlarmConfig& rules, const CrusherState& wear,
                               int64_t now_s, std::vector<Finding>* findings) {
  std::vector<Finding>& out = *findings;
  const CrusherState* w = &wear;
  {
    const core::ThinnestArea& a = w->areas.liner;
    const core::AlarmRule& r = rules.Rule("thinnest_area");
    Finding f{"thinnest_area", "liner", Verdict::kHold, a.thickness_mm, r.threshold, {}};
    if (a.supported && std::isfinite(a.thickness_mm)) f.verdict = Low<Verdict>(a.thickness_mm, r);
    f.detail = "thinnest area " + Fixed(a.thickness_mm) + " mm (band " + Fixed(a.lo_mm) + "-" + Fixed(a.hi_mm) + ") in row " +
               a.row + " at z " + Fixed(a.z_m, 2) + " m; alarm below " + Fixed(r.threshold) + " mm";
    out.push_back(std::move(f));
    // The setting's opening by the concave's wear at the discharge ring since the CSS was last
    // known (a measured setting, else installation): only a supported opening raises or clears (an
    // unsupported band holds the alarm as it is). Recording the CSS measured after raising the
    // mantle (POST .../setting/checks) restarts the count, so the alarm clears.
    const core::SettingEstimate& st = w->setting;
    const core::AlarmRule& so = rules.Rule("setting_open");
    const double since = st.OpeningSince();
    const double at_check = st.check ? st.check->opening_mm : 0.0;
    Finding open{"setting_open", "discharge", Verdict::kHold, since, so.threshold, {}};
    if (st.ring.supported && std::isfinite(since)) open.verdict = High<Verdict>(since, so);
    const std::string from = st.check ? "since it was measured on " + core::FormatIsoTime(st.check->time).substr(0, 10)
                                      : std::string("since installation");
    if (std::isfinite(since))
      open.detail =
          "the closed-side setting has opened " + Fixed(since) + " mm (band " + Fixed(st.opening_lo_mm - at_check) + "-" +
          Fixed(st.opening_hi_mm - at_check) + ") by the concave's wear at the discharge ring " + from +
          (st.check && !st.check->opening_supported ? " (the opening then is the central estimate of a ring not supported then)"
                                                    : "") +
          " (the mantle's wear not included); alarm above " + Fixed(so.threshold) +
          " mm: raise the mantle, then record the CSS measured (POST .../setting/checks)";
    else
      open.detail = "the closed-side setting's opening " + from +
                    " is not known (no sensor sets a scale, or no reading of this liner up to the measurement); alarm "
                    "above " +
                    Fixed(so.threshold) + " mm";
    out.push_back(std::move(open));
    for (const core::RowForecast& rf : w->row_forecasts) {
      Finding due{"reline_due", rf.row, Verdict::kHold, {}, rules.Rule("reline_due").threshold, {}};
      if (rf.ok && !rf.below_minimum_since && !rf.reach_earliest) due.verdict = Verdict::kClear;
      if (rf.ok && !rf.below_minimum_since && rf.reach_earliest) {
        const double days = static_cast<double>(core::ToUnixSeconds(*rf.reach_earliest) - now_s) / 86400.0;
        due.value = days;
        const core::AlarmRule& d = rules.Rule("reline_due");
        due.verdict = days <= d.threshold                 ? Verdict::kRaise
                      : days > d.threshold + d.hysteresis ? Verdict::kClear
                                                          : Verdict::kHold;
        due.detail = "row " + rf.row + " may reach its minimum " + Fixed(cfg.thickness_min_mm) + " mm by " +
                     core::FormatIsoTime(*rf.reach_earliest) + " (the band's early edge, in " + Fixed(days) + " days)";
      }
      out.push_back(std::move(due));
      const core::AlarmRule& o = rules.Rule("overdue");
      Finding over{"overdue", rf.row, Verdict::kHold, rf.min_thickness_mm, cfg.thickness_min_mm, {}};
      if (rf.ok && rf.below_minimum_since) {
        over.verdict = Verdict::kRaise;
        over.detail = "row " + rf.row + " is below its minimum " + Fixed(cfg.thickness_min_mm) + " mm since " +
                      core::FormatIsoTime(*rf.below_minimum_since) + " (thinnest area " + Fixed(rf.min_thickness_mm) +
                      " mm): reline overdue";
      } else if (rf.ok && rf.min_thickness_mm >= cfg.thickness_min_mm + o.hysteresis) {
        over.verdict = Verdict::kClear;
      }
      out.push_back(std::move(over));
    }
    Finding u{"unsupported", cfg.crusher_id, Verdict::kClear, {}, {}, {}};
    if (w->reconstruction.status == core::kStatusUnsupported) {
      u.verdict = Verdict::kRaise;
      u.detail = "the sensors and the map do not support a wear number (" + w->reconstruction.status_detail + ")";
    }
    out.push_back(std::move(u));
  }
}

void AlarmEngine::SensorFindings(const core::CrusherConfig& cfg, const core::AlarmConfig& rules, const AlarmInputs& in,
                                 std::vector<Finding>* findings) {
  std::vector<Finding>& out = *findings;
  for (const AlarmInputs::Sensor& s : in.sensors) {
    const core::AlarmRule& r = rules.Rule("sensor_silent");
    const int64_t last = s.latest_s.value_or(core::ToUnixSeconds(cfg.installed_at));
    const double hours = static_cast<double>(in.now_s - last) / 3600.0;
    out.push_back({"sensor_silent", s.id, High<Verdict>(hours, r), hours, r.threshold,
                   "sensor " + s.id + ": no reading for " + Fixed(hours) + " h (last " +
                       (s.latest_s ? core::FormatIsoSeconds(*s.latest_s) : std::string("never")) + "); alarm after " +
                       Fixed(r.threshold) + " h"});
    const core::AlarmRule& b = rules.Rule("battery_low");
    if (s.battery_mv <= 0) continue;
    out.push_back(
        {"battery_low", s.id, Low<Verdict>(static_cast<double>(s.battery_mv), b), static_cast<double>(s.battery_mv), b.threshold,
         "sensor " + s.id + ": battery " + std::to_string(s.battery_mv) + " mV, below " + Fixed(b.threshold, 0) + " mV"});
  }
}

std::vector<AlarmEngine::Finding> AlarmEngine::Findings(const Crusher& crusher, const core::AlarmConfig& rules,
                                                        const AlarmInputs& in) {
  std::vector<Finding> out;
  const core::CrusherConfig& cfg = crusher.config;
  if (in.wear && in.wear->has_wear) WearFindings(cfg, rules, *in.wear, in.now_s, &out);
  SensorFindings(cfg, rules, in, &out);
  const core::AlarmRule& g = rules.Rule("gateway_offline");
  for (const auto& [id, status] : gateways_[cfg.crusher_id]) {
    const double minutes = static_cast<double>(in.now_s - status.since_s) / 60.0;
    Verdict v = status.online ? Verdict::kClear : minutes >= g.threshold ? Verdict::kRaise : Verdict::kHold;
    out.push_back({"gateway_offline", id, v, minutes, g.threshold,
                   "gateway " + id + " offline since " + core::FormatIsoSeconds(status.since_s) + " (its last will or status)"});
  }
  const core::AlarmRule& rj = rules.Rule("rejected_rate");
  const double rejected = RejectedLastHour(cfg.crusher_id, in.now_s, in.rejected_total);
  out.push_back({"rejected_rate", cfg.crusher_id, High<Verdict>(rejected, rj), rejected, rj.threshold,
                 Fixed(rejected, 0) + " readings rejected in the last hour (alarm above " + Fixed(rj.threshold, 0) +
                     "): see GET /api/v1/rejected"});
  return out;
}

bool AlarmEngine::Apply(const core::CrusherConfig& config, const core::AlarmConfig& rules, const std::vector<Finding>& findings,
                        int64_t now_s) {
  const std::string& crusher = config.crusher_id;
  std::map<std::pair<std::string, std::string>, const Finding*> by_key;
  for (const Finding& f : findings) {
    if (rules.Rule(f.rule).enabled) by_key[{f.rule, f.subject}] = &f;
  }
  bool changed = false;
  std::vector<AlarmRecord>& open = open_[crusher];
  std::set<std::pair<std::string, std::string>> still_open;
  for (auto it = open.begin(); it != open.end();) {
    const auto f = by_key.find({it->rule, it->subject});
    // No finding: no data yet (the wear not computed, a gateway's status not heard since a
    // restart) holds the alarm; a disabled rule or a sensor no longer fitted clears it.
    const bool sensor_rule = it->rule == "sensor_silent" || it->rule == "battery_low";
    const bool gone = !rules.Rule(it->rule).enabled || (sensor_rule && !config.FindSensor(it->subject));
    if ((f == by_key.end() && !gone) || (f != by_key.end() && f->second->verdict != Verdict::kClear)) {
      still_open.insert({it->rule, it->subject});
      ++it;
      continue;
    }
    AlarmRecord cleared = *it;
    cleared.state = "cleared";
    cleared.cleared_s = now_s;
    const std::string why = f == by_key.end() ? "rule disabled or subject gone" : "back within the rule";
    store_.With([&](Store& s) { s.SaveAlarm(cleared, {0, now_s, "cleared", "server", why}); });
    it = open.erase(it);
    changed = true;
  }
  for (const auto& [key, f] : by_key) {
    if (f->verdict != Verdict::kRaise || still_open.count(key)) continue;
    AlarmRecord a;
    a.crusher = crusher;
    a.rule = f->rule;
    a.subject = f->subject;
    a.severity = rules.Rule(f->rule).severity;
    a.state = "active";
    a.since_s = now_s;
    a.detail = f->detail;
    if (f->value && std::isfinite(*f->value)) a.value = f->value;
    a.threshold = f->threshold;
    a.id = store_.With([&](Store& s) { return s.SaveAlarm(a, {0, now_s, "raised", "server", a.detail}); });
    open.push_back(std::move(a));
    changed = true;
  }
  return changed;
}

bool AlarmEngine::Evaluate(const std::string& crusher, const AlarmInputs& in) {
  bool changed = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const Crusher* c = registry_.Find(crusher);
    if (!c) return false;
    const core::AlarmConfig rules = RulesLocked(crusher);
    changed = Apply(c->config, rules, Findings(*c, rules, in), in.now_s);
  }
  if (changed && listener_) listener_(crusher);
  return changed;
}

AlarmEngine::Ack AlarmEngine::Acknowledge(const std::string& crusher, int64_t id, const std::string& by, int64_t now_s,
                                          AlarmRecord* out) {
  Ack result = Ack::kAcknowledged;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    AlarmRecord* open = nullptr;
    for (AlarmRecord& a : open_[crusher])
      if (a.id == id) open = &a;
    if (!open) {
      const auto stored = store_.With([&](Store& s) { return s.Alarm(id); });
      if (!stored || stored->crusher != crusher) return Ack::kUnknown;
      *out = *stored;
      return Ack::kCleared;  // every open alarm is in open_
    }
    if (open->state == "acknowledged") {
      *out = *open;
      return Ack::kAlreadyAcknowledged;
    }
    AlarmRecord acked = *open;
    acked.state = "acknowledged";
    acked.acknowledged_s = now_s;
    acked.acknowledged_by = by;
    store_.With([&](Store& s) { s.SaveAlarm(acked, {0, now_s, "acknowledged", by, ""}); });
    *open = acked;
    *out = acked;
  }
  if (listener_) listener_(crusher);
  return result;
}

std::vector<AlarmRecord> AlarmEngine::List(const std::string& crusher, const std::string& state, int64_t cleared_since_s,
                                           int limit) {
  return store_.With([&](Store& s) { return s.Alarms(crusher, state, cleared_since_s, limit); });
}

std::vector<AlarmRecord> AlarmEngine::Open(const std::string& crusher) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = open_.find(crusher);
  return it == open_.end() ? std::vector<AlarmRecord>{} : it->second;
}

std::vector<AlarmAuditEntry> AlarmEngine::Audit(int64_t id) {
  return store_.With([&](Store& s) { return s.AlarmAudit(id); });
}

ordered_json AlarmJson(const AlarmRecord& a, const std::vector<AlarmAuditEntry>* audit) {
  const auto time_or_null = [](const std::optional<int64_t>& t) {
    return t ? ordered_json(core::FormatIsoSeconds(*t)) : ordered_json(nullptr);
  };
  const auto number_or_null = [](const std::optional<double>& v) { return v ? ordered_json(*v) : ordered_json(nullptr); };
  ordered_json j{{"id", a.id},
                 {"rule", a.rule},
                 {"subject", a.subject},
                 {"severity", a.severity},
                 {"state", a.state},
                 {"since", core::FormatIsoSeconds(a.since_s)},
                 {"detail", a.detail},
                 {"value", number_or_null(a.value)},
                 {"threshold", number_or_null(a.threshold)},
                 {"acknowledged_at", time_or_null(a.acknowledged_s)},
                 {"acknowledged_by", a.acknowledged_by.empty() ? ordered_json(nullptr) : ordered_json(a.acknowledged_by)},
                 {"cleared_at", time_or_null(a.cleared_s)}};
  if (audit) {
    ordered_json trail = ordered_json::array();
    for (const AlarmAuditEntry& e : *audit)
      trail.push_back({{"time", core::FormatIsoSeconds(e.time_s)}, {"action", e.action}, {"by", e.by}, {"detail", e.detail}});
    j["audit"] = std::move(trail);
  }
  return j;
}

std::string AlarmsMessage(const std::string& crusher, const std::vector<AlarmRecord>& open, int64_t now_s) {
  ordered_json list = ordered_json::array();
  for (const AlarmRecord& a : open) list.push_back(AlarmJson(a));
  return ordered_json{{"crusher", crusher}, {"time", core::FormatIsoSeconds(now_s)}, {"alarms", std::move(list)}}.dump(
      -1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace lw::server
