// Test vectors from other XBee API implementations' test suites, fed through our public API
// (FrameDecoder in both API modes, EncodeFrame, Checksum, the Build*/Parse*/Encode* functions) and
// checked against what the peer's own test expects. Vectors are facts (bytes and expected results);
// no peer code is used. Each vector names its source as repository:path (test name), at these
// commits:
//   nioinnovation/python-xbee     abfe8475cbf5cd452ade1984a6f113a84e0adabc
//   jankolkmeier/xbee-api         c79490b0e624d35137539ceef759a053b80eae0e
//   digidotcom/xbee-java          eff87c88951db51d78c2df21861e925724546e8c
//   digidotcom/xbee_ansic_library 66603bd42157a9de73899c00d30bfdd5e968d661
//   jefffhaynes/XBee              38da063185c289f6bf58951b3f0132671909f6fb
//   rockwood/exbee                99e7b17a0eb37495d75e9d7f8ba56f3f3acf87e8
//   northernpaws/xbee3-rs         02fb1961f2d76cf2a7ee03dd31fe61bc332d0e73
// Where we differ from a peer on purpose, the test asserts our documented behaviour and says why.
#include <cstring>
#include <string>
#include <vector>

#include "protocol/frame_decoder.hpp"
#include "protocol/xbee_api.hpp"
#include "unit/protocol/frame_helpers.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw::protocol;
using lw::protocol::test::Decoded;
using lw::protocol::test::Encode;
using lw::protocol::test::FeedAll;
using lw::protocol::test::Hex;

namespace {

constexpr DecodeEvent kChecksum = DecodeEvent::kChecksumError;
constexpr DecodeEvent kEsc = DecodeEvent::kEscapeError;
constexpr DecodeEvent kLength = DecodeEvent::kLengthError;
constexpr DecodeEvent kTrunc = DecodeEvent::kTruncated;

/// A byte stream, the frames (frame data, hex) a peer's test expects from it, in order, and the
/// error events our decoder reports on the way.
struct StreamCase {
  const char* source;
  ApiMode mode;
  std::string wire;
  std::vector<std::string> frames;
  std::vector<DecodeEvent> errors;
};

std::vector<std::vector<uint8_t>> Frames(const StreamCase& c) {
  std::vector<std::vector<uint8_t>> out;
  for (const auto& f : c.frames) out.push_back(Hex(f));
  return out;
}

/// Feeds the case whole, then split in two reads at every position (a frame split across reads,
/// an escape byte at the end of one read), and checks the same frames and errors every time.
void RunStream(const StreamCase& c) {
  const std::vector<uint8_t> wire = Hex(c.wire);
  const auto want = Frames(c);
  for (size_t split = 0; split <= wire.size(); ++split) {
    FrameDecoder dec(c.mode);
    Decoded d;
    auto on_event = [&](DecodeEvent ev) {
      if (ev == DecodeEvent::kFrame) {
        d.frames.emplace_back(dec.frame_data(), dec.frame_data() + dec.frame_length());
      } else {
        d.errors.push_back(ev);
      }
    };
    dec.Feed(wire.data(), split, on_event);
    dec.Feed(wire.data() + split, wire.size() - split, on_event);
    const std::string where = std::string(c.source) + " (split at " + std::to_string(split) + ")";
    CHECK_TEXT(d.frames == want, where.c_str());
    CHECK_TEXT(d.errors == c.errors, where.c_str());
    CHECK_TEXT(dec.counters().frames_ok == want.size(), where.c_str());
  }
}

bool HasSpecialAfterDelimiter(const std::vector<uint8_t>& wire) {
  for (size_t i = 1; i < wire.size(); ++i) {
    const uint8_t b = wire[i];
    if (b == kStartDelimiter || b == kEscape || b == kXon || b == kXoff) return true;
  }
  return false;
}

/// A complete, valid wire frame from a peer: it decodes to its frame data in API mode 1, our
/// EncodeFrame builds the same bytes from that data, and (the four special bytes never appearing
/// after its delimiter) it is also the same frame in API mode 2.
void RunWireFrame(const char* source, const std::string& wire_hex) {
  const std::vector<uint8_t> wire = Hex(wire_hex);
  const std::vector<uint8_t> data(wire.begin() + 3, wire.end() - 1);
  FrameDecoder dec(ApiMode::kUnescaped);
  const Decoded d = FeedAll(dec, wire);
  CHECK_TEXT(d.errors.empty(), source);
  CHECK_TEXT(d.frames.size() == 1 && d.frames[0] == data, source);
  CHECK_TEXT(Encode(ApiMode::kUnescaped, data) == wire, source);
  if (!HasSpecialAfterDelimiter(wire)) {
    FrameDecoder dec2(ApiMode::kEscaped);
    const Decoded d2 = FeedAll(dec2, wire);
    CHECK_TEXT(d2.frames.size() == 1 && d2.frames[0] == data, source);
    CHECK_TEXT(Encode(ApiMode::kEscaped, data) == wire, source);
  }
}

std::vector<uint8_t> Bytes(const char* text) {
  return std::vector<uint8_t>(text, text + std::strlen(text));
}

}  // namespace

TEST_GROUP(PeerVectors){};

// ---------------------------------------------------------------------------------------------
// Checksums.
// ---------------------------------------------------------------------------------------------

TEST(PeerVectors, ChecksumsMatchDigiJavaLibrary) {
  // digidotcom/xbee-java:library/src/test/java/com/digi/xbee/api/packet/XBeeChecksumTest.java
  // (testAddIntOnce, testAddIntTwice, testAddNullArray, testAddArrayOnce, testAddArrayTwice,
  // testReset, testValidateValid).
  const uint8_t two[] = {2};
  const uint8_t two_five[] = {2, 5};
  const uint8_t five[] = {5};
  const uint8_t array[] = {2, 6, 1};
  const uint8_t arrays[] = {2, 6, 1, 5, 3};
  LONGS_EQUAL(253, Checksum(two, sizeof two));
  LONGS_EQUAL(248, Checksum(two_five, sizeof two_five));
  LONGS_EQUAL(255 - 5, Checksum(five, sizeof five));
  LONGS_EQUAL(246, Checksum(array, sizeof array));
  LONGS_EQUAL(238, Checksum(arrays, sizeof arrays));
  LONGS_EQUAL(0xFF, Checksum(nullptr, 0));
  // testValidateValid / testValidateNotValid: data plus its checksum is a valid frame; without it not.
  FrameDecoder dec(ApiMode::kUnescaped);
  const Decoded ok = FeedAll(dec, Hex("7E 00 03 02 06 01 F6"));
  LONGS_EQUAL(1, ok.frames.size());
  const Decoded bad = FeedAll(dec, Hex("7E 00 03 02 06 01 00"));
  LONGS_EQUAL(0, bad.frames.size());
  CHECK(bad.errors == std::vector<DecodeEvent>{kChecksum});
}

TEST(PeerVectors, ChecksumsMatchDigiAnsiCLibrary) {
  // digidotcom/xbee_ansic_library:test/rabbit/unittest_xbee_device.c (checksum_test[], t_xbee_checksum).
  const uint8_t ff[] = {0xFF};
  LONGS_EQUAL(0xFF, Checksum(nullptr, 0));
  const auto t = Bytes("T");
  LONGS_EQUAL(0xFF - 'T', Checksum(t.data(), t.size()));
  LONGS_EQUAL(0, Checksum(ff, 1));
  const auto fox = Bytes("The quick brown fox jumps over the lazy dog.");
  LONGS_EQUAL(248, Checksum(fox.data(), fox.size()));
  const auto box = Bytes("Pack my box with five dozen liquor jugs.");
  LONGS_EQUAL(104, Checksum(box.data(), box.size()));
  // "adding nulls to checksum should be unchanged"
  const uint8_t t_nulls[] = {'T', 0, 0, 0, 0};
  LONGS_EQUAL(0xFF - 'T', Checksum(t_nulls, sizeof t_nulls));
}

// ---------------------------------------------------------------------------------------------
// Complete wire frames: framing, length and checksum (decode and encode, API mode 1; mode 2 too
// when no byte needs escaping).
// ---------------------------------------------------------------------------------------------

TEST(PeerVectors, WireFramesDecodeAndEncodeByteExact) {
  struct Vec {
    const char* source;
    const char* wire;
  };
  const Vec vectors[] = {
      // python-xbee
      {"nioinnovation/python-xbee:xbee/tests/test_frame.py (test_single_byte, both)", "7E 00 01 00 FF"},
      {"nioinnovation/python-xbee:xbee/backend/tests/test_base.py (test_write_again)", "7E 00 03 00 01 02 FC"},
      {"nioinnovation/python-xbee:xbee/thread/tests/test_zigbee.py (test_send, AT MY)", "7E 00 04 08 01 4D 59 50"},
      // xbee-api (node)
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (AT Command Requests)", "7E 00 04 08 52 4E 4A 0D"},
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (AT Command Queue Requests)", "7E 00 05 09 01 42 44 07 68"},
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (AT Remote Command Requests)",
       "7E 00 10 17 01 00 13 A2 00 40 40 11 22 FF FE 02 42 48 01 F5"},
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (Keep Frame ID Zero)", "7E 00 04 08 00 4E 4A 5F"},
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (AT Remote Command Responses)",
       "7E 00 13 97 55 00 13 A2 00 40 52 2B AA 7D 84 53 4C 00 40 52 2B AA F0"},
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (AT Command Responses, BD)", "7E 00 05 88 01 42 44 00 F0"},
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (AT Command Responses, ND no data)", "7E 00 05 88 01 4E 44 00 E4"},
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (Receive Packet with AO=1, 0x91)",
       "7E 00 1E 91 00 13 A2 00 40 C4 01 A9 00 00 E8 E8 00 11 C1 05 01 74 65 73 74 20 6D 65 73 73 61 67 65 9E"},
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (Receive Packet 16-bit IO, 0x83)",
       "7E 00 10 83 12 34 1B 00 01 0E 58 00 18 00 46 01 54 02 0A F5"},
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (Route Record, 0xA1)",
       "7E 00 13 A1 00 13 A2 00 40 68 F6 5B 6D 32 00 03 12 34 56 78 90 AB BF"},
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (ZigBee IO Data Sample Rx, 0x92)",
       "7E 00 14 92 00 13 A2 00 40 52 2B AA 7D 84 01 01 00 1C 02 00 14 02 25 F5"},
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (AP=1 Containing Start Byte, 0x92)",
       "7E 00 14 92 00 13 A2 00 41 5B 7E D6 FF FE C2 01 00 00 0C 03 FF 03 FF F8"},
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (XBee Sensor Read Indicator, 0x94)",
       "7E 00 17 94 00 13 A2 00 40 52 2B AA DD 6C 01 03 00 02 00 CE 00 EA 00 52 01 6A 8B"},
      // xbee-java
      {"digidotcom/xbee-java:.../packet/XBeePacketParserFromInputStreamTest.java (AT command NIAT)",
       "7E 00 06 08 01 4E 49 41 54 CA"},
      {"digidotcom/xbee-java:.../packet/XBeePacketParserFromInputStreamTest.java (testParsePacketApiModeValidFrame)",
       "7E 00 0F 17 01 00 00 00 40 9D 5E 49 D5 FF FE 02 4E 49 F8"},
      {"digidotcom/xbee-java:.../packet/XBeePacketParserFromInputStreamTest.java (testParsePacketGenericFrame)",
       "7E 00 04 FF 62 79 65 C0"},
      // XBee (C#)
      {"jefffhaynes/XBee:XBee.Test/FrameTests.cs (AtCommandFrameTest)", "7E 00 04 08 52 49 53 09"},
      {"jefffhaynes/XBee:XBee.Test/FrameTests.cs (AtCommand_CoordinatorEnable_FrameTest)", "7E 00 04 08 33 43 45 3C"},
      {"jefffhaynes/XBee:XBee.Test/FrameTests.cs (AtCommand_CoordinatorEnableWithParam_FrameTest)", "7E 00 05 08 33 43 45 01 3B"},
      {"jefffhaynes/XBee:XBee.Test/FrameTests.cs (AtCommand_SleepMode_FrameTest)", "7E 00 06 88 01 53 4D 00 00 D6"},
      {"jefffhaynes/XBee:XBee.Test/FrameTests.cs (AtCommand_NonStandardBaudRate_FrameTest)", "7E 00 06 09 01 42 44 75 30 CA"},
      {"jefffhaynes/XBee:XBee.Test/FrameTests.cs (AtCommand_LargeNonStandardBaudRate_FrameTest)",
       "7E 00 08 09 01 42 44 00 2D C6 C0 BC"},
      {"jefffhaynes/XBee:XBee.Test/FrameTests.cs (AtCommand_BaudRateQuery_FrameTest)", "7E 00 04 08 01 42 44 70"},
      // exbee (Elixir)
      {"rockwood/exbee:test/exbee/message_test.exs (parses basic frames; build/1)", "7E 00 03 01 02 03 F9"},
      {"rockwood/exbee:test/exbee/message_test.exs (header comment, IO Data Sample RX)",
       "7E 00 12 92 00 13 A2 00 40 AF DC A7 D0 5C 01 01 00 02 00 00 02 14"},
  };
  for (const Vec& v : vectors) RunWireFrame(v.source, v.wire);
}

// ---------------------------------------------------------------------------------------------
// Streams: escaping, garbage, several frames per read, malformed input, resynchronisation.
// ---------------------------------------------------------------------------------------------

TEST(PeerVectors, StreamsDecodeAsPeersExpect) {
  const std::string modem = "7E 00 02 8A 06 6F";  // appended where marked "+ good frame (ours)"
  const std::string ansic_bar = "7E 00 04 F0 62 61 72 DA";
  const std::string ansic_baz = "7E 00 04 F0 62 61 7A D2";
  const std::string xbee_api_rx = "7E 00 12 90 00 13 A2 00 40 52 2B AA 7D 84 01 52 78 44 61 74 61 0D";
  const std::string xbee_api_rx_data = "90 00 13 A2 00 40 52 2B AA 7D 84 01 52 78 44 61 74 61";
  std::string garbage;
  for (int i = 0; i < 520; ++i) garbage += "00 ";
  const std::vector<StreamCase> cases = {
      // --- python-xbee
      {"nioinnovation/python-xbee:xbee/tests/test_frame.py (test_invalid_checksum)",
       ApiMode::kUnescaped,
       "7E 00 01 00 F6",
       {},
       {kChecksum}},
      {"nioinnovation/python-xbee:xbee/thread/tests/test_base.py (test_read_invalid_followed_by_valid)",
       ApiMode::kUnescaped,
       "7E 00 01 00 FA 7E 00 01 05 FA",
       {"05"},
       {kChecksum}},
      {"nioinnovation/python-xbee:xbee/thread/tests/test_base.py (test_read_escaped)",
       ApiMode::kEscaped,
       "7E 00 04 7D 5E 7D 5D 7D 31 7D 33 E0",
       {"7E 7D 11 13"},
       {}},
      // test_unescape_input: 0x7D 0x23 unescapes to 0x03 (a byte no sender needs to escape; accepted,
      // as by python-xbee and xbee-java). The frame around the pair is ours.
      {"nioinnovation/python-xbee:xbee/tests/test_frame.py (test_unescape_input)",
       ApiMode::kEscaped,
       "7E 00 02 8A 7D 23 72",
       {"8A 03"},
       {}},
      // --- xbee-api (node)
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (Stream Interface: Encode Decode)",
       ApiMode::kUnescaped,
       "7E 00 13 97 55 00 13 A2 00 40 52 2B AA 7D 84 53 4C 00 40 52 2B AA F0 7E 00 07 8B 01 7D 84 00 00 01 71",
       {"97 55 00 13 A2 00 40 52 2B AA 7D 84 53 4C 00 40 52 2B AA", "8B 01 7D 84 00 00 01"},
       {}},
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (Leading Garbage: 520 zero bytes)",
       ApiMode::kUnescaped,
       garbage + xbee_api_rx,
       {xbee_api_rx_data},
       {}},
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (Multiple Frames In One Buffer, AP=1)",
       ApiMode::kUnescaped,
       "7E 00 14 92 00 13 A2 00 40 52 2B AA 7D 84 01 01 00 1C 02 00 14 02 25 F5 "
       "7E 00 14 92 00 13 A2 00 41 55 08 83 FF FE C2 01 00 00 0C 03 FF 03 FF C7",
       {"92 00 13 A2 00 40 52 2B AA 7D 84 01 01 00 1C 02 00 14 02 25",
        "92 00 13 A2 00 41 55 08 83 FF FE C2 01 00 00 0C 03 FF 03 FF"},
       {}},
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (AT Command Responses, ND with data, AP=2)",
       ApiMode::kEscaped,
       "7E 00 12 88 01 4E 44 00 FF FE 00 7D 33 A2 00 40 D8 14 A8 34 64 00 C6",
       {"88 01 4E 44 00 FF FE 00 13 A2 00 40 D8 14 A8 34 64 00"},
       {}},
      // Escaping (AP=2): frame id 0x7D, frame id 0x7E, checksum 0x7E escaped, then three plain frames.
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (Escaping (AP=2))",
       ApiMode::kEscaped,
       "7E 00 07 8B 7D 5D 2A 6A 00 00 00 63 7E 00 07 8B 7D 5E 2A 6A 00 00 00 62 "
       "7E 00 07 8B 62 2A 6A 00 00 00 7D 5E 7E 00 07 8B 64 2A 6A 00 00 00 7C "
       "7E 00 07 8B 65 2A 6A 00 00 00 7B 7E 00 07 8B 66 2A 6A 00 00 00 7A",
       {"8B 7D 2A 6A 00 00 00", "8B 7E 2A 6A 00 00 00", "8B 62 2A 6A 00 00 00", "8B 64 2A 6A 00 00 00", "8B 65 2A 6A 00 00 00",
        "8B 66 2A 6A 00 00 00"},
       {}},
      // --- xbee-java (XBeePacketParserFromInputStreamTest.java): one packet per stream there.
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketFrameTooShortApiMode)",
       ApiMode::kUnescaped,
       "7E 00 06",
       {},
       {}},
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketFrameTooShortApiEscapeMode)",
       ApiMode::kEscaped,
       "7E 7D 33",
       {},
       {}},
      // ShorterThanExpected (API): declared 8, the checksum position holds 0x7E. Mode 1 re-reads from
      // that 0x7E (it may start the next frame), so + good frame (ours): its delimiter is taken as
      // the length byte of that false start, which fails as a length error, and the good frame is
      // then decoded from its own delimiter.
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketFrameShorterThanExpectedApiMode)"
       " + good frame (ours)",
       ApiMode::kUnescaped,
       "7E 00 08 08 01 4E 49 41 54 49 81 7E " + modem,
       {"8A 06"},
       {kChecksum, kLength}},
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketFrameShorterThanExpectedApiEscapeMode)",
       ApiMode::kEscaped,
       "7E 00 0B 88 07 53 48 00 00 7D 33 A2 00 20 25 B4",
       {},
       {kChecksum}},
      // xbee-java: "Special byte not escaped: 0x7E". We name it a truncated frame: in mode 2 an
      // unescaped 0x7E always starts the next frame (docs/protocol.md); + good frame (ours).
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketFrameShorterThanExpectedApiEscapeMode2)"
       " + good frame (ours)",
       ApiMode::kEscaped,
       "7E 00 0B 88 07 53 48 00 00 7D 33 A2 00 20 7E 00 " + modem,
       {"8A 06"},
       {kTrunc, kTrunc}},
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketFrameLongerThanExpectedApiMode)"
       " + good frame (ours)",
       ApiMode::kUnescaped,
       "7E 00 05 08 01 4E 49 41 54 49 81 7E " + modem,
       {"8A 06"},
       {kChecksum, kLength}},
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketFrameLongerThanExpectedApiEscapeMode)"
       " + good frame (ours)",
       ApiMode::kEscaped,
       "7E 00 07 88 07 53 48 00 00 7D 33 A2 00 20 25 B4 " + modem,
       {"8A 06"},
       {kChecksum}},
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketInvalidChecksumApiMode)",
       ApiMode::kUnescaped,
       "7E 00 06 08 01 4E 49 41 54 CB",
       {},
       {kChecksum}},
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketInvalidChecksumApiEscapeMode)",
       ApiMode::kEscaped,
       "7E 00 09 88 07 53 48 00 00 7D 33 A2 00 50",
       {},
       {kChecksum}},
      // An unescaped XOFF (0x13) / XON (0x11) inside a mode-2 frame: Digi's manuals say these bytes
      // "must be escaped" when sending or receiving, so they are never frame data. xbee-java
      // rejects the frame ("Special byte not escaped"); we report an escape error and drop it. (We
      // used to take the byte as data: both frames below have a valid checksum and were delivered.)
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketSpecialByteNotEscapedApiEscapeMode)"
       " + good frame (ours)",
       ApiMode::kEscaped,
       "7E 00 09 88 07 53 48 00 00 13 A2 00 20 " + modem,
       {"8A 06"},
       {kEsc}},
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketApiEscapeModeWithApiFrame2)"
       " + good frame (ours)",
       ApiMode::kEscaped,
       "7E 00 09 88 07 53 48 00 00 11 A2 00 22 " + modem,
       {"8A 06"},
       {kEsc}},
      // The same bytes in API mode 1 are a valid frame (0x11 and 0x13 are ordinary data there).
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketApiEscapeModeWithApiFrame2 bytes,"
       " read in API mode 1)",
       ApiMode::kUnescaped,
       "7E 00 09 88 07 53 48 00 00 11 A2 00 22",
       {"88 07 53 48 00 00 11 A2 00"},
       {}},
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketApiModeWithApiEscapeFrame)",
       ApiMode::kUnescaped,
       "7E 00 09 88 07 53 48 00 00 7D 33 A2 00 20",
       {},
       {kChecksum}},
      // A raw 0x7D escapes the next byte (0xA2 -> 0x82); the frame is then one byte short: incomplete.
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketApiEscapeModeWithApiFrame)",
       ApiMode::kEscaped,
       "7E 00 09 88 07 53 48 00 00 7D A2 00 B6",
       {},
       {}},
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketApiModeNonRecognizeFrameTypePayload)",
       ApiMode::kUnescaped,
       "7E 00 01 13 EC",
       {"13"},
       {}},
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java "
       "(testParsePacketApiEscapeModeNonRecognizeFrameTypePayload)",
       ApiMode::kEscaped,
       "7E 00 01 7D 33 EC",
       {"13"},
       {}},
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketApiEscapeModeValidFrame)",
       ApiMode::kEscaped,
       "7E 00 09 88 07 53 48 00 00 7D 33 A2 00 20",
       {"88 07 53 48 00 00 13 A2 00"},
       {}},
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketApiEscapeModeValidFrameNoEscapes)",
       ApiMode::kEscaped,
       "7E 00 0F 01 FF 00 00 00 40 9D 5E 49 D5 FF FE 02 4E 49 10",
       {"01 FF 00 00 00 40 9D 5E 49 D5 FF FE 02 4E 49"},
       {}},
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketApiEscapeModeLengthEscaped)",
       ApiMode::kEscaped,
       "7E 00 7D 31 88 83 4D 59 00 31 30 2E 31 30 31 2E 32 2E 31 35 37 02",
       {"88 83 4D 59 00 31 30 2E 31 30 31 2E 32 2E 31 35 37"},
       {}},
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketApiEscapeModeChecksumEscaped)",
       ApiMode::kEscaped,
       "7E 00 06 88 55 4D 54 00 03 7D 5E",
       {"88 55 4D 54 00 03"},
       {}},
      // --- xbee_ansic_library (t_load_and_dispatch): junk before a frame; a stray 0x7E before a
      // frame (its delimiter then lands in the length MSB); a stray 0x7E 0x01 (delimiter in the
      // length LSB). Digi's C library re-uses that 0x7E as the start of the frame; so do we: in
      // mode 1 as a length error and re-read, in mode 2 as a truncated frame.
      {"digidotcom/xbee_ansic_library:test/rabbit/unittest_xbee_device.c (junk goes here, skip it)",
       ApiMode::kUnescaped,
       "6A 75 6E 6B 20 67 6F 65 73 20 68 65 72 65 2C 20 73 6B 69 70 20 69 74 " + ansic_bar,
       {"F0 62 61 72"},
       {}},
      {"digidotcom/xbee_ansic_library:test/rabbit/unittest_xbee_device.c (junk, API mode 2)",
       ApiMode::kEscaped,
       "6A 75 6E 6B 20 67 6F 65 73 20 68 65 72 65 2C 20 73 6B 69 70 20 69 74 " + ansic_bar,
       {"F0 62 61 72"},
       {}},
      {"digidotcom/xbee_ansic_library:test/rabbit/unittest_xbee_device.c (extra 0x7E in length MSB)",
       ApiMode::kUnescaped,
       "7E " + ansic_bar,
       {"F0 62 61 72"},
       {kLength}},
      {"digidotcom/xbee_ansic_library:test/rabbit/unittest_xbee_device.c (extra 0x7E, API mode 2)",
       ApiMode::kEscaped,
       "7E " + ansic_bar,
       {"F0 62 61 72"},
       {kTrunc}},
      {"digidotcom/xbee_ansic_library:test/rabbit/unittest_xbee_device.c (0x7E 0x01, 0x7E in length LSB)",
       ApiMode::kUnescaped,
       "7E 01 " + ansic_baz,
       {"F0 62 61 7A"},
       {kLength}},
      {"digidotcom/xbee_ansic_library:test/rabbit/unittest_xbee_device.c (0x7E 0x01, API mode 2)",
       ApiMode::kEscaped,
       "7E 01 " + ansic_baz,
       {"F0 62 61 7A"},
       {kTrunc}},
      // --- exbee (Elixir): test/exbee/message_test.exs
      {"rockwood/exbee:test/exbee/message_test.exs (parses multipe frames in one message)",
       ApiMode::kUnescaped,
       "7E 00 03 01 02 03 F9 01 7E 00 03 01 02 03 F9",
       {"01 02 03", "01 02 03"},
       {}},
      {"rockwood/exbee:test/exbee/message_test.exs (buffers extra end bits)",
       ApiMode::kUnescaped,
       "7E 00 03 01 02 03 F9 7E 00",
       {"01 02 03"},
       {}},
      {"rockwood/exbee:test/exbee/message_test.exs (drops extra start bits)",
       ApiMode::kUnescaped,
       "00 01 7E 00 03 01 02 03 F9",
       {"01 02 03"},
       {}},
      {"rockwood/exbee:test/exbee/message_test.exs (ignores frames with invalid checksums)",
       ApiMode::kUnescaped,
       "7E 00 03 01 02 03 01",
       {},
       {kChecksum}},
  };
  for (const StreamCase& c : cases) RunStream(c);
}

TEST(PeerVectors, LeadingGarbageAndStrayBytesAreCountedAsDiscarded) {
  // jankolkmeier/xbee-api:test/xbee-api_test.js (Leading Garbage): 520 zero bytes before a frame.
  // Mode 2 (ours): the same frame data escaped by our encoder (its 0x7D84 needs escaping).
  const auto rx = Hex("7E 00 12 90 00 13 A2 00 40 52 2B AA 7D 84 01 52 78 44 61 74 61 0D");
  const std::vector<uint8_t> rx_data(rx.begin() + 3, rx.end() - 1);
  for (ApiMode mode : {ApiMode::kUnescaped, ApiMode::kEscaped}) {
    std::vector<uint8_t> stream(520, 0x00);
    const auto wire = mode == ApiMode::kUnescaped ? rx : Encode(mode, rx_data);
    stream.insert(stream.end(), wire.begin(), wire.end());
    FrameDecoder dec(mode);
    const Decoded d = FeedAll(dec, stream);
    LONGS_EQUAL(1, d.frames.size());
    CHECK(dec.counters().bytes_discarded == 520);
  }
  // rockwood/exbee:test/exbee/message_test.exs (drops extra start bits): two stray bytes.
  FrameDecoder dec(ApiMode::kUnescaped);
  FeedAll(dec, Hex("00 01 7E 00 03 01 02 03 F9"));
  CHECK(dec.counters().bytes_discarded == 2);
  CHECK(dec.counters().unknown_types == 1);  // 0x01 is no frame type linerwatch uses
}

// ---------------------------------------------------------------------------------------------
// Escaping on the encode side.
// ---------------------------------------------------------------------------------------------

TEST(PeerVectors, EncodeEscapesAsPeersExpect) {
  // nioinnovation/python-xbee:xbee/backend/tests/test_base.py (test_write_escaped).
  CHECK(Encode(ApiMode::kEscaped, Hex("7E 01 7D 11 13")) == Hex("7E 00 05 7D 5E 01 7D 5D 7D 31 7D 33 DF"));
  // nioinnovation/python-xbee:xbee/tests/test_frame.py (test_escape_method): 0x7E -> 0x7D 0x5E; the
  // frame around it is ours (checksum 0xFF - 0x7E = 0x81).
  CHECK(Encode(ApiMode::kEscaped, Hex("7E")) == Hex("7E 00 01 7D 5E 81"));
  // nioinnovation/python-xbee:xbee/tests/test_frame.py (TestAPIFrameGeneration.test_single_byte).
  CHECK(Encode(ApiMode::kUnescaped, Hex("00")) == Hex("7E 00 01 00 FF"));
  // digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java: the escaped packets it parses
  // must be generated back byte for byte (generateByteArrayEscaped).
  const char* escaped[] = {
      "7E 00 09 88 07 53 48 00 00 7D 33 A2 00 20",                          // ApiEscapeModeValidFrame
      "7E 00 0F 01 FF 00 00 00 40 9D 5E 49 D5 FF FE 02 4E 49 10",           // ValidFrameNoEscapes
      "7E 00 7D 31 88 83 4D 59 00 31 30 2E 31 30 31 2E 32 2E 31 35 37 02",  // LengthEscaped
      "7E 00 06 88 55 4D 54 00 03 7D 5E",                                   // ChecksumEscaped
      "7E 00 01 7D 33 EC",                                                  // NonRecognizeFrameType (escaped)
      "7E 00 07 8B 7D 5D 2A 6A 00 00 00 63",  // jankolkmeier/xbee-api: Escaping (AP=2), frame id 0x7D
      "7E 00 07 8B 7D 5E 2A 6A 00 00 00 62",  // ... frame id 0x7E
      "7E 00 07 8B 62 2A 6A 00 00 00 7D 5E",  // ... checksum 0x7E
      "7E 00 04 7D 5E 7D 5D 7D 31 7D 33 E0",  // python-xbee: thread/tests/test_base.py test_read_escaped
  };
  for (const char* wire : escaped) {
    FrameDecoder dec(ApiMode::kEscaped);
    const Decoded d = FeedAll(dec, Hex(wire));
    CHECK_TEXT(d.frames.size() == 1, wire);
    if (d.frames.size() == 1) CHECK_TEXT(Encode(ApiMode::kEscaped, d.frames[0]) == Hex(wire), wire);
  }
}

// ---------------------------------------------------------------------------------------------
// 0x10 Transmit Request.
// ---------------------------------------------------------------------------------------------

TEST(PeerVectors, TransmitRequestsEncodeAndParseAsPeersExpect) {
  uint8_t wire[kMaxWireFrame];
  {
    // jankolkmeier/xbee-api:test/xbee-api_test.js (Transmit Requests); also
    // jefffhaynes/XBee:XBee.Test/FrameTests.cs (TxRequestFrameTest): "TxData0A".
    const auto data = Bytes("TxData0A");
    TransmitRequest req;
    req.frame_id = 0x01;
    req.dest64 = 0x0013A200400A0127ull;
    req.dest16 = 0xFFFE;
    req.payload = data.data();
    req.payload_len = data.size();
    const size_t n = EncodeTransmitRequest(ApiMode::kUnescaped, req, wire, sizeof wire);
    CHECK(std::vector<uint8_t>(wire, wire + n) ==
          Hex("7E 00 16 10 01 00 13 A2 00 40 0A 01 27 FF FE 00 00 54 78 44 61 74 61 30 41 13"));
  }
  {
    // northernpaws/xbee3-rs:src/api/frames/transmit_request.rs (test_packet): "HELLO" to the
    // coordinator; its checksum is 0x7D. In mode 2 (ours, from Digi's escaping rule) the length 0x13
    // and the checksum 0x7D are escaped.
    const auto data = Bytes("HELLO");
    TransmitRequest req;
    req.frame_id = 0x01;
    req.dest64 = kCoordinatorAddress64;
    req.dest16 = kUnknownAddress16;
    req.payload = data.data();
    req.payload_len = data.size();
    const size_t n1 = EncodeTransmitRequest(ApiMode::kUnescaped, req, wire, sizeof wire);
    LONGS_EQUAL(23, n1);
    CHECK(std::vector<uint8_t>(wire, wire + n1) == Hex("7E 00 13 10 01 00 00 00 00 00 00 00 00 FF FE 00 00 48 45 4C 4C 4F 7D"));
    const size_t n2 = EncodeTransmitRequest(ApiMode::kEscaped, req, wire, sizeof wire);
    CHECK(std::vector<uint8_t>(wire, wire + n2) ==
          Hex("7E 00 7D 33 10 01 00 00 00 00 00 00 00 00 FF FE 00 00 48 45 4C 4C 4F 7D 5D"));
    FrameDecoder dec(ApiMode::kEscaped);
    const Decoded d = FeedAll(dec, std::vector<uint8_t>(wire, wire + n2));
    LONGS_EQUAL(1, d.frames.size());
    TransmitRequest back;
    LONGS_EQUAL(static_cast<int>(Status::kOk),
                static_cast<int>(ParseTransmitRequest(d.frames[0].data(), d.frames[0].size(), &back)));
    LONGS_EQUAL(5, back.payload_len);
    CHECK(std::memcmp(back.payload, "HELLO", 5) == 0);
  }
  {
    // rockwood/exbee:test/exbee/frames/tx_frame_test.exs (encodes binary payloads): mac 0x01,
    // network 0x02, payload 0x01.
    const uint8_t payload[] = {0x01};
    TransmitRequest req;
    req.frame_id = 0x01;
    req.dest64 = 0x01;
    req.dest16 = 0x02;
    req.payload = payload;
    req.payload_len = 1;
    uint8_t out[kMaxFrameData];
    size_t w = 0;
    LONGS_EQUAL(static_cast<int>(Status::kOk), static_cast<int>(BuildTransmitRequest(req, out, sizeof out, &w)));
    CHECK(std::vector<uint8_t>(out, out + w) == Hex("10 01 00 00 00 00 00 00 00 01 00 02 00 00 01"));
  }
  {
    // digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketTransmitRequestFrame).
    const auto frame = Hex("7E 00 11 10 01 00 13 A2 00 40 32 16 2E FF FE 00 00 42 79 65 66");
    FrameDecoder dec(ApiMode::kUnescaped);
    const Decoded d = FeedAll(dec, frame);
    LONGS_EQUAL(1, d.frames.size());
    TransmitRequest req;
    LONGS_EQUAL(static_cast<int>(Status::kOk),
                static_cast<int>(ParseTransmitRequest(d.frames[0].data(), d.frames[0].size(), &req)));
    LONGS_EQUAL(0x01, req.frame_id);
    CHECK(req.dest64 == 0x0013A2004032162Eull);
    LONGS_EQUAL(0xFFFE, req.dest16);
    LONGS_EQUAL(3, req.payload_len);
    CHECK(std::memcmp(req.payload, "Bye", 3) == 0);
    const size_t n = EncodeTransmitRequest(ApiMode::kUnescaped, req, wire, sizeof wire);
    CHECK(std::vector<uint8_t>(wire, wire + n) == frame);
  }
  // digidotcom/xbee-java:library/src/test/java/com/digi/xbee/api/packet/common/TransmitPacketTest.java:
  // frame id 0xE7, dest64 0013A2004032D9AB, dest16 B45C, radius 0, options 0x04, data "hola".
  const auto full = Hex("10 E7 00 13 A2 00 40 32 D9 AB B4 5C 00 04 68 6F 6C 61");
  TransmitRequest req;
  // testCreatePacketValidPayloadWithData
  LONGS_EQUAL(static_cast<int>(Status::kOk), static_cast<int>(ParseTransmitRequest(full.data(), full.size(), &req)));
  LONGS_EQUAL(0xE7, req.frame_id);
  CHECK(req.dest64 == 0x0013A2004032D9ABull);
  LONGS_EQUAL(0xB45C, req.dest16);
  LONGS_EQUAL(0x00, req.broadcast_radius);
  LONGS_EQUAL(0x04, req.options);
  LONGS_EQUAL(4, req.payload_len);
  CHECK(std::memcmp(req.payload, "hola", 4) == 0);
  // testCreatePacketValidPayloadWithoutData: 14 bytes, no RF data.
  LONGS_EQUAL(static_cast<int>(Status::kOk), static_cast<int>(ParseTransmitRequest(full.data(), 14, &req)));
  LONGS_EQUAL(0, req.payload_len);
  // testCreatePacketPayloadShorterThanNeeded: 13 bytes ("Incomplete Transmit packet").
  LONGS_EQUAL(static_cast<int>(Status::kTruncated), static_cast<int>(ParseTransmitRequest(full.data(), 13, &req)));
  // testCreatePacketEmptyPayload.
  LONGS_EQUAL(static_cast<int>(Status::kTruncated), static_cast<int>(ParseTransmitRequest(full.data(), 0, &req)));
  // testCreatePacketPayloadNotIncludingFrameType: starts at the frame id ("Payload is not a Transmit packet").
  LONGS_EQUAL(static_cast<int>(Status::kWrongType),
              static_cast<int>(ParseTransmitRequest(full.data() + 1, full.size() - 1, &req)));
}

// ---------------------------------------------------------------------------------------------
// 0x8B Transmit Status.
// ---------------------------------------------------------------------------------------------

TEST(PeerVectors, TransmitStatusParsesAndBuildsAsPeersExpect) {
  struct Vec {
    const char* source;
    const char* wire;
    uint8_t frame_id;
    uint16_t dest16;
    uint8_t retries, delivery, discovery;
  };
  const Vec vectors[] = {
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (Transmit Status)", "7E 00 07 8B 01 7D 84 00 00 01 71", 0x01, 0x7D84, 0, 0,
       1},
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketTransmitStatusFrame)",
       "7E 00 07 8B 01 12 34 00 00 00 2D", 0x01, 0x1234, 0, 0, 0},
      {"jefffhaynes/XBee:XBee.Test/FrameTests.cs (TxStatusExtFrameTest)", "7E 00 07 8B 47 FF FF 00 00 02 2D", 0x47, 0xFFFF, 0, 0,
       2},
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (Escaping (AP=2), frame id 0x7D; read in mode 1 after unescaping)",
       "7E 00 07 8B 7D 2A 6A 00 00 00 63", 0x7D, 0x2A6A, 0, 0, 0},
  };
  for (const Vec& v : vectors) {
    FrameDecoder dec(ApiMode::kUnescaped);
    const Decoded d = FeedAll(dec, Hex(v.wire));
    CHECK_TEXT(d.frames.size() == 1, v.source);
    if (d.frames.size() != 1) continue;
    TransmitStatus st;
    CHECK_TEXT(ParseTransmitStatus(d.frames[0].data(), d.frames[0].size(), &st) == Status::kOk, v.source);
    CHECK_TEXT(st.frame_id == v.frame_id && st.dest16 == v.dest16 && st.retry_count == v.retries &&
                   st.delivery_status == v.delivery && st.discovery_status == v.discovery,
               v.source);
    uint8_t out[kMaxFrameData];
    size_t w = 0;
    CHECK_TEXT(BuildTransmitStatus(st, out, sizeof out, &w) == Status::kOk, v.source);
    CHECK_TEXT(Encode(ApiMode::kUnescaped, std::vector<uint8_t>(out, out + w)) == Hex(v.wire), v.source);
  }
  // rockwood/exbee:test/exbee/frames/tx_result_frame_test.exs (decode): id 1, network 0xEF2F, ok.
  const auto exbee = Hex("8B 01 EF 2F 00 00 00");
  TransmitStatus st;
  LONGS_EQUAL(static_cast<int>(Status::kOk), static_cast<int>(ParseTransmitStatus(exbee.data(), exbee.size(), &st)));
  LONGS_EQUAL(1, st.frame_id);
  LONGS_EQUAL(0xEF2F, st.dest16);
  STRCMP_EQUAL("success", DeliveryStatusName(st.delivery_status));

  // digidotcom/xbee-java:library/src/test/java/com/digi/xbee/api/packet/common/TransmitStatusPacketTest.java:
  // frame id 0xE7, address B45C, 3 retries.
  const auto valid = Hex("8B E7 B4 5C 03 00 00");  // testCreatePacketValidPayload
  LONGS_EQUAL(static_cast<int>(Status::kOk), static_cast<int>(ParseTransmitStatus(valid.data(), valid.size(), &st)));
  LONGS_EQUAL(0xE7, st.frame_id);
  LONGS_EQUAL(0xB45C, st.dest16);
  LONGS_EQUAL(3, st.retry_count);
  // testCreatePacketValidPayloadUnknownDeliveryStatus: 255 -> unknown.
  const auto unknown = Hex("8B E7 B4 5C 03 FF 00");
  LONGS_EQUAL(static_cast<int>(Status::kOk), static_cast<int>(ParseTransmitStatus(unknown.data(), unknown.size(), &st)));
  STRCMP_EQUAL("unknown", DeliveryStatusName(st.delivery_status));
  // testCreatePacketValidPayloadUnknownDiscoveryStatus: delivery BROADCAST_FAILED (0x26).
  const auto broadcast = Hex("8B E7 B4 5C 03 26 FF");
  LONGS_EQUAL(static_cast<int>(Status::kOk), static_cast<int>(ParseTransmitStatus(broadcast.data(), broadcast.size(), &st)));
  STRCMP_EQUAL("broadcast_source_failed_to_hear_neighbour", DeliveryStatusName(st.delivery_status));
  LONGS_EQUAL(0xFF, st.discovery_status);
  // testCreatePacketPayloadShorterThanNeeded (6 bytes), testCreatePacketEmptyPayload.
  LONGS_EQUAL(static_cast<int>(Status::kTruncated), static_cast<int>(ParseTransmitStatus(valid.data(), 6, &st)));
  LONGS_EQUAL(static_cast<int>(Status::kTruncated), static_cast<int>(ParseTransmitStatus(valid.data(), 0, &st)));
  // testCreatePacketPayloadNotIncludingFrameType: 7 bytes starting at the frame id.
  const auto no_type = Hex("E7 B4 5C 03 00 00 00");
  LONGS_EQUAL(static_cast<int>(Status::kWrongType), static_cast<int>(ParseTransmitStatus(no_type.data(), no_type.size(), &st)));
}

// ---------------------------------------------------------------------------------------------
// 0x90 Receive Packet.
// ---------------------------------------------------------------------------------------------

TEST(PeerVectors, ReceivePacketsParseAndEncodeAsPeersExpect) {
  struct Vec {
    const char* source;
    const char* wire;
    uint64_t src64;
    uint16_t src16;
    uint8_t options;
    const char* data;
  };
  const Vec vectors[] = {
      {"jankolkmeier/xbee-api:test/xbee-api_test.js (Receive Packet)",
       "7E 00 12 90 00 13 A2 00 40 52 2B AA 7D 84 01 52 78 44 61 74 61 0D", 0x0013A20040522BAAull, 0x7D84, 0x01, "RxData"},
      {"digidotcom/xbee-java:...XBeePacketParserFromInputStreamTest.java (testParsePacketReceivePacketFrame)",
       "7E 00 0F 90 00 13 A2 00 40 32 16 2E FF FE 01 42 79 65 E6", 0x0013A2004032162Eull, 0xFFFE, 0x01, "Bye"},
  };
  uint8_t wire[kMaxWireFrame];
  for (const Vec& v : vectors) {
    for (ApiMode mode : {ApiMode::kUnescaped, ApiMode::kEscaped}) {
      // Mode 2: the same frame data, escaped by our encoder (0x7D in 0x7D84 is escaped).
      const auto data = Hex(v.wire);
      const std::vector<uint8_t> frame(data.begin() + 3, data.end() - 1);
      const auto stream = mode == ApiMode::kUnescaped ? data : Encode(mode, frame);
      FrameDecoder dec(mode);
      const Decoded d = FeedAll(dec, stream);
      CHECK_TEXT(d.frames.size() == 1, v.source);
      if (d.frames.size() != 1) continue;
      ReceivePacket rx;
      CHECK_TEXT(ParseReceivePacket(d.frames[0].data(), d.frames[0].size(), &rx) == Status::kOk, v.source);
      CHECK_TEXT(rx.src64 == v.src64 && rx.src16 == v.src16 && rx.options == v.options, v.source);
      CHECK_TEXT(rx.payload_len == std::strlen(v.data) && std::memcmp(rx.payload, v.data, rx.payload_len) == 0, v.source);
      const size_t n = EncodeReceivePacket(mode, rx, wire, sizeof wire);
      CHECK_TEXT(std::vector<uint8_t>(wire, wire + n) == stream, v.source);
    }
  }
  // digidotcom/xbee-java:library/src/test/java/com/digi/xbee/api/packet/common/ReceivePacketTest.java:
  // source 0013A2004032D9AB / D817, options 40, data "hola".
  const auto full = Hex("90 00 13 A2 00 40 32 D9 AB D8 17 28 68 6F 6C 61");
  ReceivePacket rx;
  LONGS_EQUAL(static_cast<int>(Status::kOk), static_cast<int>(ParseReceivePacket(full.data(), full.size(), &rx)));
  CHECK(rx.src64 == 0x0013A2004032D9ABull);
  LONGS_EQUAL(0xD817, rx.src16);
  LONGS_EQUAL(40, rx.options);
  LONGS_EQUAL(4, rx.payload_len);
  // testCreatePacketValidPayloadWithoutData (12 bytes), testCreatePacketPayloadShorterThanNeeded (11),
  // testCreatePacketEmptyPayload.
  LONGS_EQUAL(static_cast<int>(Status::kOk), static_cast<int>(ParseReceivePacket(full.data(), 12, &rx)));
  LONGS_EQUAL(0, rx.payload_len);
  LONGS_EQUAL(static_cast<int>(Status::kTruncated), static_cast<int>(ParseReceivePacket(full.data(), 11, &rx)));
  LONGS_EQUAL(static_cast<int>(Status::kTruncated), static_cast<int>(ParseReceivePacket(full.data(), 0, &rx)));
  // testCreatePacketPayloadNotIncludingFrameType: starts at the 64-bit address.
  LONGS_EQUAL(static_cast<int>(Status::kWrongType), static_cast<int>(ParseReceivePacket(full.data() + 1, full.size() - 1, &rx)));
}

// ---------------------------------------------------------------------------------------------
// 0x8A Modem Status.
// ---------------------------------------------------------------------------------------------

TEST(PeerVectors, ModemStatusParsesAsPeersExpect) {
  // jankolkmeier/xbee-api:test/xbee-api_test.js (Modem Status); digidotcom/xbee-java:
  // ...XBeePacketParserFromInputStreamTest.java (testParsePacketModemStatusFrame): 0x06 coordinator started.
  FrameDecoder dec(ApiMode::kUnescaped);
  const Decoded d = FeedAll(dec, Hex("7E 00 02 8A 06 6F"));
  LONGS_EQUAL(1, d.frames.size());
  ModemStatus ms;
  LONGS_EQUAL(static_cast<int>(Status::kOk), static_cast<int>(ParseModemStatus(d.frames[0].data(), d.frames[0].size(), &ms)));
  LONGS_EQUAL(6, ms.status);
  STRCMP_EQUAL("coordinator_started", ModemStatusName(ms.status));
  // digidotcom/xbee-java:library/src/test/java/com/digi/xbee/api/packet/common/ModemStatusPacketTest.java.
  const auto joined = Hex("8A 02");  // testCreatePacketValidPayload: STATUS_JOINED_NETWORK
  LONGS_EQUAL(static_cast<int>(Status::kOk), static_cast<int>(ParseModemStatus(joined.data(), joined.size(), &ms)));
  STRCMP_EQUAL("joined_network", ModemStatusName(ms.status));
  LONGS_EQUAL(static_cast<int>(Status::kTruncated), static_cast<int>(ParseModemStatus(joined.data(), 1, &ms)));
  LONGS_EQUAL(static_cast<int>(Status::kTruncated), static_cast<int>(ParseModemStatus(joined.data(), 0, &ms)));
  const auto wrong = Hex("10 02");  // testCreatePacketPayloadInvalidFrameType
  LONGS_EQUAL(static_cast<int>(Status::kWrongType), static_cast<int>(ParseModemStatus(wrong.data(), wrong.size(), &ms)));
}

// ---------------------------------------------------------------------------------------------
// 0x95 Node Identification Indicator.
// ---------------------------------------------------------------------------------------------

TEST(PeerVectors, NodeIdentificationParsesAsPeersExpect) {
  struct Vec {
    const char* source;
    std::vector<uint8_t> data;
    const char* ni;
  };
  const auto head = Hex("95 00 13 A2 00 40 52 2B AA 7D 84 02 7D 84 00 13 A2 00 40 52 2B AA");
  const auto tail = Hex("00 FF FE 01 01 C1 05 10 1E");
  auto with_ni = [&](const char* ni) {
    std::vector<uint8_t> v = head;
    v.insert(v.end(), ni, ni + std::strlen(ni));
    v.insert(v.end(), tail.begin(), tail.end());
    return v;
  };
  const Vec vectors[] = {
      {"nioinnovation/python-xbee:xbee/thread/tests/test_zigbee.py (test_split_node_identification_identifier)", with_ni(" "),
       " "},
      {"nioinnovation/python-xbee:xbee/thread/tests/test_zigbee.py (test_split_node_identification_identifier2)",
       with_ni("Coordinator"), "Coordinator"},
  };
  for (const Vec& v : vectors) {
    NodeIdentification ni;
    CHECK_TEXT(ParseNodeIdentification(v.data.data(), v.data.size(), &ni) == Status::kOk, v.source);
    CHECK_TEXT(ni.sender64 == 0x0013A20040522BAAull && ni.sender16 == 0x7D84 && ni.receive_options == 0x02, v.source);
    CHECK_TEXT(ni.remote16 == 0x7D84 && ni.remote64 == 0x0013A20040522BAAull, v.source);
    CHECK_TEXT(std::strcmp(ni.node_identifier, v.ni) == 0, v.source);
    CHECK_TEXT(ni.parent16 == 0xFFFE && ni.device_type == 1 && ni.source_event == 1, v.source);
    CHECK_TEXT(ni.profile_id == 0xC105 && ni.manufacturer_id == 0x101E, v.source);
    CHECK_TEXT(!ni.has_device_type_identifier && !ni.has_rssi, v.source);
    uint8_t out[kMaxFrameData];
    size_t w = 0;
    CHECK_TEXT(BuildNodeIdentification(ni, out, sizeof out, &w) == Status::kOk, v.source);
    CHECK_TEXT(std::vector<uint8_t>(out, out + w) == v.data, v.source);
  }
  // jankolkmeier/xbee-api:test/xbee-api_test.js (Node Identification Indicator): the NI " " frame
  // above as a complete wire frame, through the decoder in both modes (mode 2: escaped by us).
  const auto wire =
      Hex("7E 00 20 95 00 13 A2 00 40 52 2B AA 7D 84 02 7D 84 00 13 A2 00 40 52 2B AA 20 00 FF FE 01 01 C1 05 10 1E 1B");
  for (ApiMode mode : {ApiMode::kUnescaped, ApiMode::kEscaped}) {
    FrameDecoder dec(mode);
    const Decoded d = FeedAll(dec, mode == ApiMode::kUnescaped ? wire : Encode(mode, with_ni(" ")));
    LONGS_EQUAL(1, d.frames.size());
    CHECK(d.frames[0] == with_ni(" "));
  }
  // nioinnovation/python-xbee:xbee/thread/tests/test_zigbee.py (test_null_terminated_field): 21 zero
  // bytes of addresses and options, NI 01 02 03 04, terminator, 8 zero bytes.
  std::vector<uint8_t> nul(22, 0x00);
  nul[0] = 0x95;
  const auto ni_field = Hex("01 02 03 04 00");
  nul.insert(nul.end(), ni_field.begin(), ni_field.end());
  nul.insert(nul.end(), 8, 0x00);
  NodeIdentification ni;
  LONGS_EQUAL(static_cast<int>(Status::kOk), static_cast<int>(ParseNodeIdentification(nul.data(), nul.size(), &ni)));
  STRCMP_EQUAL("\x01\x02\x03\x04", ni.node_identifier);
}

// ---------------------------------------------------------------------------------------------
// Lengths: zero and maximum. No peer suite has a zero-length frame; for the maximum, peers accept
// up to 65535 (northernpaws/xbee3-rs:src/api/frames/transmit_request.rs: "65535 is the XBee max
// API packet size"). Our choice, on purpose (docs/protocol.md): frame data is 1..128 bytes
// (kMaxFrameData: a 0x10/0x90 with the 84-byte maximum RF payload fits, and so do all frames the
// radio sends linerwatch); the decoder's buffer is fixed (no heap on the MCU). A declared length of
// 0 (there is no API identifier) or above 128 is a length error, and the next frame still decodes.
// ---------------------------------------------------------------------------------------------

TEST(PeerVectors, ZeroAndOverlongLengthsAreLengthErrorsAndTheNextFrameDecodes) {
  const auto good = Hex("7E 00 02 8A 06 6F");
  const char* bad_heads[] = {"7E 00 00 FF", "7E 00 81", "7E FF FF"};
  for (ApiMode mode : {ApiMode::kUnescaped, ApiMode::kEscaped}) {
    for (const char* head : bad_heads) {
      auto stream = Hex(head);
      stream.insert(stream.end(), good.begin(), good.end());
      FrameDecoder dec(mode);
      const Decoded d = FeedAll(dec, stream);
      CHECK_TEXT(d.errors == std::vector<DecodeEvent>{kLength}, head);
      CHECK_TEXT(d.frames.size() == 1 && d.frames[0] == Hex("8A 06"), head);
    }
    // The largest frame we accept (128 bytes of frame data) decodes.
    std::vector<uint8_t> data(kMaxFrameData, 0x11);
    data[0] = 0x90;
    FrameDecoder dec(mode);
    const Decoded d = FeedAll(dec, Encode(mode, data));
    LONGS_EQUAL(1, d.frames.size());
    CHECK(d.frames[0] == data);
  }
}
