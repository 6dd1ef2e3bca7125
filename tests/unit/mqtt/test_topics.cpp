// Topics of docs/mqtt.md: every topic built, parsed back, and nothing else parsed.
#include <string>
#include <vector>

#include "mqtt/topics.hpp"

// CppUTest last: its new/delete macros break standard headers included after it.
#include <CppUTest/TestHarness.h>

using lw::mqtt::ParsedTopic;
using lw::mqtt::TopicKind;
using lw::mqtt::Topics;

TEST_GROUP(Topics){};

TEST(Topics, BuildsEveryTopicOfTheContract) {
  const Topics t("mine", "cr7");
  STRCMP_EQUAL("linerwatch/v1/mine/cr7/", t.root().c_str());
  STRCMP_EQUAL("linerwatch/v1/mine/cr7/sensors/1001/reading", t.Reading("1001").c_str());
  STRCMP_EQUAL("linerwatch/v1/mine/cr7/sensors/1001/committed", t.Committed("1001").c_str());
  STRCMP_EQUAL("linerwatch/v1/mine/cr7/gateway/status", t.Status().c_str());
  STRCMP_EQUAL("linerwatch/v1/mine/cr7/gateway/stats", t.Stats().c_str());
  STRCMP_EQUAL("linerwatch/v1/mine/cr7/gateway/devices/0013A20040A1B2C3", t.Device("0013A20040A1B2C3").c_str());
  STRCMP_EQUAL("linerwatch/v1/mine/cr7/wear", t.Wear().c_str());
  STRCMP_EQUAL("linerwatch/v1/mine/cr7/sensors/+/committed", t.CommittedFilter().c_str());
  STRCMP_EQUAL("linerwatch/v1/+/+/sensors/+/reading", Topics::ReadingsFilter().c_str());
}

TEST(Topics, AnotherPrefixAsTheServersTopicRoot) {
  const Topics t("mine", "cr7", "plant/test");
  STRCMP_EQUAL("plant/test/mine/cr7/wear", t.Wear().c_str());
  STRCMP_EQUAL("plant/test/+/+/sensors/+/reading", Topics::ReadingsFilter("plant/test").c_str());
  const auto p = Topics::ParseAny("plant/test/mine/cr7/sensors/9/reading", "plant/test");
  CHECK(p.has_value());
  STRCMP_EQUAL("9", p->id.c_str());
  CHECK_FALSE(Topics::ParseAny("plant/test/mine/cr7/sensors/9/reading"));  // not below linerwatch/v1
  CHECK_FALSE(Topics::ParseAny("plant/testx/mine/cr7/sensors/9/reading", "plant/test"));
}

TEST(Topics, EveryBuiltTopicParsesBackToItsParts) {
  const Topics t("mine", "cr7");
  const std::vector<ParsedTopic> all = {
      {TopicKind::kReading, "mine", "cr7", "1001"},
      {TopicKind::kCommitted, "mine", "cr7", "1001"},
      {TopicKind::kStatus, "mine", "cr7", ""},
      {TopicKind::kStats, "mine", "cr7", ""},
      {TopicKind::kDevice, "mine", "cr7", "0013A20040A1B2C3"},
      {TopicKind::kWear, "mine", "cr7", ""},
      {TopicKind::kAlarms, "mine", "cr7", ""},
  };
  for (const ParsedTopic& want : all) {
    const std::string topic = t.Build(want.kind, want.id);
    const auto own = t.Parse(topic);
    const auto any = Topics::ParseAny(topic);
    CHECK_TEXT(own.has_value() && *own == want, topic.c_str());
    CHECK_TEXT(any.has_value() && *any == want, topic.c_str());
  }
}

TEST(Topics, ParsesTheServersReadingTopicsOnly) {
  const auto t = Topics::ParseAny("linerwatch/v1/mine/cr7/sensors/1001/reading");
  CHECK(t.has_value());
  CHECK(t->kind == TopicKind::kReading);
  STRCMP_EQUAL("mine", t->site.c_str());
  STRCMP_EQUAL("cr7", t->crusher.c_str());
  STRCMP_EQUAL("1001", t->id.c_str());
  CHECK(Topics::ParseAny("linerwatch/v1/mine/cr7/sensors/1001/committed")->kind == TopicKind::kCommitted);
  CHECK(Topics::ParseAny("linerwatch/v1/mine/cr7/wear")->kind == TopicKind::kWear);
  STRCMP_EQUAL("linerwatch/v1/mine/cr7/alarms", Topics("mine", "cr7").Alarms().c_str());
  STRCMP_EQUAL("linerwatch/v1/+/+/gateway/status", Topics::StatusFilter().c_str());
  CHECK_FALSE(Topics::ParseAny("other/v1/mine/cr7/sensors/1001/reading"));
  CHECK_FALSE(Topics::ParseAny("linerwatch/v1/mine//sensors/1001/reading"));
  CHECK_FALSE(Topics::ParseAny("linerwatch/v1//cr7/sensors/1001/reading"));
  CHECK_FALSE(Topics::ParseAny("linerwatch/v1/mine/cr7/sensors//reading"));
  CHECK_FALSE(Topics::ParseAny("linerwatch/v1/mine/cr7/sensors/1001/reading/extra"));
  CHECK_FALSE(Topics::ParseAny("linerwatch/v1/mine/cr7/sensors/1001/readings"));
  CHECK_FALSE(Topics::ParseAny("linerwatch/v1/mine/cr7/gateway/devices"));
  CHECK_FALSE(Topics::ParseAny("linerwatch/v1/mine/cr7/gateway/other"));
  CHECK_FALSE(Topics::ParseAny("linerwatch/v1/mine/cr7"));
  CHECK_FALSE(Topics::ParseAny("linerwatch/v1/mine/cr7/"));
  CHECK_FALSE(Topics::ParseAny("linerwatch/v1"));
  CHECK_FALSE(Topics::ParseAny(""));
}

TEST(Topics, ACrushersParseTakesOnlyItsOwnTopics) {
  const Topics t("s1", "c1");
  const auto own = t.Parse("linerwatch/v1/s1/c1/sensors/1001/committed");
  CHECK(own.has_value());
  CHECK(own->kind == TopicKind::kCommitted);
  STRCMP_EQUAL("1001", own->id.c_str());
  CHECK_FALSE(t.Parse("linerwatch/v1/other-site/c1/sensors/1001/committed"));
  CHECK_FALSE(t.Parse("linerwatch/v1/s1/other-crusher/sensors/1001/committed"));
  CHECK_FALSE(t.Parse("linerwatch/v1/s1/c1/sensors/1001"));
  CHECK_FALSE(t.Parse("linerwatch/v1/s1/c1/sensors//committed"));
  // {sensor} is one topic level: a subscription to sensors/+/committed never delivers more.
  CHECK_FALSE(t.Parse("linerwatch/v1/s1/c1/sensors/10/01/committed"));
  // Any other byte is the sensor's: the gateway logs such a topic escaped.
  const auto odd = t.Parse("linerwatch/v1/s1/c1/sensors/1\n2\x1B/committed");
  CHECK(odd.has_value());
  STRCMP_EQUAL("1\n2\x1B", odd->id.c_str());
}
