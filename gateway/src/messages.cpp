#include "gateway/messages.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <ctime>

namespace lw::gateway {

using nlohmann::json;

namespace {
/// Text from the radio (NI strings) or the host is not always UTF-8: invalid bytes become U+FFFD
/// instead of an exception that would lose the message.
std::string Dump(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }
}  // namespace

std::string IsoUtc(int64_t unix_ms) {
  int64_t secs = unix_ms / 1000;
  if (unix_ms < 0 && unix_ms % 1000 != 0) --secs;
  const time_t t = static_cast<time_t>(secs);
  struct tm tm_utc {};
  gmtime_r(&t, &tm_utc);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm_utc);
  return buf;
}

std::string AddressHex(uint64_t address) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llX", static_cast<unsigned long long>(address));
  return buf;
}

std::vector<std::string> FlagNames(uint16_t flags) {
  static constexpr const char* kNames[] = {"heartbeat", "loop_healed", "non_contiguous", "all_open",
                                           "spi_stuck", "flicker",     "low_battery",    "boot",
                                           "watchdog_reset", "dropped"};
  std::vector<std::string> out;
  for (unsigned bit = 0; bit < 16; ++bit) {
    if (!(flags & (1u << bit))) continue;
    out.push_back(bit < std::size(kNames) ? kNames[bit] : "bit" + std::to_string(bit));
  }
  return out;
}

std::string ReadingJson(const protocol::ReadingsHeader& header, const protocol::SensorRecord& record,
                        const ReadingContext& context) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string bitmap;
  const size_t bitmap_bytes = (header.ladder_loops + 7u) / 8u;
  for (size_t i = 0; i < bitmap_bytes && i < protocol::kMaxBitmapBytes; ++i) {
    bitmap.push_back(kHex[record.loop_bitmap[i] >> 4]);
    bitmap.push_back(kHex[record.loop_bitmap[i] & 0xF]);
  }
  const json j = {
      {"sensor", std::to_string(header.sensor_id)},
      {"seq", record.seq},
      {"time", IsoUtc(context.received_ms - static_cast<int64_t>(record.age_s) * 1000)},
      {"thickness_mm", record.thickness_dmm / 10.0},
      {"loops_intact", record.loops_intact},
      {"flags", record.flags},
      {"flag_names", FlagNames(record.flags)},
      {"battery_mv", record.battery_mv},
      {"temperature_c", record.temperature_c},
      {"ladder_loops", header.ladder_loops},
      {"loop_bitmap", bitmap},
      {"dropped_total", header.dropped_total},
      {"address", AddressHex(context.source_address)},
      {"gateway", context.gateway_id},
      {"received", IsoUtc(context.received_ms)},
  };
  return Dump(j);
}

std::string StatusJson(bool online, const std::string& gateway_id, int64_t now_ms) {
  return Dump({{"state", online ? "online" : "offline"}, {"gateway", gateway_id}, {"time", IsoUtc(now_ms)}});
}

std::string DeviceJson(const std::vector<DeviceEntry>& entries, const std::string& gateway_id, int64_t now_ms) {
  json j = {{"gateway", gateway_id}, {"time", IsoUtc(now_ms)}};
  json sensors = json::array();
  int64_t first_seen = 0;
  for (const DeviceEntry& d : entries) {
    j["address"] = d.address;
    if (first_seen == 0 || d.first_seen_ms < first_seen) first_seen = d.first_seen_ms;
    if (!d.sensor.empty()) sensors.push_back(d.sensor);
    if (!d.node_identifier.empty()) j["node_identifier"] = d.node_identifier;
    if (d.device_type >= 0) j["device_type"] = d.device_type;
  }
  j["first_seen"] = IsoUtc(first_seen);
  j["sensors"] = std::move(sensors);
  // Node identifiers come from the radio: never let a byte that is not UTF-8 stop the message.
  return Dump(j);
}

std::string SanitizeForLog(std::string_view text, size_t max_bytes) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string out;
  const size_t n = std::min(text.size(), max_bytes);
  out.reserve(n + 16);
  for (size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c == '\\') {
      out += "\\\\";
    } else if (c < 0x20 || c >= 0x7F) {
      out += "\\x";
      out.push_back(kHex[c >> 4]);
      out.push_back(kHex[c & 0xF]);
    } else {
      out.push_back(static_cast<char>(c));
    }
  }
  if (text.size() > n) out += "... (" + std::to_string(text.size()) + " bytes)";
  return out;
}

namespace {

// SAX pass that only measures nesting and stops at the first level beyond the limit, so that a
// hostile message (`[[[[...` 100 000 deep) is refused without building a tree or recursing.
class DepthLimit {
 public:
  explicit DepthLimit(size_t max_depth) : max_depth_(max_depth) {}
  bool too_deep() const { return too_deep_; }
  bool null() { return true; }
  bool boolean(bool) { return true; }
  bool number_integer(json::number_integer_t) { return true; }
  bool number_unsigned(json::number_unsigned_t) { return true; }
  bool number_float(json::number_float_t, const json::string_t&) { return true; }
  bool string(json::string_t&) { return true; }
  bool binary(json::binary_t&) { return true; }
  bool key(json::string_t&) { return true; }
  bool start_object(std::size_t) { return Enter(); }
  bool start_array(std::size_t) { return Enter(); }
  bool end_object() { return Leave(); }
  bool end_array() { return Leave(); }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) { return false; }

 private:
  bool Enter() {
    if (++depth_ > max_depth_) too_deep_ = true;
    return !too_deep_;
  }
  bool Leave() {
    --depth_;
    return true;
  }
  size_t max_depth_;
  size_t depth_ = 0;
  bool too_deep_ = false;
};

// Describes a JSON value for an error message without serialising it (a nested value may be
// arbitrarily large): numbers and short strings as they are, anything else by its type.
std::string Describe(const json& v) {
  if (v.is_number() || v.is_boolean() || v.is_null()) return v.dump();
  if (v.is_string() && v.get_ref<const std::string&>().size() <= 32) return v.dump();
  const std::string type = v.type_name();
  return (v.is_object() || v.is_array() ? "an " : "a ") + type;
}

// Size and nesting checked before a tree is built.
std::optional<json> ParseBoundedJson(std::string_view text, size_t max_bytes, size_t max_depth, std::string* error) {
  if (text.size() > max_bytes) {
    *error = "message of " + std::to_string(text.size()) + " bytes (at most " + std::to_string(max_bytes) + ")";
    return std::nullopt;
  }
  DepthLimit limit(max_depth);
  if (!json::sax_parse(text, &limit, json::input_format_t::json, /*strict=*/true, /*ignore_comments=*/false)) {
    *error = limit.too_deep() ? "JSON nested deeper than " + std::to_string(max_depth) + " levels" : "not JSON";
    return std::nullopt;
  }
  json j = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) {
    *error = "not JSON";
    return std::nullopt;
  }
  return j;
}

}  // namespace

std::optional<CommitAck> ParseCommitAck(std::string_view payload, const std::string& topic_sensor, std::string* error) {
  auto parsed = ParseBoundedJson(payload, kMaxCommitAckBytes, kMaxCommitAckDepth, error);
  if (!parsed) return std::nullopt;
  const json& j = *parsed;
  if (!j.is_object()) {
    *error = "not a JSON object";
    return std::nullopt;
  }
  CommitAck ack;
  ack.sensor = topic_sensor;
  if (const auto it = j.find("sensor"); it != j.end()) {
    if (!it->is_string() && !it->is_number_unsigned()) {
      *error = "\"sensor\" must be a string";
      return std::nullopt;
    }
    const std::string named = it->is_string() ? it->get<std::string>() : std::to_string(it->get<uint64_t>());
    if (!topic_sensor.empty() && named != topic_sensor) {
      *error = "\"sensor\" " + named + " does not match the topic's sensor " + topic_sensor;
      return std::nullopt;
    }
    ack.sensor = named;
  }
  if (ack.sensor.empty()) {
    *error = "no sensor";
    return std::nullopt;
  }
  const auto seqs = j.find("seqs");
  if (seqs == j.end() || !seqs->is_array()) {
    *error = "\"seqs\" must be an array of sequence numbers";
    return std::nullopt;
  }
  if (seqs->size() > kMaxCommitAckSeqs) {
    *error = "\"seqs\" holds " + std::to_string(seqs->size()) + " sequence numbers (at most " +
             std::to_string(kMaxCommitAckSeqs) + ")";
    return std::nullopt;
  }
  for (const json& s : *seqs) {
    if (!s.is_number_unsigned() || s.get<uint64_t>() > 0xFFFFFFFFull) {
      *error = "\"seqs\" holds " + Describe(s) + ", not a 32-bit unsigned sequence number";
      return std::nullopt;
    }
    ack.seqs.push_back(static_cast<uint32_t>(s.get<uint64_t>()));
  }
  return ack;
}

}  // namespace lw::gateway
