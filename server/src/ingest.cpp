#include "server/ingest.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <tuple>

#include "core/time.hpp"

namespace lw::server {
namespace {

using nlohmann::json;

std::vector<std::string_view> Split(std::string_view s, char sep) {
  std::vector<std::string_view> out;
  size_t start = 0;
  while (true) {
    const size_t p = s.find(sep, start);
    out.push_back(s.substr(start, p == std::string_view::npos ? std::string_view::npos : p - start));
    if (p == std::string_view::npos) break;
    start = p + 1;
  }
  return out;
}

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
  } else if (it->is_number_float() && std::floor(it->get<double>()) == it->get<double>() &&
             std::fabs(it->get<double>()) < 9e15) {
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

}  // namespace

std::optional<ReadingTopic> ParseReadingTopic(std::string_view topic, std::string_view root) {
  if (topic.substr(0, root.size()) != root) return std::nullopt;
  const auto parts = Split(topic.substr(root.size()), '/');
  if (parts.size() != 5 || parts[2] != "sensors" || parts[4] != "reading") return std::nullopt;
  if (parts[0].empty() || parts[1].empty() || parts[3].empty()) return std::nullopt;
  return ReadingTopic{std::string(parts[0]), std::string(parts[1]), std::string(parts[3])};
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
      if (escaped) escaped = false;
      else if (ch == '\\') escaped = true;
      else if (ch == '"') in_string = false;
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
  try {
    j = json::parse(in.payload);
  } catch (const json::parse_error&) {
    v.error = "malformed JSON";
    return v;
  }
  if (!j.is_object()) {
    v.error = "not a JSON object";
    return v;
  }
  // Identify first, so that even a rejected message can be acknowledged once quarantined.
  const auto s = j.find("sensor");
  if (s != j.end() && s->is_string()) v.sensor = s->get<std::string>();
  else if (s != j.end() && s->is_number_integer()) v.sensor = std::to_string(s->get<int64_t>());
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

std::string CommitAckJson(const Ack& ack, const std::string& time) {
  const json payload = {{"sensor", ack.sensor}, {"seqs", ack.seqs}, {"time", time}};
  return payload.dump(-1, ' ', false, json::error_handler_t::replace);
}

Ingestor::Ingestor(Store& store, const Registry& registry, std::function<int64_t()> now_s)
    : store_(store), registry_(registry), now_s_(std::move(now_s)) {}

IngestResult Ingestor::Ingest(const std::vector<Incoming>& batch) {
  std::lock_guard<std::mutex> lock(mutex_);
  IngestResult result;
  const int64_t now = now_s_();
  const int64_t wall = static_cast<int64_t>(std::chrono::duration_cast<std::chrono::seconds>(
                                                std::chrono::system_clock::now().time_since_epoch())
                                                .count());
  std::vector<StoredReading> readings;
  std::vector<size_t> reading_index;  // batch index of each reading
  std::vector<Rejected> rejected;
  std::vector<Validation> validations;
  validations.reserve(batch.size());
  for (size_t i = 0; i < batch.size(); ++i) {
    validations.push_back(ValidateReading(batch[i], registry_, now));
    Validation& v = validations.back();
    if (v.reading) {
      v.reading->received_s = wall;
      readings.push_back(*v.reading);
      reading_index.push_back(i);
    } else {
      rejected.push_back({wall, batch[i].topic, batch[i].payload, v.error});
    }
  }
  const std::vector<InsertOutcome> outcomes = store_.Commit(readings, rejected);  // throws: nothing acked

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
    if (!in.site.empty()) result.sites.insert({r.crusher, in.site});
  }
  for (size_t i = 0; i < batch.size(); ++i) {
    const Validation& v = validations[i];
    if (v.reading) continue;
    ++result.rejected;
    ++crusher_counters[batch[i].crusher].rejected;
    result.log.push_back("rejected " + (batch[i].topic.empty() ? std::string("REST reading") : batch[i].topic) + ": " + v.error);
    // Quarantined in the database: the gateway may drop it (resending cannot make it valid).
    if (v.seq && !v.sensor.empty() && (batch[i].sensor.empty() || batch[i].sensor == v.sensor)) {
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
