#pragma once
// Helpers for the gateway unit tests: coordinator frames built with the shared protocol library,
// a temp directory, and the fakes for the publisher and the radio (tests/fakes/).
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "fakes/fake_publisher.hpp"
#include "fakes/fake_radio.hpp"
#include "support/temp_directory.hpp"
#include "protocol/frame_decoder.hpp"
#include "protocol/sensor_payload.hpp"
#include "protocol/xbee_api.hpp"

namespace lw::gateway::test {

inline protocol::SensorRecord MakeRecord(uint32_t seq, uint16_t thickness_dmm = 870, uint16_t flags = 0) {
  protocol::SensorRecord r;
  r.seq = seq;
  r.age_s = 5;
  r.thickness_dmm = thickness_dmm;
  r.loops_intact = static_cast<uint8_t>(thickness_dmm / 10);
  r.flags = flags;
  r.battery_mv = 3550;
  r.temperature_c = 31;
  for (size_t i = 0; i < protocol::kMaxBitmapBytes; ++i) r.loop_bitmap[i] = 0xFF;
  return r;
}

/// Wire bytes of a 0x90 Receive Packet from `src64` carrying a readings payload.
inline std::vector<uint8_t> ReadingsFrame(protocol::ApiMode mode, uint64_t src64, uint32_t sensor_id,
                                          const std::vector<protocol::SensorRecord>& records, uint8_t ladder_loops = 16) {
  protocol::ReadingsHeader h;
  h.sensor_id = sensor_id;
  h.ladder_loops = ladder_loops;
  uint8_t payload[protocol::kMaxRfPayload];
  size_t payload_len = 0;
  if (protocol::EncodeReadings(h, records.data(), records.size(), payload, sizeof payload, &payload_len) !=
      protocol::PayloadStatus::kOk) {
    return {};
  }
  std::vector<uint8_t> wire(protocol::kMaxWireFrame);
  wire.resize(protocol::EncodeReceivePacket(mode, {src64, 0x1234, 0x01, payload, payload_len}, wire.data(), wire.size()));
  return wire;
}

/// Wire bytes of any frame data.
inline std::vector<uint8_t> Wire(protocol::ApiMode mode, const std::vector<uint8_t>& frame_data) {
  std::vector<uint8_t> wire(protocol::kMaxWireFrame);
  wire.resize(protocol::EncodeFrame(mode, frame_data.data(), frame_data.size(), wire.data(), wire.size()));
  return wire;
}

}  // namespace lw::gateway::test
