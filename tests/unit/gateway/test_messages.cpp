// The gateway's side of the messages of docs/mqtt.md: a radio record as a reading, a radio's
// registry entries as its device message, log lines (the codecs: tests/unit/mqtt/).
#include <nlohmann/json.hpp>

#include "gateway/messages.hpp"
#include "unit/gateway/gateway_test_support.hpp"

// CppUTest last: its new/delete macros break standard headers included after it.
#include <CppUTest/TestHarness.h>

using nlohmann::json;
namespace gw = lw::gateway;

TEST_GROUP(Messages){};

TEST(Messages, ReadingCarriesTheRequiredFieldsAndSampleTime) {
  lw::protocol::ReadingsHeader h;
  h.sensor_id = 1001;
  h.ladder_loops = 12;
  h.dropped_total = 3;
  auto r = gw::test::MakeRecord(42, 873, lw::protocol::kFlagHeartbeat | lw::protocol::kFlagLowBattery);
  r.age_s = 7;
  r.loop_bitmap[0] = 0xAB;
  r.loop_bitmap[1] = 0x0F;
  const std::string text = gw::ReadingJson(h, r, {0x0013A20040A1B2C3ull, "gw-1", 1772366407000});
  // Byte for byte what the gateway sent before lw::mqtt encoded it (keys sorted).
  STRCMP_EQUAL(R"({"address":"0013A20040A1B2C3","battery_mv":3550,"dropped_total":3,"flag_names":["heartbeat","low_battery"],)"
               R"("flags":65,"gateway":"gw-1","ladder_loops":12,"loop_bitmap":"ab0f","loops_intact":87,)"
               R"("received":"2026-03-01T12:00:07Z","sensor":"1001","seq":42,"temperature_c":31,"thickness_mm":87.3,)"
               R"("time":"2026-03-01T12:00:00Z"})",
               text.c_str());
  const json j = json::parse(text);
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

TEST(Messages, SanitizeForLogEscapesControlBytesAndCuts) {
  STRCMP_EQUAL("plain text 123", gw::SanitizeForLog("plain text 123").c_str());
  STRCMP_EQUAL("a\\x0Ab\\x0Dc\\x1B[31m\\x7F\\\\x", gw::SanitizeForLog("a\nb\rc\x1B[31m\x7F\\x").c_str());
  STRCMP_EQUAL("\\xC3\\xA9", gw::SanitizeForLog("\xC3\xA9").c_str());
  STRCMP_EQUAL("abc... (6 bytes)", gw::SanitizeForLog("abcdef", 3).c_str());
}

TEST(Messages, DeviceMessageOfOneAddress) {
  gw::DeviceEntry node{"0013A20040A1B2C3", "", "ROW1\xFF", 2, 1772366407000};
  gw::DeviceEntry sensor{"0013A20040A1B2C3", "1001", "", -1, 1772366400000};
  const std::string text = gw::DeviceJson({node, sensor}, "gw-1", 1772366407000);
  // Byte for byte what the gateway sent before lw::mqtt encoded it.
  STRCMP_EQUAL(R"({"address":"0013A20040A1B2C3","device_type":2,"first_seen":"2026-03-01T12:00:00Z","gateway":"gw-1",)"
               R"("node_identifier":"ROW1)"
               "\xEF\xBF\xBD"
               R"(","sensors":["1001"],"time":"2026-03-01T12:00:07Z"})",
               text.c_str());
  const json j = json::parse(text);
  STRCMP_EQUAL("0013A20040A1B2C3", j["address"].get<std::string>().c_str());
  CHECK(j["sensors"] == json({"1001"}));
  LONGS_EQUAL(2, j["device_type"].get<int>());
  STRCMP_EQUAL("2026-03-01T12:00:00Z", j["first_seen"].get<std::string>().c_str());
  // Not UTF-8 from the radio: replaced, never an exception.
  STRCMP_EQUAL("ROW1\xEF\xBF\xBD", j["node_identifier"].get<std::string>().c_str());
}
