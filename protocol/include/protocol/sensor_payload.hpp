#pragma once
/// linerwatch application payload carried in the RF data of XBee 0x10/0x90 frames.
/// Byte-exact layout in docs/protocol.md. All multi-byte fields little-endian. Freestanding.
///
/// Sensor -> gateway, message type 0x01 "readings":
///   u8 version (=1) | u8 type (=0x01) | u32 sensor_id | u8 ladder_loops | u8 record_count |
///   u16 dropped_total | record[record_count] | u16 crc
/// record: u32 seq | u32 age_s | u16 thickness_dmm | u8 loops_intact | u16 flags | u16 battery_mv |
///         i8 temperature_c | u8 loop_bitmap[ceil(ladder_loops/8)]
/// Gateway -> sensor, message type 0x02 "ack":
///   u8 version | u8 type (=0x02) | u32 sensor_id | u8 count | u32 seq[count] | u16 crc
/// crc = CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) over every byte before it.
#include <cstddef>
#include <cstdint>

#include "protocol/xbee_api.hpp"

namespace lw::protocol {

inline constexpr uint8_t kPayloadVersion = 1;
inline constexpr uint8_t kMsgReadings = 0x01;
inline constexpr uint8_t kMsgAck = 0x02;

inline constexpr size_t kMaxLadderLoops = 128;
inline constexpr size_t kMaxBitmapBytes = kMaxLadderLoops / 8;
inline constexpr size_t kReadingsHeaderSize = 10;
inline constexpr size_t kRecordFixedSize = 16;  // without the bitmap
inline constexpr size_t kCrcSize = 2;
inline constexpr size_t kAckHeaderSize = 7;
/// Most seqs one ack can carry inside kMaxRfPayload.
inline constexpr size_t kMaxAckSeqs = (kMaxRfPayload - kAckHeaderSize - kCrcSize) / 4;

/// Fault and state flags of a record (bit values of SensorRecord::flags).
enum RecordFlag : uint16_t {
  kFlagHeartbeat = 1u << 0,      ///< sent because the heartbeat period elapsed, not a change
  kFlagLoopHealed = 1u << 1,     ///< a loop that was open reads closed again (fault, not wear)
  kFlagNonContiguous = 1u << 2,  ///< open loops are not contiguous from the wear face
  kFlagAllOpen = 1u << 3,        ///< every loop open: sensor consumed or cable cut
  kFlagSpiStuck = 1u << 4,       ///< SPI returned all-0x00/0xFF or failed to respond
  kFlagFlicker = 1u << 5,        ///< polls disagreed (loop being cut at the wear face)
  kFlagLowBattery = 1u << 6,
  kFlagBoot = 1u << 7,           ///< first record after a reset
  kFlagWatchdogReset = 1u << 8,  ///< the last reset was a watchdog reset
  kFlagDropped = 1u << 9,        ///< records were dropped before this one (see dropped_total)
};

/// One sample of the wear ladder. thickness_dmm is the lower bound of the thickness interval in
/// 0.1 mm: the true thickness lies in [thickness, thickness + loop pitch).
struct SensorRecord {
  uint32_t seq = 0;            ///< per-sensor sequence number, never reused (persisted in flash)
  uint32_t age_s = 0;          ///< seconds between the sample and the transmission
  uint16_t thickness_dmm = 0;  ///< remaining thickness lower bound, 0.1 mm units
  uint8_t loops_intact = 0;    ///< loops intact counted contiguously from the base
  uint16_t flags = 0;          ///< RecordFlag bits
  uint16_t battery_mv = 0;
  int8_t temperature_c = 0;
  uint8_t loop_bitmap[kMaxBitmapBytes] = {};  ///< bit i (byte i/8, bit i%8) = loop i intact; loop 0 nearest the base
};

/// Header of a readings message.
struct ReadingsHeader {
  uint32_t sensor_id = 0;
  uint8_t ladder_loops = 0;    ///< loops on this sensor's ladder (1..kMaxLadderLoops)
  uint16_t dropped_total = 0;  ///< records this sensor has dropped since manufacture (saturating)
};

struct Ack {
  uint32_t sensor_id = 0;
  uint8_t count = 0;
  uint32_t seqs[kMaxAckSeqs] = {};
};

enum class PayloadStatus : uint8_t {
  kOk = 0,
  kBufferTooSmall,
  kTruncated,
  kBadVersion,
  kBadType,
  kBadCrc,
  kBadLadder,       ///< ladder_loops 0 or above kMaxLadderLoops
  kTooManyRecords,  ///< record_count above capacity or 0
  kTrailingBytes,   ///< bytes between the last record and the CRC
};
const char* PayloadStatusName(PayloadStatus status);

/// CRC-16/CCITT-FALSE.
uint16_t Crc16Ccitt(const uint8_t* data, size_t len, uint16_t crc = 0xFFFF);

/// Size of one record on the wire for a ladder of `ladder_loops` loops.
constexpr size_t RecordWireSize(uint8_t ladder_loops) {
  return kRecordFixedSize + (ladder_loops + 7u) / 8u;
}
/// Smallest RF payload limit (NP) linerwatch supports: one record of the largest ladder (128
/// loops: 44 bytes). Every message a peer builds fits it; a link reported below it is used as if
/// it carried this much, and the gateway says so (docs/gateway.md, *Coordinator set-up*).
inline constexpr size_t kMinRfPayload = kReadingsHeaderSize + kRecordFixedSize + kMaxBitmapBytes + kCrcSize;
static_assert(kMinRfPayload == 44, "docs/protocol.md gives 44 bytes as the smallest supported NP");
static_assert(kMinRfPayload <= kEncryptedRfPayload - kApsEncryptionOverhead,
              "one record must fit an encrypted (EE=1) unicast with APS security (57 bytes, Digi)");
static_assert(kAckHeaderSize + 4 + kCrcSize <= kMinRfPayload, "an ack of one seq must fit the smallest NP");

/// `rf_limit` clamped to what linerwatch supports: [kMinRfPayload, kMaxRfPayload]; 0 (unknown)
/// gives kMinRfPayload.
constexpr size_t ClampRfPayload(size_t rf_limit) {
  return rf_limit < kMinRfPayload ? kMinRfPayload : (rf_limit > kMaxRfPayload ? kMaxRfPayload : rf_limit);
}
/// How many records fit in one RF payload of at most `rf_limit` bytes (clamped by
/// ClampRfPayload): at least 1, since every ladder's record fits kMinRfPayload.
constexpr size_t MaxRecordsPerPayload(uint8_t ladder_loops, size_t rf_limit = kMaxRfPayload) {
  return (ClampRfPayload(rf_limit) - kReadingsHeaderSize - kCrcSize) / RecordWireSize(ladder_loops);
}
static_assert(MaxRecordsPerPayload(kMaxLadderLoops, kMinRfPayload) == 1, "one record always fits the smallest NP");
/// How many seqs one ack of at most `rf_limit` bytes carries (clamped by ClampRfPayload).
constexpr size_t MaxAckSeqs(size_t rf_limit) {
  return (ClampRfPayload(rf_limit) - kAckHeaderSize - kCrcSize) / 4;
}
static_assert(MaxAckSeqs(kMaxRfPayload) == kMaxAckSeqs, "Ack::seqs holds a full-size ack");

/// Encodes a readings message with `count` records. Returns kTooManyRecords when they do not fit
/// in kMaxRfPayload. `*written` receives the payload length.
PayloadStatus EncodeReadings(const ReadingsHeader& header, const SensorRecord* records, size_t count, uint8_t* out,
                             size_t out_cap, size_t* written);

/// Decodes a readings message into `records` (capacity `records_cap`); `*count` receives how many.
PayloadStatus DecodeReadings(const uint8_t* payload, size_t len, ReadingsHeader* header, SensorRecord* records,
                             size_t records_cap, size_t* count);

PayloadStatus EncodeAck(const Ack& ack, uint8_t* out, size_t out_cap, size_t* written);
PayloadStatus DecodeAck(const uint8_t* payload, size_t len, Ack* ack);

/// Message type of a payload (second byte) or 0 when too short.
inline uint8_t PayloadType(const uint8_t* payload, size_t len) {
  return len >= 2 ? payload[1] : 0;
}

}  // namespace lw::protocol
