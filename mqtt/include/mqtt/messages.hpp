#pragma once
/// The JSON messages of docs/mqtt.md, one encoder and one decoder each: reading, commit ack,
/// gateway status, gateway stats, device registry and wear. Encoders write exactly the bytes the
/// gateway and the server have always sent (keys in sorted order, text that is not UTF-8 replaced
/// by U+FFFD, never thrown on); decoders check the fields docs/mqtt.md requires and ignore the ones
/// they do not know. Times are ISO-8601 UTC strings as on the wire. Pure functions, no I/O.
#include <cstddef>
#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace lw::mqtt {

/// Unix milliseconds as ISO-8601 UTC with second precision: "2026-03-01T12:00:07Z".
std::string IsoUtc(int64_t unix_ms);

/// 64-bit radio address as 16 upper-case hex digits (the `address` field and `{address}` level).
std::string AddressHex(uint64_t address);

/// Names of the set record flag bits ("heartbeat", "loop_healed", ...), lowest bit first; a bit
/// without a name is "bitN".
std::vector<std::string> FlagNames(uint16_t flags);

// ---- reading: `sensors/{sensor}/reading`, gateway -> server ----

/// One sensor record. `flag_names` is not a member: EncodeReading derives it from `flags`.
struct ReadingMessage {
  // Required.
  std::string sensor;
  uint32_t seq = 0;
  std::string time;  ///< when the sample was taken
  double thickness_mm = 0;
  int64_t loops_intact = 0;
  uint16_t flags = 0;
  int64_t battery_mv = 0;
  // Optional: the gateway sends them all.
  std::optional<int64_t> temperature_c;
  std::optional<int64_t> ladder_loops;
  std::optional<std::string> loop_bitmap;  ///< lower-case hex, loop 0 in the first byte's top bit
  std::optional<int64_t> dropped_total;
  std::optional<std::string> address;  ///< the radio's, AddressHex
  std::optional<std::string> gateway;
  std::optional<std::string> received;  ///< when the gateway received it

  bool operator==(const ReadingMessage&) const = default;
};

std::string EncodeReading(const ReadingMessage& reading);

/// Limits on a reading message, checked before it is parsed into a tree.
inline constexpr size_t kMaxReadingBytes = 64 * 1024;
inline constexpr size_t kMaxReadingDepth = 8;

/// What identifies a reading message, read even from one DecodeReading refuses, so that a
/// quarantined message can still be acknowledged (docs/server.md, *Bad input*).
struct ReadingIdentity {
  bool object = false;          ///< the payload is a JSON object within the limits
  std::string sensor;           ///< "sensor" as a string or a whole number; empty otherwise
  std::optional<uint32_t> seq;  ///< "seq" when it is a whole number in [0, 2^32-1]
};

/// The reading decoder (the server ingests through it). Nullopt with `*error` naming what is
/// wrong, checked in this order: size (kMaxReadingBytes) and nesting (kMaxReadingDepth) before
/// parsing; JSON (a number that overflows a double is named by its field: `"flags" '1e999' does
/// not fit a double (number overflow)`); an object; then the required fields: `sensor` (a string,
/// or a whole number naming the same sensor), `seq` in [0, 2^32-1], `time` a string (not parsed
/// here), `thickness_mm` a number, `loops_intact` in [0, 4096], `flags` in [0, 65535],
/// `battery_mv` in [0, 10000]. Whole-number fields also accept a float with no fraction (`5.0`).
/// Optional fields of another type than docs/mqtt.md's are left absent, as unknown fields are
/// ignored: they never cost the reading. `identity`, when given, is filled whatever the outcome.
std::optional<ReadingMessage> DecodeReading(std::string_view payload, std::string* error, ReadingIdentity* identity = nullptr);

// ---- several records of one sensor in one reading message (docs/mqtt.md, *Batches*) ----

/// Records in one batch at most: what the server announces in its commit acks (`"batch"`) and
/// accepts. A batch also keeps within kMaxReadingBytes and kMaxReadingDepth.
inline constexpr size_t kMaxReadingBatch = 64;

/// `{"records": [r1, r2, ...], "sensor": S}` where each `records[i]` is the text of a one-record
/// reading message of `sensor` (EncodeReading's, as the gateway spools them), copied as it is, in
/// the order given (seq order). Empty `records`: an empty batch (which decoders refuse).
std::string EncodeReadingBatch(const std::string& sensor, const std::vector<std::string_view>& records);

/// The records of a batch as one-record messages, for DecodeReading one by one, so that each
/// record goes through the same checks and is stored, a duplicate or refused on its own: each
/// element of "records", with the batch's "sensor" added when it names none (an element naming
/// another sensor keeps it: the topic check refuses that record). A payload that is not the batch
/// form (no "records" key in a JSON object within the limits, or not JSON at all) leaves
/// `*records` empty and returns true: it is a one-record message, DecodeReading's to judge, and is
/// not parsed here. False with `*error` when the batch itself is malformed: "sensor" missing or not
/// a string or whole number, "seq" beside "records", "records" not an array, empty, or longer
/// than kMaxReadingBatch.
bool SplitReadingMessage(std::string_view payload, std::vector<std::string>* records, std::string* error);

/// One record of a batch: its text, as SplitReadingMessage gives it, and what DecodeReading says
/// of that text (`reading`, or `error`; `identity` either way).
struct BatchRecord {
  std::string text;
  std::optional<ReadingMessage> reading;
  std::string error;
  ReadingIdentity identity;
};

/// SplitReadingMessage with every record also decoded, as DecodeReading(text, &error, &identity)
/// would, from the batch's one parse (the server's ingest: a record's text is not parsed again).
bool SplitAndDecodeReadingMessage(std::string_view payload, std::vector<BatchRecord>* records, std::string* error);

/// Parses `text`; false with *error set when it is not JSON ("malformed JSON", or "malformed JSON:
/// text that is not UTF-8 at byte N"). A number that
/// overflows a double (`1e999`) is named by its field: `"flags" '1e999' does not fit a double
/// (number overflow)`. No size or nesting limit: see JsonNestingDepth.
bool ParseJsonNamingField(std::string_view text, nlohmann::json* out, std::string* error);

/// Deepest nesting of [ and { in a JSON text (outside strings); no parsing, no recursion.
size_t JsonNestingDepth(std::string_view text);

// ---- commit ack: `sensors/{sensor}/committed`, server -> gateway ----

struct CommitAck {
  std::string sensor;
  std::vector<uint32_t> seqs;
  std::string time;  ///< when the server sent it (decoded: empty when absent)
  /// The server takes reading messages of up to this many records (`"batch"`; 0: absent, the
  /// one-record form only). Encoded only when not 0: an ack without it is byte for byte as before.
  uint32_t batch = 0;

  bool operator==(const CommitAck&) const = default;
};

/// Limits on a commit ack, checked before it is parsed into a tree: the server sends at most one
/// transaction's readings (`--batch-max`, default 1000) in one ack, two levels deep.
inline constexpr size_t kMaxCommitAckBytes = 64 * 1024;
inline constexpr size_t kMaxCommitAckDepth = 8;
inline constexpr size_t kMaxCommitAckSeqs = 10000;

/// `{"batch": N (when not 0), "sensor": S, "seqs": [...], "time": ISO}`.
std::string EncodeCommitAck(const CommitAck& ack);

/// The ack as messages the gateway accepts (at most kMaxCommitAckSeqs seqs and kMaxCommitAckBytes
/// each): one EncodeCommitAck per slice of `ack.seqs`, in order. Empty when the sensor name alone
/// makes a message too long (a topic level no gateway publishes: nothing it spooled to ack).
std::vector<std::string> EncodeCommitAcks(const CommitAck& ack);

/// Parses a commit ack received on `.../sensors/{sensor}/committed`. `topic_sensor` is the
/// {sensor} level of the topic; a payload naming another sensor is refused, one naming none is
/// the topic's. Returns nullopt and sets `*error` when the message is malformed, over
/// kMaxCommitAckBytes, nested deeper than kMaxCommitAckDepth or holds more than kMaxCommitAckSeqs
/// seqs.
std::optional<CommitAck> DecodeCommitAck(std::string_view payload, const std::string& topic_sensor, std::string* error);

// ---- gateway status: `gateway/status` (retained; also the last will) ----

struct StatusMessage {
  bool online = false;
  std::string gateway;
  std::string time;

  bool operator==(const StatusMessage&) const = default;
};

/// `{"state": "online"|"offline", "gateway": ID, "time": ISO}`.
std::string EncodeStatus(const StatusMessage& status);
std::optional<StatusMessage> DecodeStatus(std::string_view payload, std::string* error);

// ---- gateway stats: `gateway/stats` (fields: docs/gateway.md) ----

struct StatsMessage {
  std::string gateway;
  std::string time;
  std::map<std::string, uint64_t> counters;  ///< frames_ok, spool_depth, ... (every whole-number field)
  int64_t latency_last_ms = -1;              ///< `publish_latency_ms`: -1 before the first commit ack
  int64_t latency_max_ms = -1;
  int64_t latency_mean_ms = -1;

  bool operator==(const StatsMessage&) const = default;
};

std::string EncodeStats(const StatsMessage& stats);
std::optional<StatsMessage> DecodeStats(std::string_view payload, std::string* error);

// ---- device registry: `gateway/devices/{address}` (retained) ----

struct DeviceMessage {
  std::string gateway;
  std::string time;
  std::string address;
  std::string first_seen;
  std::vector<std::string> sensors;
  std::optional<std::string> node_identifier;
  std::optional<int64_t> device_type;

  bool operator==(const DeviceMessage&) const = default;
};

/// `{"gateway", "time", "address", "first_seen", "sensors": [ids], "node_identifier"?, "device_type"?}`.
std::string EncodeDevice(const DeviceMessage& device);
std::optional<DeviceMessage> DecodeDevice(std::string_view payload, std::string* error);

// ---- wear: `wear` (retained), server ----

/// The wear message is the server's wear result without faces (docs/wear.md, *Global wear*),
/// built by the server; this is its encoding (as the server has always sent it).
std::string EncodeWear(const nlohmann::ordered_json& summary);

/// The fields every wear message carries, as consumers read them; `summary` is the whole message.
struct WearMessage {
  std::string crusher_id;
  std::string time;  ///< the latest reading used
  std::string map_sha256;
  std::optional<double> min_thickness_mm;  ///< null when the sensors cannot support it
  struct Row {
    std::string row;
    std::optional<double> min_thickness_mm;
    bool operator==(const Row&) const = default;
  };
  std::vector<Row> rows;
  struct Used {
    std::string sensor;
    int64_t seq = 0;
    std::string time;
    double thickness_mm = 0;
    bool operator==(const Used&) const = default;
  };
  std::vector<Used> readings_used;
  nlohmann::ordered_json summary;
};

std::optional<WearMessage> DecodeWear(std::string_view payload, std::string* error);

}  // namespace lw::mqtt
