// The gateway's logic through its public interface: bytes in, acks out, spool, MQTT messages,
// commit acks, replay, bad input. Time is passed in, so nothing here waits.
#include <nlohmann/json.hpp>

#include <memory>

#include "gateway/gateway.hpp"
#include "gateway/spool.hpp"
#include "unit/gateway/gateway_test_support.hpp"

// CppUTest last: its new/delete macros break standard headers included after it.
#include <CppUTest/TestHarness.h>

using nlohmann::json;
namespace gw = lw::gateway;
namespace pr = lw::protocol;
using gw::test::MakeRecord;
using gw::test::ReadingsFrame;

namespace {
constexpr uint64_t kAddrA = 0x0013A20040A1B2C3ull;
constexpr uint64_t kAddrB = 0x0013A20040FFEE01ull;
constexpr auto kMode = pr::ApiMode::kEscaped;
std::string Committed(uint32_t sensor) { return "linerwatch/v1/s1/c1/sensors/" + std::to_string(sensor) + "/committed"; }
std::string AckJson(const std::vector<uint32_t>& seqs) { return json{{"seqs", seqs}}.dump(); }
}  // namespace

TEST_GROUP(Gateway) {
  gw::test::TempDir dir;
  std::unique_ptr<gw::Spool> spool;
  gw::test::FakePublisher publisher;
  gw::test::FakeRadio radio{kMode};
  std::unique_ptr<gw::Gateway> gateway;
  std::vector<std::string> log;
  int64_t now = 1'000'000;

  void setup() override { Start(1'000); }
  void Start(size_t capacity, size_t window = 1) {
    gateway.reset();
    spool.reset();
    spool = std::make_unique<gw::Spool>(dir.File("spool.db"), capacity);
    gw::GatewayOptions o;
    o.site = "s1";
    o.crusher = "c1";
    o.gateway_id = "gw-test";
    o.api_mode = kMode;
    o.window = window;
    o.republish_after_ms = 10'000;
    o.stats_interval_ms = 60'000;
    o.log = [this](const std::string& line) { log.push_back(line); };
    gateway = std::make_unique<gw::Gateway>(o, *spool, publisher, radio);
  }
  void Feed(const std::vector<uint8_t>& bytes) { gateway->OnBytes(bytes.data(), bytes.size(), now); }
  /// A 0x95 Node Identification of kAddrB (an end device) with NI string `ni_string`.
  void FeedNodeIdentification(const char* ni_string) {
    pr::NodeIdentification ni;
    ni.remote64 = kAddrB;
    ni.sender64 = kAddrB;
    ni.device_type = 2;
    std::snprintf(ni.node_identifier, sizeof ni.node_identifier, "%s", ni_string);
    std::vector<uint8_t> frame(pr::kMaxFrameData);
    size_t len = 0;
    CHECK(pr::BuildNodeIdentification(ni, frame.data(), frame.size(), &len) == pr::Status::kOk);
    frame.resize(len);
    Feed(gw::test::Wire(kMode, frame));
  }
  std::vector<uint32_t> PublishedSeqs(uint32_t sensor) {
    std::vector<uint32_t> out;
    for (const auto& m : publisher.SentOn("sensors/" + std::to_string(sensor) + "/reading")) {
      out.push_back(json::parse(m.payload)["seq"].get<uint32_t>());
    }
    return out;
  }
};

TEST(Gateway, RecordIsSpooledThenAckedToItsSourceAddress) {
  publisher.connected = false;
  // At the moment the ack is written, another connection to the spool file already sees the
  // records: they are committed before the ack.
  std::vector<size_t> depth_seen_at_ack;
  radio.on_write = [&] { depth_seen_at_ack.push_back(gw::Spool(dir.File("spool.db"), 1000).depth()); };
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1), MakeRecord(2)}));
  LONGS_EQUAL(2, gateway->spool_depth());
  LONGS_EQUAL(1, radio.acks.size());
  CHECK(radio.acks[0].dest64 == kAddrA);
  LONGS_EQUAL(1001, radio.acks[0].ack.sensor_id);
  CHECK(radio.AckedSeqs() == (std::vector<uint32_t>{1, 2}));
  CHECK(depth_seen_at_ack == std::vector<size_t>{2});
}

TEST(Gateway, WallClockSteppingBackDoesNotStallRepublishing) {
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));
  gateway->Pump(now);
  now -= 3'600'000;  // NTP steps the clock back an hour
  gateway->Pump(now);
  gateway->Pump(now + 10'000);
  CHECK(PublishedSeqs(1001).size() >= 2);
}

TEST(Gateway, RetransmittedRecordIsAckedAgainButSpooledOnce) {
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));
  LONGS_EQUAL(1, gateway->spool_depth());
  LONGS_EQUAL(2, radio.acks.size());
  LONGS_EQUAL(1, gateway->counters().records_duplicate);
}

TEST(Gateway, PublishesReadingsQos1OnTheContractTopic) {
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(5, 880)}));
  gateway->Pump(now);
  const auto sent = publisher.SentOn("/reading");
  LONGS_EQUAL(1, sent.size());
  STRCMP_EQUAL("linerwatch/v1/s1/c1/sensors/1001/reading", sent[0].topic.c_str());
  LONGS_EQUAL(1, sent[0].qos);
  CHECK_FALSE(sent[0].retained);
  const json j = json::parse(sent[0].payload);
  DOUBLES_EQUAL(88.0, j["thickness_mm"].get<double>(), 1e-9);
  STRCMP_EQUAL("0013A20040A1B2C3", j["address"].get<std::string>().c_str());
}

TEST(Gateway, WindowOfOneReleasesTheNextRecordOnlyAfterTheCommitAck) {
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(3), MakeRecord(1), MakeRecord(2)}));
  Feed(ReadingsFrame(kMode, kAddrB, 2002, {MakeRecord(10)}));
  gateway->Pump(now);
  CHECK(PublishedSeqs(1001) == std::vector<uint32_t>{1});
  CHECK(PublishedSeqs(2002) == std::vector<uint32_t>{10});
  gateway->OnMessage(Committed(1001), AckJson({1}), now);
  gateway->Pump(now);
  gateway->OnMessage(Committed(1001), AckJson({2}), now);
  gateway->Pump(now);
  CHECK(PublishedSeqs(1001) == (std::vector<uint32_t>{1, 2, 3}));
  LONGS_EQUAL(2, gateway->spool_depth());
  LONGS_EQUAL(2, gateway->counters().committed);
}

TEST(Gateway, WiderWindowPublishesSeveralInOrder) {
  Start(1'000, 4);
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(2), MakeRecord(1), MakeRecord(3)}));
  gateway->Pump(now);
  CHECK(PublishedSeqs(1001) == (std::vector<uint32_t>{1, 2, 3}));
}

TEST(Gateway, UnconfirmedRecordIsRepublishedAfterTheTimeoutOnly) {
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));
  gateway->Pump(now);
  gateway->Pump(now + 9'999);
  LONGS_EQUAL(1, PublishedSeqs(1001).size());
  gateway->Pump(now + 10'000);
  CHECK(PublishedSeqs(1001) == (std::vector<uint32_t>{1, 1}));
  LONGS_EQUAL(1, gateway->counters().republished);
}

TEST(Gateway, ReconnectPublishesRetainedStatusAndReplaysInOrder) {
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1), MakeRecord(2)}));
  gateway->Pump(now);
  publisher.connected = false;
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(3)}));
  gateway->Pump(now + 1);
  publisher.connected = true;
  gateway->OnConnected(now + 2);
  const auto status = publisher.SentOn("gateway/status");
  LONGS_EQUAL(1, status.size());
  CHECK_TRUE(status[0].retained);
  STRCMP_EQUAL("online", json::parse(status[0].payload)["state"].get<std::string>().c_str());
  CHECK(PublishedSeqs(1001) == (std::vector<uint32_t>{1, 1}));  // replay starts at the oldest unconfirmed
  CHECK_TRUE(json::parse(publisher.SentOn("gateway/devices").at(0).payload)["devices"].size() == 1);
}

TEST(Gateway, SpoolSurvivesARestartAndIsReplayed) {
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1), MakeRecord(2)}));
  Start(1'000);  // a new process on the same spool file
  publisher.sent.clear();
  gateway->OnConnected(now);
  CHECK(PublishedSeqs(1001) == std::vector<uint32_t>{1});
  gateway->OnMessage(Committed(1001), AckJson({1, 2}), now);
  LONGS_EQUAL(0, gateway->spool_depth());
}

TEST(Gateway, RefusedPublicationIsRetried) {
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));
  publisher.refuse = true;
  gateway->Pump(now);
  publisher.refuse = false;
  gateway->Pump(now + 1);
  CHECK(PublishedSeqs(1001) == std::vector<uint32_t>{1});
}

TEST(Gateway, FullSpoolRecordIsNeitherStoredNorAcked) {
  Start(1);
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(2)}));
  CHECK(radio.AckedSeqs() == std::vector<uint32_t>{1});
  LONGS_EQUAL(1, gateway->counters().records_rejected);
  LONGS_EQUAL(1, json::parse(gateway->StatsJson(now))["records_rejected"].get<int>());
}

TEST(Gateway, GarbageAndMalformedFramesAreCountedNotFatal) {
  Feed({0x7E, 0x00, 0x05, 0x90, 0x01, 0x02, 0x03, 0x04, 0x00});             // bad checksum
  Feed(gw::test::Wire(kMode, {0x90, 0x01, 0x02}));                            // too short to parse
  Feed(gw::test::Wire(kMode, {0x42, 0x01}));                                  // unknown type
  std::vector<uint8_t> bad_payload = ReadingsFrame(kMode, kAddrB, 1001, {MakeRecord(1)});
  Feed(gw::test::Wire(kMode, {0x90, 0, 0x13, 0xA2, 0, 0x40, 0xFF, 0xEE, 0x01, 0x12, 0x34, 0x01, 1, 0x01, 9, 9}));  // bad CRC
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));                  // still works afterwards
  LONGS_EQUAL(1, gateway->spool_depth());
  const json stats = json::parse(gateway->StatsJson(now));
  LONGS_EQUAL(1, stats["checksum_errors"].get<int>());
  LONGS_EQUAL(1, stats["malformed_frames"].get<int>());
  LONGS_EQUAL(1, stats["unknown_types"].get<int>());
  LONGS_EQUAL(1, stats["bad_payloads"].get<int>());
  LONGS_EQUAL(1, stats["spool_depth"].get<int>());
  bool logged_source = false;
  for (const auto& line : log) logged_source |= line.find("0013A20040FFEE01") != std::string::npos;
  CHECK_TRUE(logged_source);
}

TEST(Gateway, NodeIdentificationEntersTheRegistry) {
  FeedNodeIdentification("ROW1-S3");
  gateway->Pump(now);
  const auto devices = publisher.SentOn("gateway/devices");
  LONGS_EQUAL(1, devices.size());
  CHECK_TRUE(devices[0].retained);
  const json d = json::parse(devices[0].payload)["devices"][0];
  STRCMP_EQUAL("0013A20040FFEE01", d["address"].get<std::string>().c_str());
  STRCMP_EQUAL("ROW1-S3", d["node_identifier"].get<std::string>().c_str());
}

// Found by fuzz/ (fuzz_gateway_serial): a node whose NI string is not UTF-8 (the radio sends any
// bytes) made every devices message throw in json::dump; it was counted as a spool error and the
// retained device registry was never published again (the node stays in the spool).
TEST(Gateway, NodeIdentifierThatIsNotUtf8StillPublishesTheRegistry) {
  FeedNodeIdentification("ROW1-\xfe\xff");
  gateway->Pump(now);
  LONGS_EQUAL(0, gateway->counters().spool_errors);
  const auto devices = publisher.SentOn("gateway/devices");
  LONGS_EQUAL(1, devices.size());
  const json d = json::parse(devices[0].payload)["devices"][0];
  STRCMP_EQUAL("ROW1-\xef\xbf\xbd\xef\xbf\xbd", d["node_identifier"].get<std::string>().c_str());  // U+FFFD twice
}

TEST(Gateway, BadCommitAcksAreCountedAndKeepTheRecord) {
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));
  gateway->OnMessage(Committed(1001), "{oops", now);
  gateway->OnMessage(Committed(1001), R"({"sensor": "9", "seqs": [1]})", now);
  LONGS_EQUAL(2, gateway->counters().bad_commit_acks);
  LONGS_EQUAL(1, gateway->spool_depth());
}

TEST(Gateway, StatsArePublishedPeriodicallyWithLatency) {
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));
  gateway->Pump(now);
  gateway->OnMessage(Committed(1001), AckJson({1}), now + 250);
  gateway->Pump(now + 30'000);
  LONGS_EQUAL(1, publisher.SentOn("gateway/stats").size());
  gateway->Pump(now + 60'000);
  const auto stats = publisher.SentOn("gateway/stats");
  LONGS_EQUAL(2, stats.size());
  LONGS_EQUAL(0, stats[1].qos);
  const json j = json::parse(stats[1].payload);
  LONGS_EQUAL(250, j["publish_latency_ms"]["last"].get<int>());
  LONGS_EQUAL(1, j["frames_ok"].get<int>());
  LONGS_EQUAL(0, j["spool_depth"].get<int>());
}

TEST(Gateway, ApiModeOneIsDecodedAndAckedInModeOne) {
  gateway.reset();
  gw::test::FakeRadio radio1{pr::ApiMode::kUnescaped};
  gw::GatewayOptions o;
  o.site = "s1";
  o.crusher = "c1";
  o.api_mode = pr::ApiMode::kUnescaped;
  o.log = [](const std::string&) {};
  gw::Gateway g(o, *spool, publisher, radio1);
  const auto bytes = ReadingsFrame(pr::ApiMode::kUnescaped, 0x0013A2004011137Dull, 0x137D11, {MakeRecord(0x7E7D1113)});
  g.OnBytes(bytes.data(), bytes.size(), now);
  CHECK(radio1.AckedSeqs() == std::vector<uint32_t>{0x7E7D1113});
}
