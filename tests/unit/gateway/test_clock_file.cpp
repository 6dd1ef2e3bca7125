// The simulation clock (--clock-file): the file's virtual time stamps readings; timers keep the
// loop's time. Reading the file and its fallback: core::Clock (tests/unit/core/test_clock.cpp).
#include <cstdio>
#include <fstream>
#include <memory>

#include <nlohmann/json.hpp>

#include "gateway/config.hpp"
#include "gateway/gateway.hpp"
#include "gateway/spool.hpp"
#include "unit/gateway/gateway_test_support.hpp"

// CppUTest last: its new/delete macros break standard headers included after it.
#include <CppUTest/TestHarness.h>

namespace gw = lw::gateway;
namespace pr = lw::protocol;
using nlohmann::json;

TEST_GROUP(ClockFile) {
  lw::test::TempDirectory dir;
};

TEST(ClockFile, OptionIsParsed) {
  gw::Config c;
  gw::ParseCommandLine({"linerwatch-gateway", "--serial", "/dev/ttyUSB0", "--broker", "tcp://127.0.0.1:1883", "--site", "s1",
                        "--crusher", "c1", "--spool", "/tmp/x.db", "--clock-file", "/tmp/clock"},
                       &c);
  STRCMP_EQUAL("/tmp/clock", c.clock_file.c_str());
}

TEST(ClockFile, StampClockTimesReadingsButNotTheSpoolBookkeeping) {
  gw::Spool spool(dir.File("spool.db"), 1000);
  lw::test::FakePublisher publisher;
  lw::test::FakeRadio radio{pr::ApiMode::kEscaped};
  gw::GatewayOptions o;
  o.site = "s1";
  o.crusher = "c1";
  o.gateway_id = "gw-test";
  o.api_mode = pr::ApiMode::kEscaped;
  o.log = [](const std::string&) {};
  const int64_t virtual_ms = 1767571200000LL;  // 2026-01-05T00:00:00Z
  o.stamp_clock = [&](int64_t) { return virtual_ms; };
  gw::Gateway gateway(o, spool, publisher, radio);
  const int64_t wall_ms = 1'900'000'000'000LL;
  const auto bytes = gw::test::ReadingsFrame(pr::ApiMode::kEscaped, 0x0013A20040A1B2C3ull, 1001, {gw::test::MakeRecord(1)});
  gateway.OnBytes(bytes.data(), bytes.size(), wall_ms);
  gateway.Pump(wall_ms);
  const auto sent = publisher.SentOn("/reading");
  LONGS_EQUAL(1, sent.size());
  const json j = json::parse(sent[0].payload);
  // MakeRecord's age_s is 5.
  STRCMP_EQUAL("2026-01-04T23:59:55Z", j["time"].get<std::string>().c_str());
  CHECK(spool.Heads(10).at(0).received_ms == wall_ms);
}
