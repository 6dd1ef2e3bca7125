#include "gateway/messages.hpp"

#include <nlohmann/json.hpp>

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

std::string DevicesJson(const std::vector<DeviceEntry>& devices, const std::string& gateway_id, int64_t now_ms) {
  json list = json::array();
  for (const DeviceEntry& d : devices) {
    json e = {{"address", d.address}, {"first_seen", IsoUtc(d.first_seen_ms)}};
    if (!d.sensor.empty()) e["sensor"] = d.sensor;
    if (!d.node_identifier.empty()) e["node_identifier"] = d.node_identifier;
    if (d.device_type >= 0) e["device_type"] = d.device_type;
    list.push_back(std::move(e));
  }
  return Dump({{"gateway", gateway_id}, {"time", IsoUtc(now_ms)}, {"devices", std::move(list)}});
}

std::optional<CommitAck> ParseCommitAck(std::string_view payload, const std::string& topic_sensor, std::string* error) {
  const json j = json::parse(payload, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object()) {
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
  for (const json& s : *seqs) {
    if (!s.is_number_unsigned() || s.get<uint64_t>() > 0xFFFFFFFFull) {
      *error = "\"seqs\" holds " + s.dump() + ", not a 32-bit unsigned sequence number";
      return std::nullopt;
    }
    ack.seqs.push_back(static_cast<uint32_t>(s.get<uint64_t>()));
  }
  return ack;
}

}  // namespace lw::gateway
