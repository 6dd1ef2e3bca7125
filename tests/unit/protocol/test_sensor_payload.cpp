#include <cstring>
#include <vector>

#include "protocol/sensor_payload.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw::protocol;

namespace {
SensorRecord MakeRecord(uint32_t seq, uint8_t ladder, uint8_t intact) {
  SensorRecord r;
  r.seq = seq;
  r.age_s = seq * 10;
  r.thickness_dmm = static_cast<uint16_t>(intact * 10);
  r.loops_intact = intact;
  r.flags = kFlagHeartbeat | kFlagFlicker;
  r.battery_mv = 3550;
  r.temperature_c = -12;
  for (uint8_t i = 0; i < intact && i < ladder; ++i)
    r.loop_bitmap[i / 8] = static_cast<uint8_t>(r.loop_bitmap[i / 8] | (1u << (i % 8)));
  return r;
}
}  // namespace

TEST_GROUP(SensorPayload){};

TEST(SensorPayload, CrcMatchesCcittFalseCheckValue) {
  const char* check = "123456789";
  LONGS_EQUAL(0x29B1, Crc16Ccitt(reinterpret_cast<const uint8_t*>(check), 9));
}

TEST(SensorPayload, ReadingsRoundTripForEveryCountAndSeveralLadders) {
  for (uint8_t ladder : {uint8_t{1}, uint8_t{8}, uint8_t{13}, uint8_t{64}, uint8_t{100}, uint8_t{128}}) {
    const size_t max = MaxRecordsPerPayload(ladder);
    CHECK(max >= 2);
    for (size_t count = 1; count <= max; ++count) {
      std::vector<SensorRecord> recs;
      for (size_t i = 0; i < count; ++i)
        recs.push_back(MakeRecord(static_cast<uint32_t>(1000 + i), ladder, static_cast<uint8_t>(ladder - i)));
      ReadingsHeader h{4000000001u, ladder, 7};
      uint8_t buf[kMaxRfPayload];
      size_t n = 0;
      CHECK(EncodeReadings(h, recs.data(), count, buf, sizeof buf, &n) == PayloadStatus::kOk);
      CHECK(n <= kMaxRfPayload);
      ReadingsHeader back_h;
      SensorRecord back[8];
      size_t back_n = 0;
      CHECK(DecodeReadings(buf, n, &back_h, back, 8, &back_n) == PayloadStatus::kOk);
      LONGS_EQUAL(count, back_n);
      CHECK(back_h.sensor_id == 4000000001u);
      LONGS_EQUAL(ladder, back_h.ladder_loops);
      LONGS_EQUAL(7, back_h.dropped_total);
      for (size_t i = 0; i < count; ++i) {
        LONGS_EQUAL(recs[i].seq, back[i].seq);
        LONGS_EQUAL(recs[i].age_s, back[i].age_s);
        LONGS_EQUAL(recs[i].thickness_dmm, back[i].thickness_dmm);
        LONGS_EQUAL(recs[i].loops_intact, back[i].loops_intact);
        LONGS_EQUAL(recs[i].flags, back[i].flags);
        LONGS_EQUAL(recs[i].battery_mv, back[i].battery_mv);
        LONGS_EQUAL(recs[i].temperature_c, back[i].temperature_c);
        MEMCMP_EQUAL(recs[i].loop_bitmap, back[i].loop_bitmap, (ladder + 7) / 8);
      }
    }
  }
}

TEST(SensorPayload, TooManyRecordsIsRefused) {
  std::vector<SensorRecord> recs(6);
  ReadingsHeader h{1, 100, 0};
  uint8_t buf[256];
  size_t n = 0;
  CHECK(EncodeReadings(h, recs.data(), MaxRecordsPerPayload(100) + 1, buf, sizeof buf, &n) == PayloadStatus::kTooManyRecords);
  CHECK(EncodeReadings(h, recs.data(), 0, buf, sizeof buf, &n) == PayloadStatus::kTooManyRecords);
  h.ladder_loops = 0;
  CHECK(EncodeReadings(h, recs.data(), 1, buf, sizeof buf, &n) == PayloadStatus::kBadLadder);
  h.ladder_loops = 129;
  CHECK(EncodeReadings(h, recs.data(), 1, buf, sizeof buf, &n) == PayloadStatus::kBadLadder);
  h.ladder_loops = 100;
  CHECK(EncodeReadings(h, recs.data(), 1, buf, 20, &n) == PayloadStatus::kBufferTooSmall);
}

TEST(SensorPayload, EveryMalformedReadingsPayloadIsRejected) {
  SensorRecord r = MakeRecord(5, 100, 80);
  ReadingsHeader h{1001, 100, 0};
  uint8_t buf[kMaxRfPayload];
  size_t n = 0;
  CHECK(EncodeReadings(h, &r, 1, buf, sizeof buf, &n) == PayloadStatus::kOk);
  ReadingsHeader hh;
  SensorRecord out[4];
  size_t cnt = 0;
  for (size_t len = 0; len < n; ++len) {
    CHECK(DecodeReadings(buf, len, &hh, out, 4, &cnt) != PayloadStatus::kOk);
  }
  // Any single flipped bit is caught by the CRC (or the version/type check).
  for (size_t i = 0; i < n; ++i) {
    uint8_t copy[kMaxRfPayload];
    std::memcpy(copy, buf, n);
    copy[i] ^= 0x10;
    CHECK(DecodeReadings(copy, n, &hh, out, 4, &cnt) != PayloadStatus::kOk);
  }
  uint8_t copy[kMaxRfPayload];
  std::memcpy(copy, buf, n);
  copy[0] = 2;
  CHECK(DecodeReadings(copy, n, &hh, out, 4, &cnt) == PayloadStatus::kBadVersion);
  std::memcpy(copy, buf, n);
  copy[1] = kMsgAck;
  CHECK(DecodeReadings(copy, n, &hh, out, 4, &cnt) == PayloadStatus::kBadType);
  CHECK(DecodeReadings(buf, n, &hh, out, 0, &cnt) == PayloadStatus::kBufferTooSmall);
}

TEST(SensorPayload, AckRoundTripAndErrors) {
  Ack ack;
  ack.sensor_id = 1001;
  ack.count = static_cast<uint8_t>(kMaxAckSeqs);
  for (size_t i = 0; i < kMaxAckSeqs; ++i) ack.seqs[i] = static_cast<uint32_t>(0xFFFFFF00u + i);
  uint8_t buf[kMaxRfPayload];
  size_t n = 0;
  CHECK(EncodeAck(ack, buf, sizeof buf, &n) == PayloadStatus::kOk);
  CHECK(n <= kMaxRfPayload);
  LONGS_EQUAL(kMsgAck, PayloadType(buf, n));
  Ack back;
  CHECK(DecodeAck(buf, n, &back) == PayloadStatus::kOk);
  LONGS_EQUAL(1001, back.sensor_id);
  LONGS_EQUAL(kMaxAckSeqs, back.count);
  for (size_t i = 0; i < kMaxAckSeqs; ++i) CHECK(back.seqs[i] == ack.seqs[i]);
  buf[5] ^= 1;
  CHECK(DecodeAck(buf, n, &back) == PayloadStatus::kBadCrc);
  ack.count = 0;
  CHECK(EncodeAck(ack, buf, sizeof buf, &n) == PayloadStatus::kTooManyRecords);
  STRCMP_EQUAL("bad_crc", PayloadStatusName(PayloadStatus::kBadCrc));
}

// Frames sized to a link: records and ack seqs per frame follow the payload limit, one record of
// any ladder fits the smallest supported limit, and an encoder given the limit as its buffer
// never writes more.
TEST(SensorPayload, RecordsAndAcksPerFrameFollowThePayloadLimit) {
  LONGS_EQUAL(44, kMinRfPayload);
  LONGS_EQUAL(2, MaxRecordsPerPayload(100, 84));
  LONGS_EQUAL(1, MaxRecordsPerPayload(100, 66));
  LONGS_EQUAL(1, MaxRecordsPerPayload(128, 44));
  LONGS_EQUAL(1, MaxRecordsPerPayload(128, 10));  // below the minimum: used as the minimum
  LONGS_EQUAL(3, MaxRecordsPerPayload(16, 66));
  LONGS_EQUAL(18, MaxAckSeqs(84));
  LONGS_EQUAL(14, MaxAckSeqs(66));
  LONGS_EQUAL(10, MaxAckSeqs(49));
  LONGS_EQUAL(8, MaxAckSeqs(0));
  for (size_t limit = kMinRfPayload; limit <= kMaxRfPayload; ++limit) {
    for (int ladder = 1; ladder <= 128; ++ladder) {
      const size_t n = MaxRecordsPerPayload(static_cast<uint8_t>(ladder), limit);
      std::vector<SensorRecord> recs(n);
      ReadingsHeader h;
      h.ladder_loops = static_cast<uint8_t>(ladder);
      uint8_t buf[kMaxRfPayload];
      size_t written = 0;
      CHECK(EncodeReadings(h, recs.data(), n, buf, limit, &written) == PayloadStatus::kOk);
      CHECK(written <= limit);
      CHECK(written + RecordWireSize(static_cast<uint8_t>(ladder)) > limit);  // as full as it gets
    }
    Ack ack;
    ack.count = static_cast<uint8_t>(MaxAckSeqs(limit));
    uint8_t buf[kMaxRfPayload];
    size_t written = 0;
    CHECK(EncodeAck(ack, buf, limit, &written) == PayloadStatus::kOk);
    CHECK(written <= limit && written + 4 > limit);
  }
}
