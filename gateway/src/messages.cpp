#include "gateway/messages.hpp"

#include <algorithm>

namespace lw::gateway {

std::string ReadingJson(const protocol::ReadingsHeader& header, const protocol::SensorRecord& record,
                        const ReadingContext& context) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string bitmap;
  const size_t bitmap_bytes = (header.ladder_loops + 7u) / 8u;
  for (size_t i = 0; i < bitmap_bytes && i < protocol::kMaxBitmapBytes; ++i) {
    bitmap.push_back(kHex[record.loop_bitmap[i] >> 4]);
    bitmap.push_back(kHex[record.loop_bitmap[i] & 0xF]);
  }
  mqtt::ReadingMessage m;
  m.sensor = std::to_string(header.sensor_id);
  m.seq = record.seq;
  m.time = mqtt::IsoUtc(context.received_ms - static_cast<int64_t>(record.age_s) * 1000);
  m.thickness_mm = record.thickness_dmm / 10.0;
  m.loops_intact = record.loops_intact;
  m.flags = record.flags;
  m.battery_mv = record.battery_mv;
  m.temperature_c = record.temperature_c;
  m.ladder_loops = header.ladder_loops;
  m.loop_bitmap = std::move(bitmap);
  m.dropped_total = header.dropped_total;
  m.address = mqtt::AddressHex(context.source_address);
  m.gateway = context.gateway_id;
  m.received = mqtt::IsoUtc(context.received_ms);
  return mqtt::EncodeReading(m);
}

std::string DeviceJson(const std::vector<DeviceEntry>& entries, const std::string& gateway_id, int64_t now_ms) {
  mqtt::DeviceMessage m;
  m.gateway = gateway_id;
  m.time = mqtt::IsoUtc(now_ms);
  int64_t first_seen = 0;
  for (const DeviceEntry& d : entries) {
    m.address = d.address;
    if (first_seen == 0 || d.first_seen_ms < first_seen) first_seen = d.first_seen_ms;
    if (!d.sensor.empty()) m.sensors.push_back(d.sensor);
    if (!d.node_identifier.empty()) m.node_identifier = d.node_identifier;
    if (d.device_type >= 0) m.device_type = d.device_type;
  }
  m.first_seen = mqtt::IsoUtc(first_seen);
  // Node identifiers come from the radio: the encoder never lets a byte that is not UTF-8 stop the message.
  return mqtt::EncodeDevice(m);
}

}  // namespace lw::gateway
