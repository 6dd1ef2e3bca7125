// Messages of docs/mqtt.md: the reading JSON, status, commit-ack parsing.
#include <nlohmann/json.hpp>

#include "gateway/messages.hpp"
#include "unit/gateway/gateway_test_support.hpp"

// CppUTest last: its new/delete macros break standard headers included after it.
#include <CppUTest/TestHarness.h>

using nlohmann::json;
namespace gw = lw::gateway;

TEST_GROUP(Messages){};

TEST(Messages, IsoUtcFormatsUnixMilliseconds) {
  STRCMP_EQUAL("1970-01-01T00:00:00Z", gw::IsoUtc(0).c_str());
  STRCMP_EQUAL("2026-03-01T12:00:07Z", gw::IsoUtc(1772366407123).c_str());
}

TEST(Messages, AddressIsSixteenUpperCaseHexDigits) {
  STRCMP_EQUAL("0013A20040A1B2C3", gw::AddressHex(0x0013A20040A1B2C3ull).c_str());
}

TEST(Messages, ReadingCarriesTheRequiredFieldsAndSampleTime) {
  lw::protocol::ReadingsHeader h;
  h.sensor_id = 1001;
  h.ladder_loops = 12;
  h.dropped_total = 3;
  auto r = gw::test::MakeRecord(42, 873, lw::protocol::kFlagHeartbeat | lw::protocol::kFlagLowBattery);
  r.age_s = 7;
  r.loop_bitmap[0] = 0xAB;
  r.loop_bitmap[1] = 0x0F;
  const json j = json::parse(gw::ReadingJson(h, r, {0x0013A20040A1B2C3ull, "gw-1", 1772366407000}));
  STRCMP_EQUAL("1001", j["sensor"].get<std::string>().c_str());
  LONGS_EQUAL(42, j["seq"].get<int>());
  STRCMP_EQUAL("2026-03-01T12:00:00Z", j["time"].get<std::string>().c_str());
  STRCMP_EQUAL("2026-03-01T12:00:07Z", j["received"].get<std::string>().c_str());
  DOUBLES_EQUAL(87.3, j["thickness_mm"].get<double>(), 1e-9);
  LONGS_EQUAL(87, j["loops_intact"].get<int>());
  LONGS_EQUAL(0x41, j["flags"].get<int>());
  CHECK(j["flag_names"] == json({"heartbeat", "low_battery"}));
  LONGS_EQUAL(3550, j["battery_mv"].get<int>());
  LONGS_EQUAL(31, j["temperature_c"].get<int>());
  STRCMP_EQUAL("ab0f", j["loop_bitmap"].get<std::string>().c_str());
  LONGS_EQUAL(3, j["dropped_total"].get<int>());
  STRCMP_EQUAL("0013A20040A1B2C3", j["address"].get<std::string>().c_str());
  STRCMP_EQUAL("gw-1", j["gateway"].get<std::string>().c_str());
}

TEST(Messages, StatusMessage) {
  const json j = json::parse(gw::StatusJson(false, "gw-7", 0));
  STRCMP_EQUAL("offline", j["state"].get<std::string>().c_str());
  STRCMP_EQUAL("gw-7", j["gateway"].get<std::string>().c_str());
}

TEST(Messages, CommitAckParses) {
  std::string error;
  const auto ack = gw::ParseCommitAck(R"({"sensor": "1001", "seqs": [41, 42, 43], "time": "x"})", "1001", &error);
  CHECK_TRUE(ack.has_value());
  STRCMP_EQUAL("1001", ack->sensor.c_str());
  CHECK(ack->seqs == (std::vector<uint32_t>{41, 42, 43}));
}

TEST(Messages, CommitAckWithoutSensorFieldUsesTheTopic) {
  std::string error;
  const auto ack = gw::ParseCommitAck(R"({"seqs": [1]})", "77", &error);
  CHECK_TRUE(ack.has_value());
  STRCMP_EQUAL("77", ack->sensor.c_str());
}

TEST(Messages, MalformedCommitAcksAreRefusedWithAReason) {
  std::string error;
  CHECK_FALSE(gw::ParseCommitAck("not json", "1", &error).has_value());
  STRCMP_EQUAL("not JSON", error.c_str());
  CHECK_FALSE(gw::ParseCommitAck("[1, 2]", "1", &error).has_value());
  STRCMP_EQUAL("not a JSON object", error.c_str());
  CHECK_FALSE(gw::ParseCommitAck(R"({"sensor": "1", "seqs": 5})", "1", &error).has_value());
  CHECK(error.find("seqs") != std::string::npos);
  CHECK_FALSE(gw::ParseCommitAck(R"({"sensor": "1", "seqs": [-1]})", "1", &error).has_value());
  CHECK_FALSE(gw::ParseCommitAck(R"({"sensor": "1", "seqs": [4294967296]})", "1", &error).has_value());
  CHECK_FALSE(gw::ParseCommitAck(R"({"sensor": "2", "seqs": [1]})", "1", &error).has_value());
  CHECK(error.find("does not match") != std::string::npos);
}

// Finding 1 of issue 15: `seqs` nested 100 000 deep crashed the gateway (SIGSEGV in a recursive
// dump() of the offending element); sent retained it crash-looped the gateway on every restart.
TEST(Messages, DeeplyNestedCommitAckIsRefusedWithoutRecursing) {
  auto nested = [](size_t depth) {
    return R"({"sensor": "1", "seqs": [)" + std::string(depth, '[') + "1" + std::string(depth, ']') + "]}";
  };
  std::string error;
  CHECK_FALSE(gw::ParseCommitAck(nested(100000), "1", &error).has_value());  // 200 kB: over the size limit
  CHECK(error.find("bytes (at most 65536)") != std::string::npos);
  CHECK_FALSE(gw::ParseCommitAck(nested(30000), "1", &error).has_value());   // 60 kB: the depth limit
  STRCMP_EQUAL("JSON nested deeper than 8 levels", error.c_str());
  // Deep but within the byte limit, in a field the gateway does not use: refused all the same.
  const std::string nested_extra = R"({"seqs": [1], "x": )" + std::string(20, '[') + std::string(20, ']') + "}";
  CHECK_FALSE(gw::ParseCommitAck(nested_extra, "1", &error).has_value());
}

TEST(Messages, CommitAckErrorsNeverEchoANestedValue) {
  std::string error;
  CHECK_FALSE(gw::ParseCommitAck(R"({"seqs": [1, [2, [3]]]})", "1", &error).has_value());
  STRCMP_EQUAL("\"seqs\" holds an array, not a 32-bit unsigned sequence number", error.c_str());
  CHECK_FALSE(gw::ParseCommitAck(R"({"seqs": [-7]})", "1", &error).has_value());
  STRCMP_EQUAL("\"seqs\" holds -7, not a 32-bit unsigned sequence number", error.c_str());
}

TEST(Messages, OversizedCommitAcksAreRefusedBeforeParsing) {
  std::string error;
  std::string big = R"({"seqs": [1], "pad": ")" + std::string(gw::kMaxCommitAckBytes, 'x') + "\"}";
  CHECK_FALSE(gw::ParseCommitAck(big, "1", &error).has_value());
  CHECK(error.find("bytes (at most 65536)") != std::string::npos);
  json many = {{"seqs", json::array()}};
  for (uint32_t i = 0; i <= gw::kMaxCommitAckSeqs; ++i) many["seqs"].push_back(i);
  CHECK_FALSE(gw::ParseCommitAck(many.dump(), "1", &error).has_value());
  CHECK(error.find("at most 10000") != std::string::npos);
  many["seqs"].erase(many["seqs"].size() - 1);
  CHECK_TRUE(gw::ParseCommitAck(many.dump(), "1", &error).has_value());
}

TEST(Messages, SanitizeForLogEscapesControlBytesAndCuts) {
  STRCMP_EQUAL("plain text 123", gw::SanitizeForLog("plain text 123").c_str());
  STRCMP_EQUAL("a\\x0Ab\\x0Dc\\x1B[31m\\x7F\\\\x", gw::SanitizeForLog("a\nb\rc\x1B[31m\x7F\\x").c_str());
  STRCMP_EQUAL("\\xC3\\xA9", gw::SanitizeForLog("\xC3\xA9").c_str());
  STRCMP_EQUAL("abc... (6 bytes)", gw::SanitizeForLog("abcdef", 3).c_str());
}

TEST(Messages, DeviceMessageOfOneAddress) {
  gw::DeviceEntry node{"0013A20040A1B2C3", "", "ROW1\xFF", 2, 1772366407000};
  gw::DeviceEntry sensor{"0013A20040A1B2C3", "1001", "", -1, 1772366400000};
  const json j = json::parse(gw::DeviceJson({node, sensor}, "gw-1", 1772366407000));
  STRCMP_EQUAL("0013A20040A1B2C3", j["address"].get<std::string>().c_str());
  CHECK(j["sensors"] == json({"1001"}));
  LONGS_EQUAL(2, j["device_type"].get<int>());
  STRCMP_EQUAL("2026-03-01T12:00:00Z", j["first_seen"].get<std::string>().c_str());
  // Not UTF-8 from the radio: replaced, never an exception.
  STRCMP_EQUAL("ROW1\xEF\xBF\xBD", j["node_identifier"].get<std::string>().c_str());
}
