#pragma once
/// The gateway's side of the messages of docs/mqtt.md (their codecs are lw::mqtt's): a radio
/// record as a reading message, the registry entries of one radio as its device message, and log
/// lines made safe. Pure functions, no I/O.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "core/log.hpp"
#include "gateway/spool.hpp"
#include "mqtt/messages.hpp"
#include "protocol/sensor_payload.hpp"

namespace lw::gateway {

/// The commit-ack limit (config.cpp bounds --window by it).
using mqtt::kMaxCommitAckSeqs;

/// Context of one received readings message.
struct ReadingContext {
  uint64_t source_address = 0;
  std::string gateway_id;
  int64_t received_ms = 0;
};

/// The reading message of docs/mqtt.md for one record.
std::string ReadingJson(const protocol::ReadingsHeader& header, const protocol::SensorRecord& record,
                        const ReadingContext& context);

/// The retained message of one radio on `gateway/devices/{address}` from the registry entries of
/// that address (`entries` all have the same address): every sensor, the earliest first_seen,
/// the node identifier and device type when known.
std::string DeviceJson(const std::vector<DeviceEntry>& entries, const std::string& gateway_id, int64_t now_ms);

/// core::SanitizeForLog (core/log.hpp), the one the server's log uses too.
using core::SanitizeForLog;

}  // namespace lw::gateway
