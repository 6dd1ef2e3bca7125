#include "server/ingest.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <tuple>

#include "core/time.hpp"
#include "mqtt/messages.hpp"

namespace lw::server {
bool IsFaultReading(int64_t flags, int64_t loops_intact) {
  constexpr int64_t kAllOpen = 1 << 3, kSpiStuck = 1 << 4;
  if (flags & kSpiStuck) return true;
  return (flags & kAllOpen) && loops_intact > 0;
}

Validation ValidateReading(const Incoming& in, const Registry& registry, int64_t now_s) {
  Validation v;
  mqtt::ReadingIdentity id;
  std::string decode_error;
  const std::optional<mqtt::ReadingMessage> m = mqtt::DecodeReading(in.payload, &decode_error, &id);
  // The identity even of a refused message, so that it can be acknowledged once quarantined.
  v.sensor = id.sensor;
  if (id.seq) v.seq = *id.seq;
  // The decoder stops at the first fault; the registry's checks on the identity come before the
  // decoder's on the other fields (an unknown sensor is named as such, whatever else is wrong).
  if (!id.object || v.sensor.empty()) {
    v.error = decode_error;
    return v;
  }
  if (!in.sensor.empty() && v.sensor != in.sensor) {
    v.error = "payload sensor '" + v.sensor + "' differs from the topic's '" + in.sensor + "'";
    return v;
  }
  if (!v.seq) {
    v.error = decode_error;
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
  if (!m) {
    v.error = decode_error;
    return v;
  }
  const auto time = core::ParseIsoTime(m->time);
  if (!time) {
    v.error = "\"time\" '" + m->time + "' is not an ISO-8601 UTC time";
    return v;
  }
  const int64_t time_s = time->time_since_epoch().count();
  const int64_t installed_s = crusher->config.installed_at.time_since_epoch().count();
  if (time_s < installed_s - 86400) {
    v.error =
        "\"time\" " + m->time + " is before the liner was installed (" + core::FormatIsoTime(crusher->config.installed_at) + ")";
    return v;
  }
  if (time_s > now_s + 86400) {
    v.error = "\"time\" " + m->time + " is more than a day in the future";
    return v;
  }
  const double thickness = m->thickness_mm;
  if (!std::isfinite(thickness) || thickness < 0 || thickness > sensor->thickness_new_mm + 1.0) {
    v.error = "\"thickness_mm\" " + nlohmann::json(thickness).dump() + " is outside [0, " +
              std::to_string(sensor->thickness_new_mm + 1.0) + "]";
    return v;
  }
  StoredReading r;
  r.crusher = in.crusher;
  r.sensor = v.sensor;
  r.seq = *v.seq;
  r.time_s = time_s;
  r.thickness_mm = thickness;
  r.loops_intact = m->loops_intact;
  r.flags = m->flags;
  r.battery_mv = m->battery_mv;
  r.payload = in.payload;
  v.reading = std::move(r);
  return v;
}

namespace {

/// `messages` with every batch (several records of one sensor in one message, docs/mqtt.md)
/// replaced by its records, in order, each a message of its own: validated, stored and acked
/// alone. `messages` itself when it holds no batch. A malformed batch stays one message and
/// `(*malformed)[i]` says what is wrong with it (then `malformed` has an entry per message).
const std::vector<Incoming>& SplitBatches(const std::vector<Incoming>& messages, std::vector<Incoming>* expanded,
                                          std::vector<std::string>* malformed) {
  std::vector<std::string> records;
  std::string error;
  for (size_t i = 0; i < messages.size(); ++i) {
    const bool ok = mqtt::SplitReadingMessage(messages[i].payload, &records, &error);
    if (ok && records.empty() && expanded->empty() && malformed->empty()) continue;  // none so far
    if (expanded->empty() && malformed->empty()) {
      expanded->assign(messages.begin(), messages.begin() + static_cast<std::ptrdiff_t>(i));
      malformed->assign(i, std::string());
    }
    if (!ok || records.empty()) {
      expanded->push_back(messages[i]);
      malformed->push_back(ok ? std::string() : error);
      continue;
    }
    for (std::string& r : records) {
      Incoming one = messages[i];
      one.payload = std::move(r);
      expanded->push_back(std::move(one));
      malformed->emplace_back();
    }
  }
  return malformed->empty() ? messages : *expanded;
}

}  // namespace

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

IngestResult Ingestor::Ingest(const std::vector<Incoming>& messages) {
  std::vector<Incoming> expanded;
  std::vector<std::string> malformed;
  const std::vector<Incoming>& batch = SplitBatches(messages, &expanded, &malformed);
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
      if (!malformed.empty() && !malformed[i].empty()) {
        validations.push_back({});
        validations.back().sensor = in.sensor;  // no seq: nothing to acknowledge
        validations.back().error = malformed[i];
      } else {
        validations.push_back(ValidateReading(in, registry_, now));
      }
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
      readings.push_back(std::move(*v.reading));  // v.reading stays set: "valid" for the loops below
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
    StoredReading& r = readings[k];
    const Incoming& in = batch[reading_index[k]];
    IngestCounters& cc = crusher_counters[r.crusher];
    acks[{in.site, r.crusher, r.sensor}].insert(r.seq);
    switch (outcomes[k]) {
      case InsertOutcome::kStored:
        ++result.stored;
        ++cc.stored;
        result.new_readings.push_back(std::move(r));  // not used below
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
