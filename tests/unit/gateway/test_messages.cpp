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
  STRCMP_EQUAL("not a JSON object", error.c_str());
  CHECK_FALSE(gw::ParseCommitAck(R"({"sensor": "1", "seqs": 5})", "1", &error).has_value());
  CHECK(error.find("seqs") != std::string::npos);
  CHECK_FALSE(gw::ParseCommitAck(R"({"sensor": "1", "seqs": [-1]})", "1", &error).has_value());
  CHECK_FALSE(gw::ParseCommitAck(R"({"sensor": "1", "seqs": [4294967296]})", "1", &error).has_value());
  CHECK_FALSE(gw::ParseCommitAck(R"({"sensor": "2", "seqs": [1]})", "1", &error).has_value());
  CHECK(error.find("does not match") != std::string::npos);
}
