#pragma once
/// JSON messages of docs/mqtt.md: building readings, status and device messages, parsing commit
/// acknowledgements. Pure functions, no I/O.
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "gateway/spool.hpp"
#include "protocol/sensor_payload.hpp"

namespace lw::gateway {

/// Unix milliseconds as ISO-8601 UTC with second precision: "2026-03-01T12:00:07Z".
std::string IsoUtc(int64_t unix_ms);

/// 64-bit radio address as 16 upper-case hex digits.
std::string AddressHex(uint64_t address);

/// Names of the set RecordFlag bits ("heartbeat", "loop_healed", ...), lowest bit first.
std::vector<std::string> FlagNames(uint16_t flags);

/// Context of one received readings message.
struct ReadingContext {
  uint64_t source_address = 0;
  std::string gateway_id;
  int64_t received_ms = 0;
};

/// The reading message of docs/mqtt.md for one record.
std::string ReadingJson(const protocol::ReadingsHeader& header, const protocol::SensorRecord& record,
                        const ReadingContext& context);

/// `{"state": "online"|"offline", "gateway": ID, "time": ISO}`.
std::string StatusJson(bool online, const std::string& gateway_id, int64_t now_ms);

/// The retained message of one radio on `gateway/devices/{address}`: `{"gateway": ID, "time": ISO,
/// "address", "first_seen", "sensors": [ids], "node_identifier"?, "device_type"?}` from the
/// registry entries of that address (`entries` all have the same address).
std::string DeviceJson(const std::vector<DeviceEntry>& entries, const std::string& gateway_id, int64_t now_ms);

/// `text` made safe for a one-line log: control characters (newline, ESC, ...), DEL, bytes above
/// 0x7E and backslash as `\xNN` / `\\`; longer than `max_bytes`: cut, with the length noted.
std::string SanitizeForLog(std::string_view text, size_t max_bytes = 2048);

/// A parsed commit acknowledgement.
struct CommitAck {
  std::string sensor;
  std::vector<uint32_t> seqs;
};

/// Limits on a commit ack, checked before it is parsed into a tree: the server sends at most one
/// transaction's readings (`--batch-max`, default 1000) in one ack, two levels deep.
inline constexpr size_t kMaxCommitAckBytes = 64 * 1024;
inline constexpr size_t kMaxCommitAckDepth = 8;
inline constexpr size_t kMaxCommitAckSeqs = 10000;

/// Parses `{"sensor": "1001", "seqs": [41, 42]}` received on `.../sensors/{sensor}/committed`.
/// `topic_sensor` is the {sensor} level of the topic; a payload naming another sensor is refused.
/// Returns nullopt and sets `*error` when the message is malformed, over kMaxCommitAckBytes,
/// nested deeper than kMaxCommitAckDepth or holds more than kMaxCommitAckSeqs seqs.
std::optional<CommitAck> ParseCommitAck(std::string_view payload, const std::string& topic_sensor, std::string* error);

}  // namespace lw::gateway
