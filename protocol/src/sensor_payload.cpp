#include "protocol/sensor_payload.hpp"

#include <cstring>

namespace lw::protocol {
namespace {

void Put16(uint8_t* p, uint16_t v) {
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
}
void Put32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}
uint16_t Get16(const uint8_t* p) {
  return static_cast<uint16_t>(p[0] | (p[1] << 8));
}
uint32_t Get32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) | (static_cast<uint32_t>(p[2]) << 16) |
         (static_cast<uint32_t>(p[3]) << 24);
}

// Checks version, type and CRC common to every message; `min_len` excludes the CRC.
PayloadStatus CheckEnvelope(const uint8_t* payload, size_t len, uint8_t type, size_t min_len) {
  if (payload == nullptr || len < 2) return PayloadStatus::kTruncated;
  if (payload[0] != kPayloadVersion) return PayloadStatus::kBadVersion;
  if (payload[1] != type) return PayloadStatus::kBadType;
  if (len < min_len + kCrcSize) return PayloadStatus::kTruncated;
  const uint16_t crc = Get16(payload + len - kCrcSize);
  if (Crc16Ccitt(payload, len - kCrcSize) != crc) return PayloadStatus::kBadCrc;
  return PayloadStatus::kOk;
}

}  // namespace

const char* PayloadStatusName(PayloadStatus status) {
  switch (status) {
    case PayloadStatus::kOk:
      return "ok";
    case PayloadStatus::kBufferTooSmall:
      return "buffer_too_small";
    case PayloadStatus::kTruncated:
      return "truncated";
    case PayloadStatus::kBadVersion:
      return "bad_version";
    case PayloadStatus::kBadType:
      return "bad_type";
    case PayloadStatus::kBadCrc:
      return "bad_crc";
    case PayloadStatus::kBadLadder:
      return "bad_ladder";
    case PayloadStatus::kTooManyRecords:
      return "too_many_records";
    case PayloadStatus::kTrailingBytes:
      return "trailing_bytes";
  }
  return "unknown";
}

uint16_t Crc16Ccitt(const uint8_t* data, size_t len, uint16_t crc) {
  for (size_t i = 0; i < len; ++i) {
    crc = static_cast<uint16_t>(crc ^ (static_cast<uint16_t>(data[i]) << 8));
    for (int b = 0; b < 8; ++b) {
      crc = (crc & 0x8000u) ? static_cast<uint16_t>((crc << 1) ^ 0x1021) : static_cast<uint16_t>(crc << 1);
    }
  }
  return crc;
}

PayloadStatus EncodeReadings(const ReadingsHeader& header, const SensorRecord* records, size_t count, uint8_t* out,
                             size_t out_cap, size_t* written) {
  if (header.ladder_loops == 0 || header.ladder_loops > kMaxLadderLoops) return PayloadStatus::kBadLadder;
  if (count == 0 || records == nullptr || count > MaxRecordsPerPayload(header.ladder_loops) || count > 255) {
    return PayloadStatus::kTooManyRecords;
  }
  const size_t rec_size = RecordWireSize(header.ladder_loops);
  const size_t bitmap_bytes = rec_size - kRecordFixedSize;
  const size_t needed = kReadingsHeaderSize + count * rec_size + kCrcSize;
  if (out == nullptr || needed > out_cap) return PayloadStatus::kBufferTooSmall;
  uint8_t* p = out;
  *p++ = kPayloadVersion;
  *p++ = kMsgReadings;
  Put32(p, header.sensor_id);
  p += 4;
  *p++ = header.ladder_loops;
  *p++ = static_cast<uint8_t>(count);
  Put16(p, header.dropped_total);
  p += 2;
  for (size_t i = 0; i < count; ++i) {
    const SensorRecord& r = records[i];
    Put32(p, r.seq);
    p += 4;
    Put32(p, r.age_s);
    p += 4;
    Put16(p, r.thickness_dmm);
    p += 2;
    *p++ = r.loops_intact;
    Put16(p, r.flags);
    p += 2;
    Put16(p, r.battery_mv);
    p += 2;
    *p++ = static_cast<uint8_t>(r.temperature_c);
    std::memcpy(p, r.loop_bitmap, bitmap_bytes);
    // Bits beyond the ladder are always zero on the wire.
    if (header.ladder_loops % 8) {
      p[bitmap_bytes - 1] = static_cast<uint8_t>(p[bitmap_bytes - 1] & ((1u << (header.ladder_loops % 8)) - 1u));
    }
    p += bitmap_bytes;
  }
  Put16(p, Crc16Ccitt(out, static_cast<size_t>(p - out)));
  if (written) *written = needed;
  return PayloadStatus::kOk;
}

PayloadStatus DecodeReadings(const uint8_t* payload, size_t len, ReadingsHeader* header, SensorRecord* records,
                             size_t records_cap, size_t* count) {
  PayloadStatus s = CheckEnvelope(payload, len, kMsgReadings, kReadingsHeaderSize);
  if (s != PayloadStatus::kOk) return s;
  const uint8_t ladder = payload[6];
  const uint8_t n = payload[7];
  if (ladder == 0 || ladder > kMaxLadderLoops) return PayloadStatus::kBadLadder;
  if (n == 0 || n > MaxRecordsPerPayload(ladder)) return PayloadStatus::kTooManyRecords;
  const size_t rec_size = RecordWireSize(ladder);
  const size_t body = len - kCrcSize - kReadingsHeaderSize;
  if (body < n * rec_size) return PayloadStatus::kTruncated;
  if (body > n * rec_size) return PayloadStatus::kTrailingBytes;
  if (n > records_cap || records == nullptr) return PayloadStatus::kBufferTooSmall;
  header->sensor_id = Get32(payload + 2);
  header->ladder_loops = ladder;
  header->dropped_total = Get16(payload + 8);
  const uint8_t* p = payload + kReadingsHeaderSize;
  for (size_t i = 0; i < n; ++i) {
    SensorRecord& r = records[i];
    r = SensorRecord{};
    r.seq = Get32(p);
    p += 4;
    r.age_s = Get32(p);
    p += 4;
    r.thickness_dmm = Get16(p);
    p += 2;
    r.loops_intact = *p++;
    r.flags = Get16(p);
    p += 2;
    r.battery_mv = Get16(p);
    p += 2;
    r.temperature_c = static_cast<int8_t>(*p++);
    std::memcpy(r.loop_bitmap, p, rec_size - kRecordFixedSize);
    p += rec_size - kRecordFixedSize;
  }
  if (count) *count = n;
  return PayloadStatus::kOk;
}

PayloadStatus EncodeAck(const Ack& ack, uint8_t* out, size_t out_cap, size_t* written) {
  if (ack.count == 0 || ack.count > kMaxAckSeqs) return PayloadStatus::kTooManyRecords;
  const size_t needed = kAckHeaderSize + 4u * ack.count + kCrcSize;
  if (out == nullptr || needed > out_cap) return PayloadStatus::kBufferTooSmall;
  uint8_t* p = out;
  *p++ = kPayloadVersion;
  *p++ = kMsgAck;
  Put32(p, ack.sensor_id);
  p += 4;
  *p++ = ack.count;
  for (size_t i = 0; i < ack.count; ++i) {
    Put32(p, ack.seqs[i]);
    p += 4;
  }
  Put16(p, Crc16Ccitt(out, static_cast<size_t>(p - out)));
  if (written) *written = needed;
  return PayloadStatus::kOk;
}

PayloadStatus DecodeAck(const uint8_t* payload, size_t len, Ack* ack) {
  PayloadStatus s = CheckEnvelope(payload, len, kMsgAck, kAckHeaderSize);
  if (s != PayloadStatus::kOk) return s;
  const uint8_t n = payload[6];
  if (n == 0 || n > kMaxAckSeqs) return PayloadStatus::kTooManyRecords;
  const size_t body = len - kCrcSize - kAckHeaderSize;
  if (body < 4u * n) return PayloadStatus::kTruncated;
  if (body > 4u * n) return PayloadStatus::kTrailingBytes;
  ack->sensor_id = Get32(payload + 2);
  ack->count = n;
  for (size_t i = 0; i < n; ++i) ack->seqs[i] = Get32(payload + kAckHeaderSize + 4 * i);
  return PayloadStatus::kOk;
}

}  // namespace lw::protocol
