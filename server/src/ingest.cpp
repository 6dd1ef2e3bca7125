#include "server/ingest.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <tuple>

#include "core/time.hpp"
#include "mqtt/messages.hpp"

namespace lw::server {
namespace {

/// ValidateReading's checks once the payload is decoded (`m`, `decode_error` and `id`: DecodeReading's
/// verdict on it). The reading it returns has no payload yet.
Validation CheckReading(const Incoming& in, const std::optional<mqtt::ReadingMessage>& m, const std::string& decode_error,
                        const mqtt::ReadingIdentity& id, const Registry& registry, int64_t now_s) {
  Validation v;
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
    // A `--crusher` typo or a folder that failed to load: resent until one of that id loads.
    v.error = "unknown crusher '" + in.crusher + "' (held, not acknowledged: stored once a crusher folder of that id loads)";
    v.held = "unknown_crusher";
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
  if (*time < crusher->config.LinerStart()) {
    v.error =
        "\"time\" " + m->time + " is before the liner was installed (" + core::FormatIsoTime(crusher->config.installed_at) + ")";
    return v;
  }
  if (time_s > now_s + 86400) {
    v.error = "\"time\" " + m->time + " is more than a day in the future";
    return v;
  }
  const double thickness = m->thickness_mm;
  if (const std::string error = core::ReadingThicknessError(*sensor, thickness); !error.empty()) {
    v.error = "\"thickness_mm\" " + error;
    return v;
  }
  if (time_s > now_s + kFutureSlackS) {
    v.error = "\"time\" " + m->time + " is " + std::to_string(time_s - now_s) + " s after the server's clock (" +
              core::FormatIsoSeconds(now_s) + "): held, not acknowledged, until it is at most " + std::to_string(kFutureSlackS) +
              " s ahead";
    v.held = "future";
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
  v.reading = std::move(r);
  return v;
}

/// The kRejectionReasons class of a record CheckReading (or the site check) refused, from what is
/// known of it, in CheckReading's order; the message itself is only looked at for the last checks.
const char* RejectionReason(const Incoming& in, const Validation& v, bool foreign_site, const Registry& registry) {
  if (foreign_site) return "foreign_site";
  if (v.error.rfind("cannot validate", 0) == 0) return "internal";
  if (v.sensor.empty()) return "malformed";
  if (!in.sensor.empty() && v.sensor != in.sensor) return "sensor_mismatch";
  if (!v.seq) return "malformed";
  const Crusher* crusher = registry.Find(in.crusher);
  if (!crusher) return "internal";  // held, never rejected
  if (!crusher->config.FindSensor(v.sensor)) return "unknown_sensor";
  if (v.error.rfind("\"time\" ", 0) == 0) return "time";
  if (v.error.rfind("\"thickness_mm\" ", 0) == 0 && v.error.find(" is outside ") != std::string::npos) return "thickness";
  return "malformed";
}

// One entry per record: a one-record message, or each record of a batch (docs/mqtt.md), each
// validated, stored and acked alone. A malformed batch is one entry, rejected whole.
struct Record {
  size_t message = 0;   ///< its message in `messages`
  std::string payload;  ///< its text: the message's, or the record's within its batch
  Validation v;
  bool foreign_site = false;  ///< a known crusher heard under another site
  const char* reason = "";    ///< kRejectionReasons class when rejected
};

std::vector<Record> ValidateRecords(std::vector<Incoming>& messages, const Registry& registry, int64_t now) {
  std::vector<Record> records;
  records.reserve(messages.size());
  std::vector<mqtt::BatchRecord> parts;
  // A record must never fail the others: whatever its validation throws quarantines it alone.
  const auto add = [&](size_t message, std::string payload, const auto& validate) {
    Record& r = records.emplace_back();
    r.message = message;
    r.payload = std::move(payload);
    try {
      r.v = validate(r.payload);
    } catch (const std::exception& e) {
      r.v = {};
      r.v.error = std::string("cannot validate: ") + e.what();
    }
  };
  for (size_t i = 0; i < messages.size(); ++i) {
    Incoming& in = messages[i];
    std::string malformed;
    bool well_formed = false;
    try {
      well_formed = mqtt::SplitAndDecodeReadingMessage(in.payload, &parts, &malformed);
    } catch (const std::exception& e) {
      parts.clear();
      malformed = std::string("cannot validate: ") + e.what();
    }
    if (!well_formed) {
      add(i, std::move(in.payload), [&](const std::string&) {
        Validation v;
        v.sensor = in.sensor;  // no seq: nothing to acknowledge
        v.error = malformed;
        return v;
      });
    } else if (parts.empty()) {
      add(i, std::move(in.payload), [&](const std::string& text) {
        mqtt::ReadingIdentity id;
        std::string error;
        const std::optional<mqtt::ReadingMessage> m = mqtt::DecodeReading(text, &error, &id);
        return CheckReading(in, m, error, id, registry, now);
      });
    } else {
      // Sized for the rest of the call at the first batch, assuming the messages still to come
      // carry as many records as this one: grown record by record, the reallocations moved every
      // record again into fresh pages (7.7 % of the main loop with batches of 64).
      if (records.capacity() < records.size() + parts.size()) {
        records.reserve(std::max(2 * records.capacity(), records.size() + parts.size() * (messages.size() - i)));
      }
      for (mqtt::BatchRecord& part : parts) {
        add(i, std::move(part.text),
            [&](const std::string&) { return CheckReading(in, part.reading, part.error, part.identity, registry, now); });
      }
    }
  }
  return records;
}

// Acks per (site, crusher, sensor); records come sensor by sensor, so the last key is tried first.
class Acks {
 public:
  void Add(const std::string& site, const std::string& crusher, const std::string& sensor, int64_t seq) {
    if (last_ == acks_.end() || std::get<2>(last_->first) != sensor || std::get<1>(last_->first) != crusher ||
        std::get<0>(last_->first) != site) {
      last_ = acks_.try_emplace(Key{site, crusher, sensor}).first;
    }
    last_->second.push_back(seq);
  }
  /// Each key's seqs, ascending and once each, into `out` (REST's, without a site, left out).
  void MoveTo(std::vector<Ack>& out) {
    for (auto& [key, seqs] : acks_) {
      if (std::get<0>(key).empty()) continue;  // REST: no gateway to tell
      std::sort(seqs.begin(), seqs.end());
      seqs.erase(std::unique(seqs.begin(), seqs.end()), seqs.end());
      out.push_back({std::get<0>(key), std::get<1>(key), std::get<2>(key), std::move(seqs)});
    }
  }

 private:
  using Key = std::tuple<std::string, std::string, std::string>;
  std::map<Key, std::vector<int64_t>> acks_;
  std::map<Key, std::vector<int64_t>>::iterator last_ = acks_.end();
};

// Per-crusher counters, the last crusher's tried first.
class PerCrusherCounters {
 public:
  explicit PerCrusherCounters(std::map<std::string, IngestCounters>& per_crusher) : per_crusher_(per_crusher) {}
  IngestCounters& Of(const std::string& crusher) {
    if (last_ == per_crusher_.end() || last_->first != crusher) last_ = per_crusher_.try_emplace(crusher).first;
    return last_->second;
  }

 private:
  std::map<std::string, IngestCounters>& per_crusher_;
  std::map<std::string, IngestCounters>::iterator last_ = per_crusher_.end();
};

// The store's outcome of each reading counted and acked; returns the conflicting readings, to be
// quarantined.
std::vector<Rejected> CountOutcomes(const std::vector<InsertOutcome>& outcomes, std::vector<StoredReading>& readings,
                                    const std::vector<size_t>& reading_index, const std::vector<Record>& records,
                                    const std::vector<Incoming>& messages, int64_t wall, Acks& acks, PerCrusherCounters& counters,
                                    IngestResult& result) {
  result.new_readings.reserve(readings.size());
  std::vector<Rejected> conflicted;
  for (size_t k = 0; k < outcomes.size(); ++k) {
    StoredReading& r = readings[k];
    const Incoming& in = messages[records[reading_index[k]].message];
    acks.Add(in.site, r.crusher, r.sensor, r.seq);
    switch (outcomes[k]) {
      case InsertOutcome::kStored:
        ++result.stored;
        ++counters.Of(r.crusher).stored;
        result.new_readings.push_back(std::move(r));  // not used below
        break;
      case InsertOutcome::kDuplicate:
        ++result.duplicates;
        ++counters.Of(r.crusher).duplicates;
        break;
      case InsertOutcome::kConflict:
        ++result.conflicts;
        ++counters.Of(r.crusher).conflicts;
        result.log.push_back("conflict: " + r.crusher + "/" + r.sensor + " seq " + std::to_string(r.seq) +
                             " was stored before with another time or thickness; the first is kept");
        conflicted.push_back({wall, in.topic, std::move(r.payload), result.log.back() + ", this one quarantined", "conflict"});
        break;
    }
  }
  return conflicted;
}

// The records that are not readings counted, held or rejected, and the rejected ones acked.
void CountTheOthers(const std::vector<Record>& records, const std::vector<Incoming>& messages, const Registry& registry,
                    Acks& acks, PerCrusherCounters& counters, IngestCounters& totals, IngestResult& result) {
  for (const Record& rec : records) {
    const Validation& v = rec.v;
    if (v.reading) continue;
    const Incoming& in = messages[rec.message];
    // Per crusher for known crushers only: a flood of made-up ids must not grow the map.
    const bool known = registry.Find(in.crusher) != nullptr;
    if (v.held) {
      ++result.held;
      if (known) ++counters.Of(in.crusher).held;
      ++totals.held_by_reason[v.held];
      result.log.push_back("held " + (in.topic.empty() ? std::string("REST reading") : in.topic) + ": " + v.error);
      continue;  // not acknowledged: the gateway publishes it again (docs/gateway.md, Replay)
    }
    ++result.rejected;
    if (known) ++counters.Of(in.crusher).rejected;
    ++totals.rejected_by_reason[rec.reason];
    result.log.push_back("rejected " + (in.topic.empty() ? std::string("REST reading") : in.topic) + ": " + v.error);
    // Quarantined in the database: the gateway may drop it (resending cannot make it valid). Not
    // under a site the crusher does not belong to: that publisher is not its gateway.
    if (!rec.foreign_site && v.seq && !v.sensor.empty() && (in.sensor.empty() || in.sensor == v.sensor)) {
      acks.Add(in.site, in.crusher, v.sensor, *v.seq);
    }
  }
}

void AddTotals(const IngestResult& result, IngestCounters& totals) {
  totals.stored += static_cast<int64_t>(result.stored);
  totals.duplicates += static_cast<int64_t>(result.duplicates);
  totals.conflicts += static_cast<int64_t>(result.conflicts);
  totals.rejected += static_cast<int64_t>(result.rejected);
  totals.held += static_cast<int64_t>(result.held);
  ++totals.batches;
}

}  // namespace

Validation ValidateReading(const Incoming& in, const Registry& registry, int64_t now_s) {
  mqtt::ReadingIdentity id;
  std::string decode_error;
  const std::optional<mqtt::ReadingMessage> m = mqtt::DecodeReading(in.payload, &decode_error, &id);
  Validation v = CheckReading(in, m, decode_error, id, registry, now_s);
  if (v.reading) v.reading->payload = in.payload;
  return v;
}

Ingestor::Ingestor(Store& store, const Registry& registry, std::function<int64_t()> now_s, LiveState* live)
    : store_(store), registry_(registry), live_(live), now_s_(std::move(now_s)) {
  for (const Crusher* c : registry_.All()) named_sites_ |= !c->config.site.empty();
  for (const auto& [crusher, site] : store_.CrusherSites()) sites_[crusher] = site;
  for (const Crusher* c : registry_.All()) {
    const std::string& id = c->config.crusher_id;
    // crusher.json's "site" binds; it overrides a binding learnt from the first reading.
    if (!c->config.site.empty()) {
      sites_[id] = c->config.site;
      continue;
    }
    if (!named_sites_) continue;
    // With named sites a binding learnt from a first reading is not kept: whoever spoke first won it.
    const auto learnt = sites_.find(id);
    warnings_.push_back("crusher " + id + " has no \"site\" in " + (c->dir / "crusher.json").string() +
                        " and this server's other crushers name theirs: its readings are held (not stored, not "
                        "acknowledged) until you add \"site\": \"SITE\" (its gateway's --site" +
                        (learnt == sites_.end() ? std::string() : "; it was first heard from '" + learnt->second + "'") +
                        ") and restart");
    if (learnt != sites_.end()) sites_.erase(learnt);
  }
}

void Ingestor::CheckSite(const Incoming& in, Validation& v, bool* foreign, std::map<std::string, std::string>& new_sites) const {
  const Crusher* crusher = in.site.empty() ? nullptr : registry_.Find(in.crusher);  // REST: no site
  if (!crusher || v.held) return;
  if (named_sites_ && crusher->config.site.empty()) {
    v.reading.reset();
    v.held = "no_site";
    v.error = "crusher " + in.crusher +
              " has no \"site\" in its crusher.json and this server's other crushers name theirs "
              "(held, not acknowledged: add \"site\": \"" +
              in.site + "\" to " + (crusher->dir / "crusher.json").string() + " if that is its site, and restart)";
    return;
  }
  const auto bound = sites_.find(in.crusher);
  const auto pending = new_sites.find(in.crusher);
  const std::string* site = bound != sites_.end() ? &bound->second : pending != new_sites.end() ? &pending->second : nullptr;
  if (!site && v.reading) site = &new_sites.emplace(in.crusher, in.site).first->second;
  if (site && *site != in.site) {
    *foreign = true;
    v.reading.reset();
    v.error = "site '" + in.site + "' is not crusher " + in.crusher + "'s site '" + *site + "' (quarantined, not acknowledged)";
  }
}

std::optional<std::string> Ingestor::SiteOf(const std::string& crusher) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = sites_.find(crusher);
  if (it == sites_.end()) return std::nullopt;
  return it->second;
}

IngestResult Ingestor::Ingest(std::vector<Incoming> messages) {
  std::lock_guard<std::mutex> lock(mutex_);
  IngestResult result;
  const int64_t now = now_s_();
  const int64_t wall = static_cast<int64_t>(
      std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count());
  std::vector<Record> records = ValidateRecords(messages, registry_, now);
  // Each record a reading to store, a rejection to quarantine or held (here: CheckSite reads sites_).
  std::vector<StoredReading> readings;
  std::vector<size_t> reading_index;  // index in `records` of each reading
  readings.reserve(records.size());
  reading_index.reserve(records.size());
  std::vector<Rejected> rejected;
  std::map<std::string, std::string> new_sites;  // bound by this call (first site heard)
  for (size_t k = 0; k < records.size(); ++k) {
    Record& rec = records[k];
    const Incoming& in = messages[rec.message];
    Validation& v = rec.v;
    // Sites are identities: a crusher's readings count only under its own site's topics.
    CheckSite(in, v, &rec.foreign_site, new_sites);
    if (v.reading) {
      v.reading->received_s = wall;
      v.reading->payload = std::move(rec.payload);
      readings.push_back(std::move(*v.reading));  // v.reading stays set: "valid" for the loops below
      reading_index.push_back(k);
    } else if (!v.held) {  // a held record is stored nowhere: its gateway keeps it
      rec.reason = RejectionReason(in, v, rec.foreign_site, registry_);
      rejected.push_back({wall, in.topic, rec.payload, v.error, rec.reason});
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

  Acks acks;
  PerCrusherCounters counters(per_crusher_);
  const std::vector<Rejected> conflicted =
      CountOutcomes(outcomes, readings, reading_index, records, messages, wall, acks, counters, result);
  if (live_) {
    live_->Add(result.new_readings);
    commit_order.unlock();
  }
  // A conflict's reading is quarantined, not dropped (a board that restarted its seqs under a kept
  // id: docs/server.md). Before any ack: a crash in between resends it, and it conflicts again.
  if (!conflicted.empty()) store_.Commit({}, conflicted);
  CountTheOthers(records, messages, registry_, acks, counters, totals_, result);
  acks.MoveTo(result.acks);
  AddTotals(result, totals_);
  return result;
}

int64_t Ingestor::NowS() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return now_s_();
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
