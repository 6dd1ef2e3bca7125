// /healthz's server fields: the counters and the broker as given, the start-up pass done once every
// crusher is computed, and "degraded" with the reason only when the database takes no writes.
#include <string>

#include "server/health.hpp"

#include <CppUTest/TestHarness.h>  // last: its leak-detection macros clash with std headers

using namespace lw::server;

TEST_GROUP(Health){};

TEST(Health, AWritableServerReportsItsCountersAndNoStatusOfItsOwn) {
  HealthInputs in;
  in.counters.stored = 12;
  in.counters.duplicates = 3;
  in.counters.rejected = 2;
  in.counters.held = 1;
  in.broker_connected = true;
  in.crusher_errors = {"bad: crusher.json: missing"};
  in.startup = {2, 2, 1};
  const nlohmann::ordered_json j = HealthJson(in);
  STRCMP_EQUAL("connected", j["broker"].get<std::string>().c_str());
  LONGS_EQUAL(12, j["readings_stored"].get<int64_t>());
  LONGS_EQUAL(3, j["duplicates"].get<int64_t>());
  LONGS_EQUAL(2, j["rejected"].get<int64_t>());
  LONGS_EQUAL(1, j["held"].get<int64_t>());
  STRCMP_EQUAL("bad: crusher.json: missing", j["crusher_errors"][0].get<std::string>().c_str());
  LONGS_EQUAL(2, j["startup"]["crushers"].get<int64_t>());
  LONGS_EQUAL(2, j["startup"]["loaded"].get<int64_t>());
  LONGS_EQUAL(1, j["startup"]["computed"].get<int64_t>());
  CHECK_FALSE(j["startup"]["done"].get<bool>());
  CHECK_FALSE(j.contains("status"));
  CHECK_FALSE(j.contains("reason"));
}

TEST(Health, TheStartupPassIsDoneOnceEveryCrusherIsComputed) {
  HealthInputs in;
  in.startup = {3, 3, 3};
  CHECK(HealthJson(in)["startup"]["done"].get<bool>());
  STRCMP_EQUAL("disconnected", HealthJson(in)["broker"].get<std::string>().c_str());
}

TEST(Health, ADatabaseThatTakesNoWritesMakesItDegradedWithTheReason) {
  HealthInputs in;
  in.not_writable = "disk full: 10 bytes free for x.db";
  const nlohmann::ordered_json j = HealthJson(in);
  STRCMP_EQUAL("degraded", j["status"].get<std::string>().c_str());
  STRCMP_EQUAL("disk full: 10 bytes free for x.db", j["reason"].get<std::string>().c_str());
}
