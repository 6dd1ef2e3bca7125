#include <random>
#include <vector>

#include "protocol/frame_decoder.hpp"
#include "unit/protocol/frame_helpers.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw::protocol;
using lw::protocol::test::Decoded;
using lw::protocol::test::Encode;
using lw::protocol::test::FeedAll;
using lw::protocol::test::Hex;

namespace {
std::vector<uint8_t> Concat(std::initializer_list<std::vector<uint8_t>> parts) {
  std::vector<uint8_t> out;
  for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}
const std::vector<uint8_t> kDigiTx = Hex("7E 00 16 10 01 00 13 A2 00 40 0A 01 27 FF FE 00 00 54 78 44 61 74 61 30 41 13");
const std::vector<uint8_t> kDigiRx = Hex("7E 00 12 90 00 13 A2 00 40 52 2B AA 7D 84 01 52 78 44 61 74 61 0D");
const std::vector<uint8_t> kDigiModem = Hex("7E 00 02 8A 06 6F");
}  // namespace

TEST_GROUP(FrameDecoder) {};

TEST(FrameDecoder, DecodesDigiExamplesInMode1) {
  FrameDecoder dec(ApiMode::kUnescaped);
  const Decoded d = FeedAll(dec, Concat({kDigiTx, kDigiRx, kDigiModem}));
  LONGS_EQUAL(3, d.frames.size());
  LONGS_EQUAL(0, d.errors.size());
  LONGS_EQUAL(0x10, d.frames[0][0]);
  LONGS_EQUAL(0x16, d.frames[0].size());
  LONGS_EQUAL(0x90, d.frames[1][0]);
  LONGS_EQUAL(0x8A, d.frames[2][0]);
  LONGS_EQUAL(3, dec.counters().frames_ok);
}

TEST(FrameDecoder, DecodesEscapedExampleInMode2) {
  FrameDecoder dec(ApiMode::kEscaped);
  const Decoded d = FeedAll(dec, Hex("7E 00 02 23 7D 31 CB"));
  LONGS_EQUAL(1, d.frames.size());
  CHECK(d.frames[0] == Hex("23 11"));
  LONGS_EQUAL(1, dec.counters().unknown_types);  // 0x23 is not a type linerwatch uses
}

TEST(FrameDecoder, RoundTripsEveryByteValueInBothModes) {
  for (ApiMode mode : {ApiMode::kUnescaped, ApiMode::kEscaped}) {
    for (int first = 0; first < 256; ++first) {
      std::vector<uint8_t> data = {0x90};
      for (int i = 0; i < 20; ++i) data.push_back(static_cast<uint8_t>(first + i * 13));
      FrameDecoder dec(mode);
      const Decoded d = FeedAll(dec, Encode(mode, data));
      LONGS_EQUAL(1, d.frames.size());
      CHECK(d.frames[0] == data);
    }
  }
}

TEST(FrameDecoder, RoundTripsEveryLengthUpToMaximum) {
  for (ApiMode mode : {ApiMode::kUnescaped, ApiMode::kEscaped}) {
    FrameDecoder dec(mode);
    std::vector<uint8_t> stream;
    std::vector<std::vector<uint8_t>> sent;
    for (size_t len = 1; len <= kMaxFrameData; ++len) {
      std::vector<uint8_t> data(len);
      data[0] = 0x90;
      for (size_t i = 1; i < len; ++i) data[i] = static_cast<uint8_t>(len * 31 + i);
      sent.push_back(data);
      const auto wire = Encode(mode, data);
      stream.insert(stream.end(), wire.begin(), wire.end());
    }
    const Decoded d = FeedAll(dec, stream);
    CHECK(d.frames == sent);
  }
}

TEST(FrameDecoder, ResynchronisesAfterGarbage) {
  FrameDecoder dec(ApiMode::kUnescaped);
  const Decoded d = FeedAll(dec, Concat({Hex("00 11 22 FF"), kDigiModem, Hex("55 AA"), kDigiModem}));
  LONGS_EQUAL(2, d.frames.size());
  LONGS_EQUAL(6, dec.counters().bytes_discarded);
}

TEST(FrameDecoder, BadChecksumIsCountedAndNextFrameDecodes) {
  auto bad = kDigiModem;
  bad.back() = 0x70;
  for (ApiMode mode : {ApiMode::kUnescaped, ApiMode::kEscaped}) {
    FrameDecoder dec(mode);
    const Decoded d = FeedAll(dec, Concat({bad, kDigiModem}));
    LONGS_EQUAL(1, d.frames.size());
    LONGS_EQUAL(1, dec.counters().checksum_errors);
    CHECK(d.errors[0] == DecodeEvent::kChecksumError);
  }
}

TEST(FrameDecoder, TruncatedFrameDoesNotSwallowTheNextInMode1) {
  // First frame cut after 5 bytes: the decoder must still find the next frame.
  std::vector<uint8_t> cut(kDigiTx.begin(), kDigiTx.begin() + 9);
  FrameDecoder dec(ApiMode::kUnescaped);
  const Decoded d = FeedAll(dec, Concat({cut, kDigiRx, kDigiModem}));
  CHECK(d.frames.size() >= 1);
  CHECK(d.frames.back() == Hex("8A 06"));
  CHECK(dec.counters().checksum_errors + dec.counters().truncated_frames >= 1);
}

TEST(FrameDecoder, TruncatedFrameIsCountedInMode2) {
  const auto full = Encode(ApiMode::kEscaped, Hex("90 00 13 A2 00 40 52 2B AA 7D 84 01 52 78"));
  std::vector<uint8_t> cut(full.begin(), full.begin() + 8);
  FrameDecoder dec(ApiMode::kEscaped);
  const Decoded d = FeedAll(dec, Concat({cut, full}));
  LONGS_EQUAL(1, d.frames.size());
  LONGS_EQUAL(1, dec.counters().truncated_frames);
}

TEST(FrameDecoder, BadEscapeIsCounted) {
  FrameDecoder dec(ApiMode::kEscaped);
  const Decoded d = FeedAll(dec, Concat({Hex("7E 00 02 8A 7D"), Encode(ApiMode::kEscaped, Hex("8A 06"))}));
  LONGS_EQUAL(1, d.frames.size());
  LONGS_EQUAL(1, dec.counters().escape_errors);
  CHECK(d.errors[0] == DecodeEvent::kEscapeError);
}

TEST(FrameDecoder, LengthBeyondBufferAndZeroLengthAreRejected) {
  FrameDecoder dec(ApiMode::kUnescaped);
  const Decoded d = FeedAll(dec, Concat({Hex("7E 7F FF 00 01 02"), Hex("7E 00 00 FF"), kDigiModem}));
  LONGS_EQUAL(1, d.frames.size());
  LONGS_EQUAL(2, dec.counters().length_errors);
}

TEST(FrameDecoder, UnknownTypeIsDeliveredAndCounted) {
  FrameDecoder dec(ApiMode::kUnescaped);
  const Decoded d = FeedAll(dec, Encode(ApiMode::kUnescaped, Hex("88 01 4E 4A 00")));
  LONGS_EQUAL(1, d.frames.size());
  LONGS_EQUAL(1, dec.counters().unknown_types);
}

TEST(FrameDecoder, SurvivesRandomNoiseAndStillDecodesFramesAfterIt) {
  std::mt19937 rng(1234);
  for (ApiMode mode : {ApiMode::kUnescaped, ApiMode::kEscaped}) {
    FrameDecoder dec(mode);
    size_t good = 0;
    for (int round = 0; round < 200; ++round) {
      std::vector<uint8_t> noise(rng() % 40);
      for (auto& b : noise) b = static_cast<uint8_t>(rng());
      FeedAll(dec, noise);
      // A clean frame after a full idle gap: preceded by enough bytes to flush any partial frame.
      std::vector<uint8_t> data = {0x8A, static_cast<uint8_t>(round)};
      Decoded d = FeedAll(dec, Encode(mode, data));
      if (!d.frames.empty() && d.frames.back() == data) ++good;
    }
    // Noise may start a frame whose declared length swallows the clean one (mode 1 has no
    // in-band resync marker), but the great majority must decode.
    CHECK(good > 150);
  }
}
