#include <cstring>
#include <string>
#include <vector>

#include "protocol/xbee_api.hpp"
#include "unit/protocol/frame_helpers.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw::protocol;
using lw::protocol::test::Encode;
using lw::protocol::test::Hex;

TEST_GROUP(XbeeApi){};

// Digi XBee Zigbee user guide, 0x10 Transmit Request example: payload "TxData0A" to 0013A200400A0127.
TEST(XbeeApi, DigiTransmitRequestExampleEncodesByteExact) {
  const char* text = "TxData0A";
  TransmitRequest req;
  req.frame_id = 0x01;
  req.dest64 = 0x0013A200400A0127ull;
  req.dest16 = 0xFFFE;
  req.payload = reinterpret_cast<const uint8_t*>(text);
  req.payload_len = std::strlen(text);
  uint8_t data[kMaxFrameData];
  size_t n = 0;
  CHECK(BuildTransmitRequest(req, data, sizeof data, &n) == Status::kOk);
  const auto wire = Encode(ApiMode::kUnescaped, std::vector<uint8_t>(data, data + n));
  const auto expected = Hex("7E 00 16 10 01 00 13 A2 00 40 0A 01 27 FF FE 00 00 54 78 44 61 74 61 30 41 13");
  CHECK(wire == expected);
}

TEST(XbeeApi, DigiTransmitStatusExampleParses) {
  const auto wire = Hex("7E 00 07 8B 01 7D 84 00 00 01 71");
  const std::vector<uint8_t> data(wire.begin() + 3, wire.end() - 1);
  TransmitStatus st;
  CHECK(ParseTransmitStatus(data.data(), data.size(), &st) == Status::kOk);
  LONGS_EQUAL(0x01, st.frame_id);
  LONGS_EQUAL(0x7D84, st.dest16);
  LONGS_EQUAL(0, st.retry_count);
  LONGS_EQUAL(0, st.delivery_status);
  STRCMP_EQUAL("success", DeliveryStatusName(st.delivery_status));
  LONGS_EQUAL(0x01, st.discovery_status);
  LONGS_EQUAL(0x71, Checksum(data.data(), data.size()));
}

TEST(XbeeApi, DigiReceivePacketExampleParses) {
  const auto wire = Hex("7E 00 12 90 00 13 A2 00 40 52 2B AA 7D 84 01 52 78 44 61 74 61 0D");
  const std::vector<uint8_t> data(wire.begin() + 3, wire.end() - 1);
  ReceivePacket rx;
  CHECK(ParseReceivePacket(data.data(), data.size(), &rx) == Status::kOk);
  CHECK(rx.src64 == 0x0013A20040522BAAull);
  LONGS_EQUAL(0x7D84, rx.src16);
  LONGS_EQUAL(0x01, rx.options);
  LONGS_EQUAL(6, rx.payload_len);
  MEMCMP_EQUAL("RxData", rx.payload, 6);
}

// The same Digi example built: 0x90 from 0013A20040522BAA / 0x7D84, options 0x01 (acknowledged),
// RF data "RxData". Hand check: length 0x12 = 1 type + 8 + 2 + 1 options + 6 data; checksum
// 0xFF - (sum of the 18 frame-data bytes & 0xFF) = 0x0D. In API mode 2 the 0x13 of the address and
// the 0x7D of the 16-bit address are escaped (7D 33, 7D 5D).
TEST(XbeeApi, DigiReceivePacketExampleEncodesByteExact) {
  const char* text = "RxData";
  const ReceivePacket rx{0x0013A20040522BAAull, 0x7D84, 0x01, reinterpret_cast<const uint8_t*>(text), 6};
  uint8_t wire[kMaxWireFrame];
  size_t n = EncodeReceivePacket(ApiMode::kUnescaped, rx, wire, sizeof wire);
  CHECK(std::vector<uint8_t>(wire, wire + n) == Hex("7E 00 12 90 00 13 A2 00 40 52 2B AA 7D 84 01 52 78 44 61 74 61 0D"));
  n = EncodeReceivePacket(ApiMode::kEscaped, rx, wire, sizeof wire);
  CHECK(std::vector<uint8_t>(wire, wire + n) == Hex("7E 00 12 90 00 7D 33 A2 00 40 52 2B AA 7D 5D 84 01 52 78 44 61 74 61 0D"));
  LONGS_EQUAL(0, EncodeReceivePacket(ApiMode::kUnescaped, rx, wire, 21));  // one byte short
  uint8_t big[kMaxRfPayload + 1] = {};
  const ReceivePacket too_big{1, 2, 0x01, big, sizeof big};
  LONGS_EQUAL(0, EncodeReceivePacket(ApiMode::kUnescaped, too_big, wire, sizeof wire));
}

TEST(XbeeApi, DigiModemStatusExampleRoundTrips) {
  ModemStatus ms{0x06};
  uint8_t data[4];
  size_t n = 0;
  CHECK(BuildModemStatus(ms, data, sizeof data, &n) == Status::kOk);
  CHECK(Encode(ApiMode::kUnescaped, std::vector<uint8_t>(data, data + n)) == Hex("7E 00 02 8A 06 6F"));
  ModemStatus back;
  CHECK(ParseModemStatus(data, n, &back) == Status::kOk);
  STRCMP_EQUAL("coordinator_started", ModemStatusName(back.status));
}

// Digi's API-mode-2 example: frame data 23 11 is sent as 23 7D 31.
TEST(XbeeApi, EscapedModeEscapesDataBytes) {
  CHECK(Encode(ApiMode::kEscaped, Hex("23 11")) == Hex("7E 00 02 23 7D 31 CB"));
  CHECK(Encode(ApiMode::kUnescaped, Hex("23 11")) == Hex("7E 00 02 23 11 CB"));
}

TEST(XbeeApi, EscapedModeEscapesLengthAndChecksum) {
  // Length 0x13 (XOFF) must be escaped; choose data whose checksum is 0x7E.
  std::vector<uint8_t> data(0x13, 0x00);
  data[0] = 0x10;
  // checksum = 0xFF - sum; make sum = 0x81 -> checksum 0x7E.
  data[1] = 0x71;
  LONGS_EQUAL(0x7E, Checksum(data.data(), data.size()));
  const auto wire = Encode(ApiMode::kEscaped, data);
  LONGS_EQUAL(0x7E, wire[0]);
  LONGS_EQUAL(0x00, wire[1]);
  LONGS_EQUAL(0x7D, wire[2]);
  LONGS_EQUAL(0x33, wire[3]);
  LONGS_EQUAL(0x7D, wire[wire.size() - 2]);
  LONGS_EQUAL(0x5E, wire[wire.size() - 1]);
  for (size_t i = 1; i < wire.size(); ++i) CHECK(wire[i] != 0x7E);
}

TEST(XbeeApi, EncodeRefusesSmallBufferAndBadLength) {
  const auto data = Hex("8A 06");
  uint8_t out[5];
  LONGS_EQUAL(0, EncodeFrame(ApiMode::kUnescaped, data.data(), data.size(), out, sizeof out));
  uint8_t big[kMaxFrameData + 1] = {};
  uint8_t wire[kMaxWireFrame + 4];
  LONGS_EQUAL(0, EncodeFrame(ApiMode::kUnescaped, big, sizeof big, wire, sizeof wire));
  LONGS_EQUAL(0, EncodeFrame(ApiMode::kUnescaped, big, 0, wire, sizeof wire));
  // Escaped frame that needs every byte escaped still fits kMaxWireFrame.
  uint8_t all_escape[kMaxFrameData];
  std::memset(all_escape, 0x7D, sizeof all_escape);
  CHECK(EncodeFrame(ApiMode::kEscaped, all_escape, sizeof all_escape, wire, kMaxWireFrame) > 0);
}

TEST(XbeeApi, NodeIdentificationRoundTrips) {
  NodeIdentification ni;
  ni.sender64 = 0x0013A20040A1B2C3ull;
  ni.sender16 = 0x1234;
  ni.receive_options = 0x02;
  ni.remote16 = 0x1234;
  ni.remote64 = 0x0013A20040A1B2C3ull;
  std::strcpy(ni.node_identifier, "LDWN-S07");
  ni.parent16 = 0xFFFE;
  ni.device_type = 2;
  ni.source_event = 1;
  ni.profile_id = 0xC105;
  ni.manufacturer_id = 0x101E;
  uint8_t data[kMaxFrameData];
  size_t n = 0;
  CHECK(BuildNodeIdentification(ni, data, sizeof data, &n) == Status::kOk);
  LONGS_EQUAL(0x95, data[0]);
  NodeIdentification back;
  CHECK(ParseNodeIdentification(data, n, &back) == Status::kOk);
  CHECK(back.sender64 == ni.sender64);
  CHECK(back.remote64 == ni.remote64);
  LONGS_EQUAL(ni.sender16, back.sender16);
  STRCMP_EQUAL("LDWN-S07", back.node_identifier);
  LONGS_EQUAL(2, back.device_type);
  LONGS_EQUAL(0xC105, back.profile_id);
  LONGS_EQUAL(0x101E, back.manufacturer_id);
  // Truncated anywhere -> error, never a read past the end.
  for (size_t len = 0; len < n; ++len) {
    CHECK(ParseNodeIdentification(data, len, &back) != Status::kOk);
  }
}

namespace {
// Parses a wire frame (mode 1) as a 0x95 and re-encodes it; the two wires must be equal.
std::vector<uint8_t> ReencodeNodeIdentification(const std::vector<uint8_t>& wire, NodeIdentification* ni) {
  const std::vector<uint8_t> data(wire.begin() + 3, wire.end() - 1);
  CHECK(ParseNodeIdentification(data.data(), data.size(), ni) == Status::kOk);
  uint8_t built[kMaxFrameData];
  size_t n = 0;
  CHECK(BuildNodeIdentification(*ni, built, sizeof built, &n) == Status::kOk);
  std::vector<uint8_t> out(kMaxWireFrame);
  out.resize(EncodeFrame(ApiMode::kUnescaped, built, n, out.data(), out.size()));
  return out;
}
}  // namespace

// Real-world 0x95 frames keep their optional trailing fields (DD device type identifier, RSSI)
// through parse and build. Vectors: Digi's XBee-PRO 900HP/XSC manual (DD + RSSI, NO set), a
// DD-only frame from another project's XBee test suite, Digi's Zigbee manual (no optional field).
TEST(XbeeApi, NodeIdentificationKeepsOptionalFieldsOnReencode) {
  const auto digi_dd_rssi =
      Hex("7E 00 25 95 00 13 A2 00 40 74 02 AC FF FE C2 FF FE 00 13 A2 00 40 74 02 AC 20 00 FF FE 01 01 C1 05 10 1E"
          " 00 0C 00 00 2E 33");
  NodeIdentification ni;
  CHECK(ReencodeNodeIdentification(digi_dd_rssi, &ni) == digi_dd_rssi);
  CHECK(ni.remote64 == 0x0013A200407402ACull);
  STRCMP_EQUAL(" ", ni.node_identifier);
  LONGS_EQUAL(1, ni.device_type);
  LONGS_EQUAL(0xC105, ni.profile_id);
  CHECK_TRUE(ni.has_device_type_identifier);
  LONGS_EQUAL(0x000C0000, ni.device_type_identifier);
  CHECK_TRUE(ni.has_rssi);
  LONGS_EQUAL(0x2E, ni.rssi);

  const auto dd_only =
      Hex("7E 00 27 95 00 13 A2 00 12 34 56 78 FF FE C2 FF FE 00 13 A2 00 12 34 56 78 4C 48 37 35 00 FF FE 01 01 C1 05"
          " 10 1E 00 14 00 08 0D");
  CHECK(ReencodeNodeIdentification(dd_only, &ni) == dd_only);
  STRCMP_EQUAL("LH75", ni.node_identifier);
  CHECK_TRUE(ni.has_device_type_identifier);
  LONGS_EQUAL(0x00140008, ni.device_type_identifier);
  CHECK_FALSE(ni.has_rssi);

  const auto zigbee_plain =
      Hex("7E 00 20 95 00 13 A2 00 40 52 2B AA 7D 84 02 7D 84 00 13 A2 00 40 52 2B AA 20 00 FF FE 01 01 C1 05 10 1E 1B");
  CHECK(ReencodeNodeIdentification(zigbee_plain, &ni) == zigbee_plain);
  LONGS_EQUAL(0x7D84, ni.remote16);
  CHECK_FALSE(ni.has_device_type_identifier);
  CHECK_FALSE(ni.has_rssi);

  // RSSI alone (NO asks for RSSI only): one byte after the manufacturer id.
  std::vector<uint8_t> data(zigbee_plain.begin() + 3, zigbee_plain.end() - 1);
  data.push_back(0x40);
  CHECK(ParseNodeIdentification(data.data(), data.size(), &ni) == Status::kOk);
  CHECK_TRUE(ni.has_rssi);
  CHECK_FALSE(ni.has_device_type_identifier);
  LONGS_EQUAL(0x40, ni.rssi);
  // Two or three trailing bytes are a cut DD field; more than five is not a 0x95 we know.
  data.push_back(0x41);
  CHECK(ParseNodeIdentification(data.data(), data.size(), &ni) == Status::kTruncated);
  data.insert(data.end(), {1, 2, 3, 4});
  CHECK(ParseNodeIdentification(data.data(), data.size(), &ni) == Status::kPayloadTooLarge);
}

TEST(XbeeApi, ParsersRejectWrongTypeAndTruncation) {
  const auto ms = Hex("8A 06");
  ReceivePacket rx;
  CHECK(ParseReceivePacket(ms.data(), ms.size(), &rx) == Status::kWrongType);
  TransmitStatus st;
  CHECK(ParseTransmitStatus(ms.data(), ms.size(), &st) == Status::kWrongType);
  const auto ts = Hex("8B 01 7D 84 00 00");
  CHECK(ParseTransmitStatus(ts.data(), ts.size(), &st) == Status::kTruncated);
  CHECK(ParseModemStatus(nullptr, 0, nullptr) == Status::kTruncated);
  const auto rx_short = Hex("90 00 13 A2 00 40 52 2B AA 7D 84");
  CHECK(ParseReceivePacket(rx_short.data(), rx_short.size(), &rx) == Status::kTruncated);
}

TEST(XbeeApi, TransmitRequestRoundTripAndLimits) {
  uint8_t payload[kMaxRfPayload];
  for (size_t i = 0; i < sizeof payload; ++i) payload[i] = static_cast<uint8_t>(i * 7);
  TransmitRequest req;
  req.frame_id = 0x42;
  req.dest64 = 0x0013A20040A1B2C3ull;
  req.payload = payload;
  req.payload_len = sizeof payload;
  uint8_t data[kMaxFrameData];
  size_t n = 0;
  CHECK(BuildTransmitRequest(req, data, sizeof data, &n) == Status::kOk);
  TransmitRequest back;
  CHECK(ParseTransmitRequest(data, n, &back) == Status::kOk);
  LONGS_EQUAL(0x42, back.frame_id);
  CHECK(back.dest64 == req.dest64);
  LONGS_EQUAL(sizeof payload, back.payload_len);
  MEMCMP_EQUAL(payload, back.payload, sizeof payload);
  req.payload_len = kMaxRfPayload + 1;
  CHECK(BuildTransmitRequest(req, data, sizeof data, &n) == Status::kPayloadTooLarge);
  req.payload_len = 10;
  CHECK(BuildTransmitRequest(req, data, 12, &n) == Status::kBufferTooSmall);
}

TEST(XbeeApi, DeliveryStatusNamesCoverDocumentedCodes) {
  STRCMP_EQUAL("mac_ack_failure", DeliveryStatusName(0x01));
  STRCMP_EQUAL("network_ack_failure", DeliveryStatusName(0x21));
  STRCMP_EQUAL("route_not_found", DeliveryStatusName(0x25));
  STRCMP_EQUAL("data_payload_too_large", DeliveryStatusName(0x74));
  STRCMP_EQUAL("unknown", DeliveryStatusName(0x99));
}

TEST(XbeeApi, EncodeTransmitRequestIsBuildThenEncode) {
  uint8_t payload[10] = {0x7E, 0x7D, 0x11, 0x13, 1, 2, 3, 4, 5, 6};  // bytes that need escaping in mode 2
  TransmitRequest req;
  req.frame_id = 9;
  req.dest64 = 0x0013A20040A1B2C3ull;
  req.payload = payload;
  req.payload_len = sizeof payload;
  uint8_t data[kMaxFrameData];
  size_t n = 0;
  CHECK(BuildTransmitRequest(req, data, sizeof data, &n) == Status::kOk);
  for (ApiMode mode : {ApiMode::kUnescaped, ApiMode::kEscaped}) {
    uint8_t a[kMaxWireFrame], b[kMaxWireFrame];
    const size_t la = EncodeFrame(mode, data, n, a, sizeof a);
    const size_t lb = EncodeTransmitRequest(mode, req, b, sizeof b);
    LONGS_EQUAL(la, lb);
    MEMCMP_EQUAL(a, b, la);
  }
  uint8_t small[8];
  LONGS_EQUAL(0, EncodeTransmitRequest(ApiMode::kEscaped, req, small, sizeof small));
  LONGS_EQUAL(1, NextFrameId(255));
  LONGS_EQUAL(2, NextFrameId(1));
}

// Digi's local AT Command example: NJ queried with frame id 0x52.
TEST(XbeeApi, AtCommandMatchesDigisExample) {
  AtCommand cmd;
  cmd.frame_id = 0x52;
  cmd.command[0] = 'N';
  cmd.command[1] = 'J';
  uint8_t wire[16];
  const size_t n = EncodeAtCommand(ApiMode::kUnescaped, cmd, wire, sizeof wire);
  const uint8_t expected[] = {0x7E, 0x00, 0x04, 0x08, 0x52, 0x4E, 0x4A, 0x0D};
  LONGS_EQUAL(sizeof expected, n);
  MEMCMP_EQUAL(expected, wire, n);
  AtCommand back;
  CHECK(ParseAtCommand(wire + 3, 4, &back) == Status::kOk);
  LONGS_EQUAL(0x52, back.frame_id);
  LONGS_EQUAL('J', back.command[1]);
  LONGS_EQUAL(0, back.parameter_len);
  CHECK(ParseAtCommand(wire + 3, 3, &back) == Status::kTruncated);
}

// Digi's AT Command Response example (BD set, OK), and a query answer carrying a value.
TEST(XbeeApi, AtCommandResponseMatchesDigisExampleAndCarriesTheValue) {
  const uint8_t digi[] = {0x88, 0x01, 0x42, 0x44, 0x00};
  LONGS_EQUAL(0xF0, Checksum(digi, sizeof digi));
  AtCommandResponse rsp;
  CHECK(ParseAtCommandResponse(digi, sizeof digi, &rsp) == Status::kOk);
  LONGS_EQUAL(1, rsp.frame_id);
  LONGS_EQUAL('B', rsp.command[0]);
  LONGS_EQUAL(0, rsp.status);
  uint64_t v = 0;
  CHECK_FALSE(rsp.Value(&v));  // a set: no value
  const uint8_t np[] = {0x88, 0x07, 'N', 'P', 0x00, 0x00, 0x54};
  CHECK(ParseAtCommandResponse(np, sizeof np, &rsp) == Status::kOk);
  CHECK(rsp.Value(&v));
  LONGS_EQUAL(84, v);
  const uint8_t failed[] = {0x88, 0x07, 'N', 'P', 0x02};
  CHECK(ParseAtCommandResponse(failed, sizeof failed, &rsp) == Status::kOk);
  CHECK_FALSE(rsp.Value(&v));
  uint8_t built[16];
  size_t len = 0;
  CHECK(ParseAtCommandResponse(np, sizeof np, &rsp) == Status::kOk);
  CHECK(BuildAtCommandResponse(rsp, built, sizeof built, &len) == Status::kOk);
  LONGS_EQUAL(sizeof np, len);
  MEMCMP_EQUAL(np, built, len);
}

// Digi's table (XBee 3 Zigbee, "Maximum RF payload size"): 84 bytes unencrypted, 66 with EE=1;
// NP 0xFF is the fragmented maximum an XBee 3 reports in API mode, so the EE table decides.
TEST(XbeeApi, RfPayloadLimitFollowsNpAndEe) {
  LONGS_EQUAL(84, RfPayloadLimit(0x54, 0));
  LONGS_EQUAL(66, RfPayloadLimit(0x42, 1));
  LONGS_EQUAL(84, RfPayloadLimit(0xFF, 0));
  LONGS_EQUAL(66, RfPayloadLimit(0xFF, 1));
  LONGS_EQUAL(66, RfPayloadLimit(0xFF, -1));  // EE unknown: assume encryption
  LONGS_EQUAL(49, RfPayloadLimit(49, 1));
  LONGS_EQUAL(84, RfPayloadLimit(0x80, 0));  // never above a single packet
  LONGS_EQUAL(0, RfPayloadLimit(-1, 0));     // NP unknown
}
