#include "server/ingest.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <tuple>

#include "core/time.hpp"

namespace lw::server {
namespace {

using nlohmann::json;

/// An integer field in [lo, hi]; sets *error (naming the field) otherwise.
std::optional<int64_t> IntField(const json& j, const char* name, int64_t lo, int64_t hi, std::string* error) {
  const auto it = j.find(name);
  if (it == j.end()) {
    *error = std::string("missing \"") + name + "\"";
    return std::nullopt;
  }
  int64_t v = 0;
  if (it->is_number_integer()) {
    v = it->get<int64_t>();
  } else if (it->is_number_float() && std::floor(it->get<double>()) == it->get<double>() && std::fabs(it->get<double>()) < 9e15) {
    v = static_cast<int64_t>(it->get<double>());
  } else {
    *error = std::string("\"") + name + "\" must be a whole number";
    return std::nullopt;
  }
  if (v < lo || v > hi) {
    *error = std::string("\"") + name + "\" " + std::to_string(v) + " is outside [" + std::to_string(lo) + ", " +
             std::to_string(hi) + "]";
    return std::nullopt;
  }
  return v;
}

/// The quoted token of a number overflow message ("... parsing '1e999'"), or empty.
std::string OverflowToken(const std::string& what) {
  const size_t a = what.find('\'');
  const size_t b = a == std::string::npos ? a : what.find('\'', a + 1);
  return b == std::string::npos ? std::string() : what.substr(a + 1, b - a - 1);
}

/// A message whose numbers overflow a double still names its sensor and seq: read them from a copy
/// with each overflowing number replaced by 0 (at most 16), so the rejection can be acknowledged.
void IdentifyDespiteOverflow(std::string_view payload, Validation* v) {
  std::string text(payload);
  for (int tries = 0; tries < 16; ++tries) {
    try {
      const json j = json::parse(text);
      if (!j.is_object()) return;
      const auto s = j.find("sensor");
      if (s != j.end() && s->is_string())
        v->sensor = s->get<std::string>();
      else if (s != j.end() && s->is_number_integer())
        v->sensor = std::to_string(s->get<int64_t>());
      std::string ignored;
      v->seq = IntField(j, "seq", 0, 0xFFFFFFFFLL, &ignored);
      return;
    } catch (const json::out_of_range& e) {
      const std::string token = OverflowToken(e.what());
      if (token.empty()) return;
      bool replaced = false;
      for (size_t at = text.find(token); at != std::string::npos; at = text.find(token, at + 1)) {
        // Only a whole number token (after ':' ',' or '[' and optional spaces), not text in a string.
        size_t before = at;
        while (before > 0 && std::isspace(static_cast<unsigned char>(text[before - 1]))) --before;
        const char prev = before > 0 ? text[before - 1] : '\0';
        const size_t after = at + token.size();
        const bool ends = after >= text.size() || std::strchr(",]} \t\r\n", text[after]) != nullptr;
        if ((prev == ':' || prev == ',' || prev == '[') && ends) {
          // Never invent the identity itself: an overflowing "seq" or "sensor" identifies nothing.
          if (prev == ':') {
            const size_t quote = text.rfind('"', before - 1);
            const size_t open = quote == std::string::npos || quote == 0 ? std::string::npos : text.rfind('"', quote - 1);
            const std::string key = open == std::string::npos ? std::string() : text.substr(open + 1, quote - open - 1);
            if (key == "seq" || key == "sensor") return;
          }
          text.replace(at, token.size(), "0");
          replaced = true;
          break;
        }
      }
      if (!replaced) return;
    } catch (const json::exception&) {
      return;
    }
  }
}

}  // namespace

bool ParseJsonNamingField(std::string_view text, nlohmann::json* out, std::string* error) {
  std::string key;  // the last object key seen: names the field a number overflow sits in
  try {
    *out = json::parse(text, [&key](int, json::parse_event_t event, json& parsed) {
      if (event == json::parse_event_t::key && parsed.is_string()) key = parsed.get<std::string>();
      return true;
    });
    return true;
  } catch (const json::out_of_range& e) {
    // nlohmann: "[json.exception.out_of_range.406] number overflow parsing '1e999'"
    const std::string what = e.what();
    const size_t q = what.find('\'');
    const std::string number = q == std::string::npos ? std::string() : what.substr(q);
    *error = (key.empty() ? std::string("a number") : "\"" + key + "\"") + (number.empty() ? "" : " " + number) +
             " does not fit a double (number overflow)";
  } catch (const json::exception&) {
    *error = "malformed JSON";
  }
  return false;
}

bool IsFaultReading(int64_t flags, int64_t loops_intact) {
  constexpr int64_t kAllOpen = 1 << 3, kSpiStuck = 1 << 4;
  if (flags & kSpiStuck) return true;
  return (flags & kAllOpen) && loops_intact > 0;
}

size_t JsonNestingDepth(std::string_view text) {
  size_t depth = 0, deepest = 0;
  bool in_string = false, escaped = false;
  for (const char ch : text) {
    if (in_string) {
      if (escaped)
        escaped = false;
      else if (ch == '\\')
        escaped = true;
      else if (ch == '"')
        in_string = false;
    } else if (ch == '"') {
      in_string = true;
    } else if (ch == '[' || ch == '{') {
      deepest = std::max(deepest, ++depth);
    } else if ((ch == ']' || ch == '}') && depth > 0) {
      --depth;
    }
  }
  return deepest;
}

Validation ValidateReading(const Incoming& in, const Registry& registry, int64_t now_s) {
  Validation v;
  if (in.payload.size() > kMaxPayloadBytes) {
    v.error = "message of " + std::to_string(in.payload.size()) + " bytes (at most " + std::to_string(kMaxPayloadBytes) + ")";
    return v;
  }
  if (JsonNestingDepth(in.payload) > kMaxJsonDepth) {
    v.error = "JSON nested deeper than " + std::to_string(kMaxJsonDepth) + " levels";
    return v;
  }
  json j;
  if (!ParseJsonNamingField(in.payload, &j, &v.error)) {
    IdentifyDespiteOverflow(in.payload, &v);  // so that the quarantined message can be acknowledged
    return v;
  }
  if (!j.is_object()) {
    v.error = "not a JSON object";
    return v;
  }
  // Identify first, so that even a rejected message can be acknowledged once quarantined.
  const auto s = j.find("sensor");
  if (s != j.end() && s->is_string())
    v.sensor = s->get<std::string>();
  else if (s != j.end() && s->is_number_integer())
    v.sensor = std::to_string(s->get<int64_t>());
  std::string error;
  if (const auto seq = IntField(j, "seq", 0, 0xFFFFFFFFLL, &error)) v.seq = seq;
  if (v.sensor.empty()) {
    v.error = "missing or invalid \"sensor\"";
    return v;
  }
  if (!in.sensor.empty() && v.sensor != in.sensor) {
    v.error = "payload sensor '" + v.sensor + "' differs from the topic's '" + in.sensor + "'";
    return v;
  }
  if (!v.seq) {
    v.error = error;
    return v;
  }
  const Crusher* crusher = registry.Find(in.crusher);
  if (!crusher) {
    v.error = "unknown crusher '" + in.crusher + "'";
    return v;
  }
  const core::SensorInfo* sensor = crusher->config.FindSensor(v.sensor);
  if (!sensor) {
    v.error = "unknown sensor '" + v.sensor + "' (not in " + in.crusher + "'s crusher.json)";
    return v;
  }
  const auto t = j.find("time");
  if (t == j.end() || !t->is_string()) {
    v.error = "missing or non-string \"time\"";
    return v;
  }
  const auto time = core::ParseIsoTime(t->get<std::string>());
  if (!time) {
    v.error = "\"time\" '" + t->get<std::string>() + "' is not an ISO-8601 UTC time";
    return v;
  }
  const int64_t time_s = time->time_since_epoch().count();
  const int64_t installed_s = crusher->config.installed_at.time_since_epoch().count();
  if (time_s < installed_s - 86400) {
    v.error = "\"time\" " + t->get<std::string>() + " is before the liner was installed (" +
              core::FormatIsoTime(crusher->config.installed_at) + ")";
    return v;
  }
  if (time_s > now_s + 86400) {
    v.error = "\"time\" " + t->get<std::string>() + " is more than a day in the future";
    return v;
  }
  const auto th = j.find("thickness_mm");
  if (th == j.end() || !th->is_number()) {
    v.error = "missing or non-numeric \"thickness_mm\"";
    return v;
  }
  const double thickness = th->get<double>();
  if (!std::isfinite(thickness) || thickness < 0 || thickness > sensor->thickness_new_mm + 1.0) {
    v.error = "\"thickness_mm\" " + th->dump() + " is outside [0, " + std::to_string(sensor->thickness_new_mm + 1.0) + "]";
    return v;
  }
  StoredReading r;
  r.crusher = in.crusher;
  r.sensor = v.sensor;
  r.seq = *v.seq;
  r.time_s = time_s;
  r.thickness_mm = thickness;
  const auto loops = IntField(j, "loops_intact", 0, 4096, &error);
  const auto flags = loops ? IntField(j, "flags", 0, 0xFFFF, &error) : std::nullopt;
  const auto battery = flags ? IntField(j, "battery_mv", 0, 10000, &error) : std::nullopt;
  if (!battery) {
    v.error = error;
    return v;
  }
  r.loops_intact = *loops;
  r.flags = *flags;
  r.battery_mv = *battery;
  r.payload = in.payload;
  v.reading = std::move(r);
  return v;
}

Ingestor::Ingestor(Store& store, const Registry& registry, std::function<int64_t()> now_s, LiveState* live)
    : store_(store), registry_(registry), live_(live), now_s_(std::move(now_s)) {
  for (const auto& [crusher, site] : store_.CrusherSites()) sites_[crusher] = site;
  // crusher.json's "site" binds; it overrides a binding learnt from the first reading.
  for (const Crusher* c : registry_.All()) {
    if (!c->config.site.empty()) sites_[c->config.crusher_id] = c->config.site;
  }
}

std::optional<std::string> Ingestor::SiteOf(const std::string& crusher) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = sites_.find(crusher);
  if (it == sites_.end()) return std::nullopt;
  return it->second;
}

IngestResult Ingestor::Ingest(const std::vector<Incoming>& batch) {
  std::lock_guard<std::mutex> lock(mutex_);
  IngestResult result;
  const int64_t now = now_s_();
  const int64_t wall = static_cast<int64_t>(
      std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count());
  std::vector<StoredReading> readings;
  std::vector<size_t> reading_index;  // batch index of each reading
  std::vector<Rejected> rejected;
  std::vector<Validation> validations;
  std::vector<bool> foreign_site(batch.size(), false);  // a known crusher heard under another site
  std::map<std::string, std::string> new_sites;         // bound by this batch (first site heard)
  validations.reserve(batch.size());
  for (size_t i = 0; i < batch.size(); ++i) {
    const Incoming& in = batch[i];
    // A message must never fail the batch: whatever validation throws quarantines this one only.
    try {
      validations.push_back(ValidateReading(in, registry_, now));
    } catch (const std::exception& e) {
      validations.push_back({});
      validations.back().error = std::string("cannot validate: ") + e.what();
    }
    Validation& v = validations.back();
    // Sites are identities: a crusher's readings count only under its own site's topics.
    if (!in.site.empty() && registry_.Find(in.crusher)) {
      auto bound = sites_.find(in.crusher);
      auto pending = new_sites.find(in.crusher);
      const std::string* site = bound != sites_.end() ? &bound->second : pending != new_sites.end() ? &pending->second : nullptr;
      if (!site && v.reading) site = &new_sites.emplace(in.crusher, in.site).first->second;
      if (site && *site != in.site) {
        foreign_site[i] = true;
        v.reading.reset();
        v.error =
            "site '" + in.site + "' is not crusher " + in.crusher + "'s site '" + *site + "' (quarantined, not acknowledged)";
      }
    }
    if (v.reading) {
      v.reading->received_s = wall;
      readings.push_back(*v.reading);
      reading_index.push_back(i);
    } else {
      rejected.push_back({wall, in.topic, in.payload, v.error});
    }
  }
  std::unique_lock<std::mutex> commit_order;  // from the commit to live_->Add (LiveState::CommitGuard)
  if (live_) commit_order = live_->CommitGuard();
  const std::vector<InsertOutcome> outcomes =
      store_.Commit(readings, rejected, {new_sites.begin(), new_sites.end()});  // throws: nothing acked
  for (const auto& [crusher, site] : new_sites) {
    sites_[crusher] = site;
    result.log.push_back("crusher " + crusher + " is now bound to site '" + site +
                         "' (the first site it was heard from; set \"site\" in its crusher.json to choose)");
  }

  std::map<std::tuple<std::string, std::string, std::string>, std::set<int64_t>> acks;
  auto& crusher_counters = per_crusher_;
  for (size_t k = 0; k < outcomes.size(); ++k) {
    const StoredReading& r = readings[k];
    const Incoming& in = batch[reading_index[k]];
    IngestCounters& cc = crusher_counters[r.crusher];
    switch (outcomes[k]) {
      case InsertOutcome::kStored:
        ++result.stored;
        ++cc.stored;
        result.new_readings.push_back(r);
        break;
      case InsertOutcome::kDuplicate:
        ++result.duplicates;
        ++cc.duplicates;
        break;
      case InsertOutcome::kConflict:
        ++result.conflicts;
        ++cc.conflicts;
        result.log.push_back("conflict: " + r.crusher + "/" + r.sensor + " seq " + std::to_string(r.seq) +
                             " was stored before with another time or thickness; the first is kept");
        break;
    }
    acks[{in.site, r.crusher, r.sensor}].insert(r.seq);
  }
  if (live_) {
    live_->Add(result.new_readings);
    commit_order.unlock();
  }
  for (size_t i = 0; i < batch.size(); ++i) {
    const Validation& v = validations[i];
    if (v.reading) continue;
    ++result.rejected;
    ++crusher_counters[batch[i].crusher].rejected;
    result.log.push_back("rejected " + (batch[i].topic.empty() ? std::string("REST reading") : batch[i].topic) + ": " + v.error);
    // Quarantined in the database: the gateway may drop it (resending cannot make it valid). Not
    // under a site the crusher does not belong to: that publisher is not its gateway.
    if (!foreign_site[i] && v.seq && !v.sensor.empty() && (batch[i].sensor.empty() || batch[i].sensor == v.sensor)) {
      acks[{batch[i].site, batch[i].crusher, v.sensor}].insert(*v.seq);
    }
  }
  for (auto& [key, seqs] : acks) {
    if (std::get<0>(key).empty()) continue;  // REST: no gateway to tell
    result.acks.push_back({std::get<0>(key), std::get<1>(key), std::get<2>(key), {seqs.begin(), seqs.end()}});
  }
  totals_.stored += static_cast<int64_t>(result.stored);
  totals_.duplicates += static_cast<int64_t>(result.duplicates);
  totals_.conflicts += static_cast<int64_t>(result.conflicts);
  totals_.rejected += static_cast<int64_t>(result.rejected);
  ++totals_.batches;
  return result;
}

IngestCounters Ingestor::Counters() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return totals_;
}

IngestCounters Ingestor::CrusherCounters(const std::string& crusher) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = per_crusher_.find(crusher);
  return it == per_crusher_.end() ? IngestCounters{} : it->second;
}

}  // namespace lw::server
