// The gateway's logic through its public interface: bytes in, acks out, spool, MQTT messages,
// commit acks, replay, bad input. Time is passed in, so nothing here waits.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <map>
#include <memory>
#include <sstream>
#include <string>

#include "core/log.hpp"
#include "gateway/gateway.hpp"
#include "gateway/spool.hpp"
#include "mqtt/messages.hpp"
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
std::string Committed(uint32_t sensor) {
  return "linerwatch/v1/s1/c1/sensors/" + std::to_string(sensor) + "/committed";
}
std::string AckJson(const std::vector<uint32_t>& seqs) {
  return json{{"seqs", seqs}}.dump();
}
/// A commit ack announcing that the server takes up to `batch` records per reading message.
std::string BatchAckJson(const std::vector<uint32_t>& seqs, uint32_t batch) {
  return json{{"seqs", seqs}, {"batch", batch}}.dump();
}
std::vector<uint8_t> NodeIdFrame(uint64_t address, const char* node_identifier) {
  pr::NodeIdentification ni;
  ni.remote64 = address;
  ni.sender64 = address;
  ni.device_type = 2;
  std::snprintf(ni.node_identifier, sizeof ni.node_identifier, "%s", node_identifier);
  std::vector<uint8_t> frame(pr::kMaxFrameData);
  size_t len = 0;
  if (pr::BuildNodeIdentification(ni, frame.data(), frame.size(), &len) != pr::Status::kOk) return {};
  frame.resize(len);
  return gw::test::Wire(kMode, frame);
}
}  // namespace

TEST_GROUP(Gateway) {
  lw::test::TempDirectory dir;
  std::unique_ptr<gw::Spool> spool;
  lw::test::FakePublisher publisher;
  lw::test::FakeRadio radio{kMode};
  std::unique_ptr<gw::Gateway> gateway;
  std::vector<std::string> log;
  int64_t now = 1'000'000;

  void setup() override {
    Start(1'000);
  }
  void Start(size_t capacity, size_t window = 1, size_t max_devices = 1000, size_t max_batch = 64) {
    gateway.reset();
    spool.reset();
    spool = std::make_unique<gw::Spool>(dir.File("spool.db"), capacity);
    gw::GatewayOptions o;
    o.site = "s1";
    o.crusher = "c1";
    o.gateway_id = "gw-test";
    o.api_mode = kMode;
    o.window = window;
    o.max_devices = max_devices;
    o.max_batch = max_batch;
    o.republish_after_ms = 10'000;
    o.stats_interval_ms = 60'000;
    o.log = [this](const std::string& line) { log.push_back(line); };
    gateway = std::make_unique<gw::Gateway>(o, *spool, publisher, radio);
  }
  void Feed(const std::vector<uint8_t>& bytes) {
    gateway->OnBytes(bytes.data(), bytes.size(), now);
  }
  /// Records `first`..`last` of sensor 1001 (at kAddrA), two per frame (what fits a frame).
  void FeedSeqs(uint32_t first, uint32_t last) {
    for (uint32_t seq = first; seq <= last; seq += 2) {
      const auto frame = seq < last ? ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(seq), MakeRecord(seq + 1)})
                                    : ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(seq)});
      CHECK_FALSE(frame.empty());
      Feed(frame);
    }
  }
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
  // The gateway replaced by one on the same spool whose coordinator runs API mode 1.
  gw::Gateway& ModeOneGateway(lw::test::FakeRadio & radio1) {
    gw::GatewayOptions o;
    o.site = "s1";
    o.crusher = "c1";
    o.api_mode = pr::ApiMode::kUnescaped;
    o.log = [](const std::string&) {};
    gateway = std::make_unique<gw::Gateway>(o, *spool, publisher, radio1);
    return *gateway;
  }
  /// The seqs of each reading message of `sensor`, message by message; a batch (docs/mqtt.md) is
  /// read through lw::mqtt as the server reads it, and must name the sensor of its topic.
  std::vector<std::vector<uint32_t>> PublishedMessages(uint32_t sensor) {
    std::vector<std::vector<uint32_t>> out;
    for (const auto& m : publisher.SentOn("sensors/" + std::to_string(sensor) + "/reading")) {
      std::vector<std::string> records;
      std::string error;
      CHECK_TEXT(lw::mqtt::SplitReadingMessage(m.payload, &records, &error), error.c_str());
      if (records.empty()) records.push_back(m.payload);
      std::vector<uint32_t> seqs;
      for (const std::string& r : records) {
        const auto reading = lw::mqtt::DecodeReading(r, &error);
        CHECK_TEXT(reading.has_value(), error.c_str());
        STRCMP_EQUAL(std::to_string(sensor).c_str(), reading->sensor.c_str());
        seqs.push_back(reading->seq);
      }
      out.push_back(seqs);
    }
    return out;
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

// Frames read together are spooled in one transaction (group commit) and acked to their sensors
// only after it: at the ack write another connection already sees every record of the read, and
// the new senders' registry entries. The acks go out together, in one write, one ack list per
// sensor (its retransmitted seq named once).
TEST(Gateway, FramesOfOneReadAreSpooledTogetherBeforeAnyAck) {
  publisher.connected = false;
  std::vector<size_t> depth_seen_at_ack, devices_seen_at_ack;
  radio.on_write = [&] {
    const gw::Spool other(dir.File("spool.db"), 1000);
    depth_seen_at_ack.push_back(other.depth());
    devices_seen_at_ack.push_back(other.Devices().size());
  };
  std::vector<uint8_t> bytes = ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1), MakeRecord(2)});
  const std::vector<uint8_t> second = ReadingsFrame(kMode, kAddrB, 2002, {MakeRecord(7)});
  const std::vector<uint8_t> again = ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(2)});  // a retransmission in the same read
  bytes.insert(bytes.end(), second.begin(), second.end());
  bytes.insert(bytes.end(), again.begin(), again.end());
  Feed(bytes);
  LONGS_EQUAL(3, gateway->spool_depth());
  LONGS_EQUAL(2, radio.acks.size());
  CHECK(radio.AckedSeqs() == (std::vector<uint32_t>{1, 2, 7}));
  CHECK(depth_seen_at_ack == std::vector<size_t>{3});
  CHECK(devices_seen_at_ack == std::vector<size_t>{2});  // 1001 at A, 2002 at B
  CHECK(radio.acks[1].dest64 == kAddrB);
  LONGS_EQUAL(2002, radio.acks[1].ack.sensor_id);
  LONGS_EQUAL(3, gateway->counters().records_spooled);
  LONGS_EQUAL(1, gateway->counters().records_duplicate);
}

// The serial loop reads whatever the port holds (SerialPort::ReadWaiting), so a read can end
// anywhere: inside a frame, between an API-2 escape byte (0x7D) and the byte it escapes. At every
// cut of a stream of two frames full of escaped bytes, each record is spooled once and acked once.
TEST(Gateway, AReadEndingAnywhereInAFrameLosesAndDuplicatesNothing) {
  publisher.connected = false;
  constexpr uint64_t kEscapy = 0x0013A2007E7D1113ull;  // every byte API mode 2 escapes
  constexpr uint32_t kBase = 0x7E7D1100u;
  size_t cuts = 0, escapes = 0;
  for (uint32_t k = 0;; ++k) {
    std::vector<uint8_t> bytes = ReadingsFrame(kMode, kEscapy, 0x137D, {MakeRecord(kBase + 2 * k, 0x117E)});
    const auto second = ReadingsFrame(kMode, kEscapy, 0x137D, {MakeRecord(kBase + 2 * k + 1, 0x7D13)});
    bytes.insert(bytes.end(), second.begin(), second.end());
    if (k == 0) escapes = static_cast<size_t>(std::count(bytes.begin(), bytes.end(), 0x7D));
    const size_t cut = k + 1;
    if (cut >= bytes.size()) break;
    gateway->OnBytes(bytes.data(), cut, now);
    gateway->OnBytes(bytes.data() + cut, bytes.size() - cut, now);
    ++cuts;
  }
  CHECK_TEXT(escapes >= 8, std::to_string(escapes).c_str());
  CHECK(cuts > 100);
  LONGS_EQUAL(2 * cuts, gateway->spool_depth());
  LONGS_EQUAL(2 * cuts, gateway->counters().records_spooled);
  LONGS_EQUAL(0, gateway->counters().records_duplicate);
  std::vector<uint32_t> acked = radio.AckedSeqs();
  std::sort(acked.begin(), acked.end());
  LONGS_EQUAL(2 * cuts, acked.size());
  for (uint32_t i = 0; i < acked.size(); ++i) LONGS_EQUAL(kBase + i, acked[i]);
  for (const auto& a : radio.acks) CHECK(a.dest64 == kEscapy);
  const pr::DecoderCounters& d = gateway->decoder_counters();
  LONGS_EQUAL(0, d.checksum_errors + d.escape_errors);
}

// The acks of a long read go out compacted (one ack list per sensor, cut to the payload limit:
// 8 seqs per ack before the coordinator told its NP) in a few writes, not one per frame; a failed
// write counts every ack in it (the sensors keep their records and retransmit; the spooled ones
// are acked again).
TEST(Gateway, AcksOfALongReadGoOutInFewWritesAndAFailedWriteCountsEachAck) {
  publisher.connected = false;
  size_t writes = 0;
  radio.on_write = [&] { ++writes; };
  std::vector<uint8_t> bytes;
  for (uint32_t seq = 1; seq <= 120; seq += 2) {
    const auto frame = ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(seq), MakeRecord(seq + 1)});
    bytes.insert(bytes.end(), frame.begin(), frame.end());
  }
  Feed(bytes);
  LONGS_EQUAL(15, radio.acks.size());  // 120 seqs, 8 per ack
  LONGS_EQUAL(120, radio.AckedSeqs().size());
  LONGS_EQUAL(15, gateway->counters().acks_sent);
  CHECK_TEXT(writes >= 1 && writes <= 6, std::to_string(writes).c_str());
  radio.fail = true;
  std::vector<uint8_t> more;
  for (uint32_t seq = 121; seq <= 140; seq += 2) {
    const auto frame = ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(seq), MakeRecord(seq + 1)});
    more.insert(more.end(), frame.begin(), frame.end());
  }
  Feed(more);
  LONGS_EQUAL(3, gateway->counters().ack_write_errors);  // 20 seqs: 8 + 8 + 4
  LONGS_EQUAL(15, gateway->counters().acks_sent);
  LONGS_EQUAL(140, gateway->spool_depth());
}

// Commit acks that arrive together release their records in one spool transaction; each sensor
// then publishes its next record, and a sensor that got no ack is not republished early.
TEST(Gateway, CommitAcksHandledTogetherReleaseEverySensorsNextRecord) {
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1), MakeRecord(2)}));
  Feed(ReadingsFrame(kMode, kAddrB, 2002, {MakeRecord(10), MakeRecord(11)}));
  Feed(ReadingsFrame(kMode, kAddrB, 3003, {MakeRecord(5), MakeRecord(6)}));
  gateway->Pump(now);
  const std::string a = AckJson({1}), b = AckJson({10}), bad = "{oops";
  gateway->OnMessages({{Committed(1001), a}, {Committed(2002), b}, {Committed(3003), bad}}, now + 1);
  gateway->Pump(now + 1);
  CHECK(PublishedSeqs(1001) == (std::vector<uint32_t>{1, 2}));
  CHECK(PublishedSeqs(2002) == (std::vector<uint32_t>{10, 11}));
  CHECK(PublishedSeqs(3003) == (std::vector<uint32_t>{5}));
  LONGS_EQUAL(2, gateway->counters().committed);
  LONGS_EQUAL(1, gateway->counters().bad_commit_acks);
  LONGS_EQUAL(4, gateway->spool_depth());
  LONGS_EQUAL(3, gateway->in_flight());
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

using Messages = std::vector<std::vector<uint32_t>>;

// docs/mqtt.md, *Batches*: one record per message until a commit ack announces batches; then
// the sensor's next records (up to the announced number) go in one message, in seq order, and
// each is released only by an ack naming it.
TEST(Gateway, RecordsGoTogetherOnlyAfterTheServerAnnouncedBatches) {
  FeedSeqs(1, 8);
  gateway->Pump(now);
  CHECK(PublishedMessages(1001) == (Messages{{1}}));
  CHECK(json::parse(publisher.SentOn("sensors/1001/reading").back().payload).contains("seq"));  // the one-record form
  gateway->OnMessage(Committed(1001), BatchAckJson({1}, 3), now);
  gateway->Pump(now);
  CHECK(PublishedMessages(1001) == (Messages{{1}, {2, 3, 4}}));
  LONGS_EQUAL(3, gateway->batch_records());
  LONGS_EQUAL(3, gateway->in_flight());
  // Only the seqs named are released: 4 stays in flight, the next message starts after it.
  gateway->OnMessage(Committed(1001), BatchAckJson({2, 3}, 3), now);
  gateway->Pump(now);
  CHECK(PublishedMessages(1001) == (Messages{{1}, {2, 3, 4}, {5, 6}}));
  LONGS_EQUAL(5, gateway->spool_depth());  // 4, 5, 6, 7, 8
  gateway->OnMessage(Committed(1001), BatchAckJson({4, 5, 6}, 3), now);
  gateway->Pump(now);
  CHECK(PublishedMessages(1001) == (Messages{{1}, {2, 3, 4}, {5, 6}, {7, 8}}));
  LONGS_EQUAL(3, gateway->counters().batches_published);  // {2, 3, 4}, {5, 6}, {7, 8}
  gateway->OnMessage(Committed(1001), BatchAckJson({7, 8}, 3), now);
  gateway->Pump(now + 1'000);
  LONGS_EQUAL(0, gateway->spool_depth());
  LONGS_EQUAL(8, gateway->counters().committed);
  LONGS_EQUAL(8, gateway->counters().published);
}

TEST(Gateway, AReconnectOrAnAckWithoutTheAnnouncementGoesBackToOneRecordPerMessage) {
  FeedSeqs(1, 12);
  gateway->Pump(now);
  gateway->OnMessage(Committed(1001), BatchAckJson({1}, 64), now);
  gateway->Pump(now);
  CHECK(PublishedMessages(1001) == (Messages{{1}, {2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12}}));
  // The connection drops: whoever answers now may not know batches.
  publisher.connected = false;
  gateway->Pump(now + 1);
  publisher.connected = true;
  gateway->OnConnected(now + 2);
  LONGS_EQUAL(1, gateway->batch_records());
  CHECK(PublishedMessages(1001).back() == std::vector<uint32_t>{2});
  // Announced again, then an ack from a server that does not announce it: one record again.
  gateway->OnMessage(Committed(1001), BatchAckJson({2}, 4), now + 3);
  gateway->Pump(now + 3);
  CHECK(PublishedMessages(1001).back() == (std::vector<uint32_t>{3, 4, 5, 6}));
  gateway->OnMessage(Committed(1001), AckJson({3, 4, 5, 6}), now + 4);
  gateway->Pump(now + 4);
  LONGS_EQUAL(1, gateway->batch_records());
  CHECK(PublishedMessages(1001).back() == std::vector<uint32_t>{7});
}

// A batch without an ack (lost, or a server that cannot read it) is republished one record per
// message: an older server behind the broker takes and acks those.
TEST(Gateway, AnUnackedBatchIsRepublishedOneRecordPerMessage) {
  FeedSeqs(1, 3);
  gateway->Pump(now);
  gateway->OnMessage(Committed(1001), BatchAckJson({1}, 8), now);
  gateway->Pump(now);
  CHECK(PublishedMessages(1001) == (Messages{{1}, {2, 3}}));
  gateway->Pump(now + 10'000);  // the fixture's republish_after_ms
  CHECK(PublishedMessages(1001) == (Messages{{1}, {2, 3}, {2}, {3}}));
  LONGS_EQUAL(2, gateway->counters().republished);
  gateway->OnMessage(Committed(1001), AckJson({2, 3}), now + 10'001);
  LONGS_EQUAL(0, gateway->spool_depth());
}

// A server that stops announcing batches while batches are in flight (an older one took over
// behind the broker, or two servers answer in turn): the records beyond the one-record window are
// published again, never lost; every record ends committed and the spool empty.
TEST(Gateway, AServerThatStopsAnnouncingBatchesMidFlightLosesNoRecord) {
  FeedSeqs(1, 40);
  FeedSeqs(41, 41);
  size_t served = 0;
  // Plays the server: acks every seq of every reading message not served yet, announcing
  // batches or not as `announce` says.
  const auto serve = [&](bool announce, int64_t at) {
    const auto sent = publisher.SentOn("sensors/1001/reading");
    for (; served < sent.size(); ++served) {
      std::vector<std::string> records;
      std::string error;
      CHECK_TEXT(lw::mqtt::SplitReadingMessage(sent[served].payload, &records, &error), error.c_str());
      if (records.empty()) records.push_back(sent[served].payload);
      std::vector<uint32_t> seqs;
      for (const std::string& r : records) seqs.push_back(json::parse(r)["seq"].get<uint32_t>());
      gateway->OnMessage(Committed(1001), announce ? BatchAckJson(seqs, 64) : AckJson(seqs), at);
    }
  };
  gateway->Pump(now);
  serve(true, now);
  gateway->Pump(now);
  CHECK(PublishedMessages(1001).back().size() > 1);  // a batch in flight
  // Another sensor's ack from a server without the announcement arrives first.
  gateway->OnMessage(Committed(2002), AckJson({1}), now + 1);
  LONGS_EQUAL(1, gateway->batch_records());
  for (int round = 0; round < 200 && gateway->spool_depth() > 0; ++round) {
    now += 20'000;  // past republish_after_ms: whatever waits is published again
    gateway->Pump(now);
    serve(round % 3 == 0, now);
    gateway->Pump(now);
  }
  gateway->Pump(now + 1'000'000);
  LONGS_EQUAL(0, gateway->spool_depth());
  LONGS_EQUAL(41, gateway->counters().committed);
}

TEST(Gateway, MaxBatchBoundsTheRecordsPerMessageAndOneNeverBatches) {
  Start(1'000, 2, 1000, 2);  // window 2, at most 2 records per message
  FeedSeqs(1, 6);
  gateway->Pump(now);
  CHECK(PublishedMessages(1001) == (Messages{{1}, {2}}));
  gateway->OnMessage(Committed(1001), BatchAckJson({1, 2}, 64), now);
  gateway->Pump(now);
  CHECK(PublishedMessages(1001) == (Messages{{1}, {2}, {3, 4}, {5, 6}}));  // two messages in flight
  Start(1'000, 1, 1000, 1);
  publisher.sent.clear();
  gateway->OnConnected(now);
  gateway->OnMessage(Committed(1001), BatchAckJson({3}, 64), now);
  gateway->Pump(now);
  CHECK(PublishedMessages(1001) == (Messages{{3}, {4}}));
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
  const auto device = publisher.SentOn("gateway/devices/0013A20040A1B2C3");
  LONGS_EQUAL(2, device.size());  // when first seen, and again after the reconnect
  CHECK_TRUE(device[1].retained);
  CHECK(json::parse(device[1].payload)["sensors"] == json({"1001"}));
}

TEST(Gateway, SpoolSurvivesARestartAndIsReplayed) {
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1), MakeRecord(2)}));
  Start(1'000);  // a new process on the same spool file
  publisher.sent.clear();
  gateway->OnConnected(now);
  CHECK(PublishedSeqs(1001) == std::vector<uint32_t>{1});
  gateway->OnMessage(Committed(1001), AckJson({1}), now);
  gateway->Pump(now);
  gateway->OnMessage(Committed(1001), AckJson({2}), now);
  LONGS_EQUAL(0, gateway->spool_depth());
}

TEST(Gateway, RefusedPublicationIsRetried) {
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));
  publisher.refuse = true;
  gateway->Pump(now);
  LONGS_EQUAL(1, json::parse(gateway->StatsJson(now))["publish_refused"].get<int>());
  publisher.refuse = false;
  gateway->Pump(now + 1);
  CHECK(PublishedSeqs(1001) == std::vector<uint32_t>{1});
  LONGS_EQUAL(1, gateway->counters().publish_refused);
}

// A connection that carries nothing of QoS 1 (every publication refused, no commit ack) while
// records wait is reported after three republication periods, not before, and not while
// publications are taken (a server that is down: republications go out, no ack comes back).
TEST(Gateway, LinkThatCarriesNothingOfQos1IsReportedAfterThreeRepublicationPeriods) {
  const int64_t period = 10'000;  // the fixture's republish_after_ms
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));
  gateway->Pump(now);  // published, no ack comes back
  for (int64_t t = now; t <= now + 4 * period; t += 1000) {
    gateway->Pump(t);
    CHECK_FALSE_TEXT(gateway->LinkStalled(t), "republications are taken: the server may only be down");
  }
  const int64_t refused_from = now + 4 * period;
  publisher.refuse = true;
  // The last taken republication was less than a period before the refusals began.
  for (int64_t t = refused_from; t <= refused_from + 2 * period; t += 1000) {
    gateway->Pump(t);
    CHECK_FALSE(gateway->LinkStalled(t));
  }
  const int64_t stalled_at = refused_from + 3 * period + 1000;
  gateway->Pump(stalled_at);
  CHECK_TRUE(gateway->LinkStalled(stalled_at));
  gateway->OnLinkReset(stalled_at);
  CHECK_FALSE(gateway->LinkStalled(stalled_at + 1000));
  LONGS_EQUAL(1, gateway->counters().link_resets);
  publisher.refuse = false;
  gateway->OnConnected(stalled_at + 2000);
  gateway->OnMessage(Committed(1001), AckJson({1}), stalled_at + 2000);
  LONGS_EQUAL(0, gateway->spool_depth());
  CHECK_FALSE(gateway->LinkStalled(stalled_at + 10 * period));  // nothing waits
}

TEST(Gateway, FullSpoolRecordIsNeitherStoredNorAcked) {
  Start(1);
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(2)}));
  CHECK(radio.AckedSeqs() == std::vector<uint32_t>{1});
  LONGS_EQUAL(1, gateway->counters().records_rejected);
  LONGS_EQUAL(1, json::parse(gateway->StatsJson(now))["records_rejected"].get<int>());
}

// The spool fills in the middle of one read (one transaction): the records that fit are stored
// and acked, the rest of the same frame is not acked (the sensor keeps it), and a retransmission
// of a stored record later in the same read is still a duplicate, acked again.
TEST(Gateway, SpoolFullInTheMiddleOfOneReadAcksExactlyWhatWasStored) {
  Start(3);
  publisher.connected = false;
  std::vector<uint8_t> bytes = ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1), MakeRecord(2)});
  for (const auto& frame :
       {ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(3), MakeRecord(4)}), ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(2)}),
        ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(5)})}) {
    bytes.insert(bytes.end(), frame.begin(), frame.end());
  }
  Feed(bytes);
  LONGS_EQUAL(3, gateway->spool_depth());
  LONGS_EQUAL(1, radio.acks.size());  // {1, 2, 3}: the retransmitted 2 once; none for 4 and 5
  CHECK(radio.AckedSeqs() == (std::vector<uint32_t>{1, 2, 3}));
  LONGS_EQUAL(2, gateway->counters().records_rejected);  // 4 and 5
  LONGS_EQUAL(1, gateway->counters().records_duplicate);
  const auto heads = spool->Heads(10);
  LONGS_EQUAL(3, heads.size());
  LONGS_EQUAL(3, heads.back().seq);
}

TEST(Gateway, GarbageAndMalformedFramesAreCountedNotFatal) {
  Feed({0x7E, 0x00, 0x05, 0x90, 0x01, 0x02, 0x03, 0x04, 0x00});  // bad checksum
  Feed(gw::test::Wire(kMode, {0x90, 0x01, 0x02}));               // too short to parse
  Feed(gw::test::Wire(kMode, {0x42, 0x01}));                     // unknown type
  std::vector<uint8_t> bad_payload = ReadingsFrame(kMode, kAddrB, 1001, {MakeRecord(1)});
  const uint8_t bad_crc[] = {1, 0x01, 9, 9};  // a readings payload whose CRC does not match
  std::vector<uint8_t> wire(pr::kMaxWireFrame);
  wire.resize(
      pr::EncodeReceivePacket(kMode, {0x0013A20040FFEE01ull, 0x1234, 0x01, bad_crc, sizeof bad_crc}, wire.data(), wire.size()));
  Feed(wire);
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));  // still works afterwards
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
  const auto devices = publisher.SentOn("gateway/devices/0013A20040FFEE01");
  LONGS_EQUAL(1, devices.size());
  CHECK_TRUE(devices[0].retained);
  const json d = json::parse(devices[0].payload);
  STRCMP_EQUAL("0013A20040FFEE01", d["address"].get<std::string>().c_str());
  STRCMP_EQUAL("ROW1-S3", d["node_identifier"].get<std::string>().c_str());
}

// Found by fuzz/ (fuzz_gateway_serial; DeviceJson's own test covers the message): a node whose NI
// string is not UTF-8 (the radio sends any bytes) made the devices message throw in json::dump; it
// was counted as a spool error and the retained registry was never published again.
TEST(Gateway, NodeIdentifierThatIsNotUtf8StillPublishesTheRegistry) {
  FeedNodeIdentification("ROW1-\xfe\xff");
  gateway->Pump(now);
  LONGS_EQUAL(0, gateway->counters().spool_errors);
  const auto devices = publisher.SentOn("gateway/devices/0013A20040FFEE01");
  LONGS_EQUAL(1, devices.size());
  const json d = json::parse(devices[0].payload);
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

// The stats message, byte for byte as the gateway sent it before lw::mqtt encoded it (keys sorted).
TEST(Gateway, StatsMessageKeepsItsBytes) {
  const uint8_t junk[] = {1, 2, 3, 0x7E, 0x00};
  gateway->OnBytes(junk, sizeof junk, now);
  STRCMP_EQUAL(
      R"({"ack_write_errors":0,"acks_sent":0,"acks_too_large":0,"bad_commit_acks":0,"bad_payloads":0,"batch_records":1,"batches_published":0,)"
      R"("bytes_discarded":3,)"
      R"("checksum_errors":0,"commit_acks_ignored":0,"committed":0,"connects":0,"devices":0,"devices_refused":0,)"
      R"("escape_errors":0,"frames_ok":0,"gateway":"gw-test","in_flight":0,"length_errors":0,"link_resets":0,"malformed_frames":0,)"
      R"("max_devices":1000,"oversize_frames":0,"publish_latency_ms":{"last":-1,"max":-1,"mean":-1},"publish_refused":0,"published":0,"records_duplicate":0,)"
      R"("records_evicted":0,"records_received":0,"records_rejected":0,"records_spooled":0,"republished":0,"rf_payload_limit":44,)"
      R"("spool_depth":0,"spool_errors":0,"spool_max_records":1000,"time":"2026-03-01T12:00:07Z","truncated_frames":0,)"
      R"("tx_failures":0,"unknown_frames":0,"unknown_payloads":0,"unknown_types":0})",
      gateway->StatsJson(1772366407000).c_str());
}

TEST(Gateway, ApiModeOneIsDecodedAndAckedInModeOne) {
  lw::test::FakeRadio radio1{pr::ApiMode::kUnescaped};
  gw::Gateway& g = ModeOneGateway(radio1);
  const auto bytes = ReadingsFrame(pr::ApiMode::kUnescaped, 0x0013A2004011137Dull, 0x137D11, {MakeRecord(0x7E7D1113)});
  g.OnBytes(bytes.data(), bytes.size(), now);
  CHECK(radio1.AckedSeqs() == std::vector<uint32_t>{0x7E7D1113});
}

// The decoder fix seen from the gateway: a coordinator frame cut short in API mode 1 must not
// cost the readings frames that follow it (before the fix only the last of them reached the
// spool; the others were decoded, counted in frames_ok, and dropped).
TEST(Gateway, ReadingsAfterATruncatedFrameInModeOneAreAllSpooledAndAcked) {
  lw::test::FakeRadio radio1{pr::ApiMode::kUnescaped};
  gw::Gateway& g = ModeOneGateway(radio1);
  // A readings frame cut after its first 20 bytes: its declared length swallows the next two.
  auto cut = ReadingsFrame(pr::ApiMode::kUnescaped, kAddrA, 1001, {MakeRecord(1), MakeRecord(2), MakeRecord(3)});
  cut.resize(20);
  std::vector<uint8_t> bytes = cut;
  for (uint32_t seq : {10u, 11u}) {
    const auto f = ReadingsFrame(pr::ApiMode::kUnescaped, kAddrB, 2002, {MakeRecord(seq)});
    bytes.insert(bytes.end(), f.begin(), f.end());
  }
  const auto last = ReadingsFrame(pr::ApiMode::kUnescaped, kAddrB, 2002, {MakeRecord(12), MakeRecord(13)});
  bytes.insert(bytes.end(), last.begin(), last.end());
  g.OnBytes(bytes.data(), bytes.size(), now);
  CHECK(radio1.AckedSeqs() == (std::vector<uint32_t>{10, 11, 12, 13}));
  LONGS_EQUAL(4, spool->depth());
  LONGS_EQUAL(3, g.decoder_counters().frames_ok);
}

// Finding 1 of issue 15 through the gateway: a commit ack nested 100 000 deep is counted as bad
// and deletes nothing (it crashed the process before).
TEST(Gateway, DeeplyNestedCommitAckIsCountedAndDeletesNothing) {
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));
  gateway->Pump(now);
  const std::string deep = R"({"seqs": [1, )" + std::string(100000, '[') + std::string(100000, ']') + "]}";
  gateway->OnMessage(Committed(1001), deep, now);
  LONGS_EQUAL(1, gateway->counters().bad_commit_acks);
  LONGS_EQUAL(1, gateway->spool_depth());
  gateway->OnMessage(Committed(1001), AckJson({1}), now);
  LONGS_EQUAL(0, gateway->spool_depth());
}

// Finding 13/14 of issue 15: every new radio address republished the whole retained registry
// (300 announced nodes: about 4 MB in total). Now each address has its own small retained
// message and only the changed one goes out.
TEST(Gateway, EachNewRadioPublishesOnlyItsOwnSmallRegistryMessage) {
  size_t bytes = 0, messages = 0;
  for (uint64_t i = 0; i < 300; ++i) {
    Feed(NodeIdFrame(0x0013A20050000000ull + i, "FAKE-NODE-NAME-XYZ01"));
    gateway->Pump(now);
  }
  for (const auto& m : publisher.sent) {
    if (m.topic.find("/gateway/devices") == std::string::npos) continue;
    bytes += m.payload.size();
    ++messages;
  }
  LONGS_EQUAL(300, messages);
  CHECK(bytes < 300 * 300);  // each well under 300 bytes
}

TEST(Gateway, RegistryIsBoundedAndRefusalsAreCountedAndLogged) {
  Start(1'000, 1, 5);
  for (uint64_t i = 0; i < 300; ++i) Feed(NodeIdFrame(0x0013A20050000000ull + i, "N"));
  // A sensor that is not registered any more still has its readings spooled and acked.
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));
  gateway->Pump(now);
  LONGS_EQUAL(4, spool->Devices().size());  // 3 announced (at most half of 5), then the sensor
  LONGS_EQUAL(297, gateway->counters().devices_refused);
  LONGS_EQUAL(1, gateway->spool_depth());
  CHECK(radio.AckedSeqs() == std::vector<uint32_t>{1});
  const json stats = json::parse(gateway->StatsJson(now));
  LONGS_EQUAL(4, stats["devices"].get<int>());
  LONGS_EQUAL(297, stats["devices_refused"].get<int>());
  size_t full_lines = 0;
  for (const auto& line : log) full_lines += line.find("registry: full") != std::string::npos ? 1 : 0;
  LONGS_EQUAL(10, full_lines);  // rate limited: the first 10 (then every 1000th)
  // A known node may still update its identification.
  Feed(NodeIdFrame(0x0013A20050000000ull, "RENAMED"));
  gateway->Pump(now);
  const auto renamed = publisher.SentOn("gateway/devices/0013A20050000000");
  STRCMP_EQUAL("RENAMED", json::parse(renamed.back().payload)["node_identifier"].get<std::string>().c_str());
  // After a restart on the same spool the bound still holds (entries are counted from the file).
  Start(1'000, 1, 5);
  Feed(NodeIdFrame(0x0013A200600000FFull, "LATE"));
  LONGS_EQUAL(1, gateway->counters().devices_refused);
}

// Finding (issue 45, low): a radio announcing 1,000 made-up addresses filled the registry, and
// genuine new sensors were refused. Addresses known only from identification frames now take at
// most half of it.
TEST(Gateway, AnnouncedOnlyAddressesTakeAtMostHalfOfTheRegistry) {
  Start(1'000, 1, 10);
  for (uint64_t i = 0; i < 300; ++i) Feed(NodeIdFrame(0x0013A20050000000ull + i, "FAKE"));
  gateway->Pump(now);
  LONGS_EQUAL(5, spool->Devices().size());
  LONGS_EQUAL(295, gateway->counters().devices_refused);
  // New sensors are still registered, and an announced address that sends readings stops being
  // announced-only (its sensor entry joins it).
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));
  Feed(ReadingsFrame(kMode, kAddrB, 1002, {MakeRecord(1)}));
  Feed(ReadingsFrame(kMode, 0x0013A20050000000ull, 1003, {MakeRecord(1)}));
  gateway->Pump(now);
  LONGS_EQUAL(8, spool->Devices().size());
  LONGS_EQUAL(295, gateway->counters().devices_refused);
  Feed(NodeIdFrame(0x0013A20060000000ull, "ONE-MORE"));  // 4 announced-only now: room for one
  Feed(NodeIdFrame(0x0013A20060000001ull, "AND-ANOTHER"));
  gateway->Pump(now);
  LONGS_EQUAL(9, spool->Devices().size());
  LONGS_EQUAL(296, gateway->counters().devices_refused);
}

// Finding 11/12 of issue 15: a node identifier with ESC and a newline wrote raw terminal escapes
// and a forged second line into the log.
// The lines go to the program's log as main wires it (core::Logger), escaped once: a backslash
// shows as two, not four.
TEST(Gateway, TextFromTheRadioAndTheBrokerIsEscapedInTheLog) {
  Feed(NodeIdFrame(kAddrB, "A\x1B[2J\nFAKE: ok\\"));
  gateway->OnMessage("linerwatch/v1/s1/c1/sensors/1\n2\x1B/committed", "{oops", now);
  std::ostringstream out;
  lw::core::Logger logger(out, "linerwatch-gateway");
  for (const auto& line : log) logger(line);
  bool saw_node = false, saw_topic = false;
  std::istringstream lines(out.str());
  for (std::string line; std::getline(lines, line);) {
    for (char c : line) CHECK_FALSE(static_cast<unsigned char>(c) < 0x20 || c == 0x7F);
    saw_node |= line.find("A\\x1B[2J\\x0AFAKE: ok\\\\") != std::string::npos;
    CHECK_TEXT(line.find("\\\\\\\\") == std::string::npos, line.c_str());  // escaped twice
    saw_topic |= line.find("sensors/1\\x0A2\\x1B/committed") != std::string::npos;
  }
  CHECK_TRUE(saw_node);
  CHECK_TRUE(saw_topic);
}

// Finding 9 of issue 15, the gateway's part: an ack releases only records this gateway published
// and awaits. A forged ack naming the whole backlog (or records of another site's topic) deletes
// nothing that was never sent to the server.
TEST(Gateway, CommitAcksReleaseOnlyPublishedRecordsOfTheirOwnTopic) {
  std::vector<pr::SensorRecord> records;
  for (uint32_t seq = 1; seq <= 4; ++seq) records.push_back(MakeRecord(seq));
  Feed(ReadingsFrame(kMode, kAddrA, 1001, records));
  gateway->Pump(now);
  CHECK(PublishedSeqs(1001) == std::vector<uint32_t>{1});  // window 1: only seq 1 is out
  gateway->OnMessage(Committed(1001), AckJson({2, 3, 4, 99}), now);
  LONGS_EQUAL(4, gateway->spool_depth());
  LONGS_EQUAL(4, gateway->counters().commit_acks_ignored);
  gateway->OnMessage("linerwatch/v1/other-site/c1/sensors/1001/committed", AckJson({1}), now);
  gateway->OnMessage("linerwatch/v1/s1/other-crusher/sensors/1001/committed", AckJson({1}), now);
  gateway->OnMessage(Committed(2002), AckJson({1}), now);
  LONGS_EQUAL(4, gateway->spool_depth());
  gateway->OnMessage(Committed(1001), AckJson({1, 2}), now);  // the awaited one goes, 2 is not out yet
  LONGS_EQUAL(3, gateway->spool_depth());
  LONGS_EQUAL(1, gateway->counters().committed);
  gateway->Pump(now);
  CHECK(PublishedSeqs(1001) == (std::vector<uint32_t>{1, 2}));
  LONGS_EQUAL(6, json::parse(gateway->StatsJson(now))["commit_acks_ignored"].get<int>());
}

TEST(Gateway, RegistryMessagesRefusedByAFullClientBufferGoOutLaterOnceEach) {
  for (uint64_t i = 0; i < 5; ++i) Feed(NodeIdFrame(0x0013A20050000000ull + i, "N"));
  publisher.refuse = true;
  gateway->OnConnected(now);
  publisher.refuse = false;
  gateway->Pump(now + 1);
  gateway->Pump(now + 2);
  size_t messages = 0;
  for (const auto& m : publisher.sent) messages += m.topic.find("/gateway/devices/") != std::string::npos ? 1 : 0;
  LONGS_EQUAL(5, messages);
}

// Issue 16 (replay throughput): a commit ack releases its record at once (the sensor's next one
// goes out on the next Pump), while the deletions of many acks are made together, within
// release_delay_ms (default 200 ms): a hundred sensors' acks cost one spool transaction.
TEST(Gateway, CommittedRecordsAreDeletedTogetherWithinTheReleaseDelay) {
  const auto depth_on_disk = [&] { return gw::Spool(dir.File("spool.db"), 1000).depth(); };
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1), MakeRecord(2)}));
  Feed(ReadingsFrame(kMode, kAddrB, 2002, {MakeRecord(10), MakeRecord(11)}));
  gateway->Pump(now);
  gateway->OnMessage(Committed(1001), AckJson({1}), now + 1);
  gateway->OnMessage(Committed(2002), AckJson({10}), now + 2);
  gateway->Pump(now + 2);
  CHECK(PublishedSeqs(1001) == (std::vector<uint32_t>{1, 2}));
  CHECK(PublishedSeqs(2002) == (std::vector<uint32_t>{10, 11}));
  LONGS_EQUAL(2, gateway->spool_depth());  // waiting for a commit ack
  LONGS_EQUAL(2, gateway->counters().committed);
  LONGS_EQUAL(4, depth_on_disk());  // not deleted yet
  const int64_t delay = gw::GatewayOptions{}.release_delay_ms;
  gateway->Pump(now + delay);
  LONGS_EQUAL(4, depth_on_disk());
  gateway->Pump(now + 1 + delay);
  LONGS_EQUAL(2, depth_on_disk());  // both deleted, release_delay_ms after the first ack
  LONGS_EQUAL(2, gateway->spool_depth());
  // The released records are not read again: nothing is republished, the next acks go on.
  gateway->OnMessage(Committed(1001), AckJson({2}), now + 2 + delay);
  gateway->Pump(now + 2 + delay);
  CHECK(PublishedSeqs(1001) == (std::vector<uint32_t>{1, 2}));
  LONGS_EQUAL(1, gateway->spool_depth());
  LONGS_EQUAL(0, gateway->counters().republished);
}

// Records released by commit acks are deleted in the transaction of the next spooled batch: when
// the new record is acked on the radio, the released one is already gone from the file.
TEST(Gateway, ReleasedRecordsAreDeletedWithTheNextSpooledBatch) {
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));
  gateway->Pump(now);
  gateway->OnMessage(Committed(1001), AckJson({1}), now);
  std::vector<size_t> depth_seen_at_ack;
  radio.on_write = [&] { depth_seen_at_ack.push_back(gw::Spool(dir.File("spool.db"), 1000).depth()); };
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(2)}));
  CHECK(depth_seen_at_ack == std::vector<size_t>{1});  // seq 2 stored, seq 1 deleted
  LONGS_EQUAL(1, gateway->spool_depth());
  gateway->Pump(now + 1);
  CHECK(PublishedSeqs(1001) == (std::vector<uint32_t>{1, 2}));
}

// A full spool counts the released records as room: deleted before the new record is stored.
TEST(Gateway, ReleasedRecordsMakeRoomInAFullSpool) {
  Start(1);
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1)}));
  gateway->Pump(now);
  gateway->OnMessage(Committed(1001), AckJson({1}), now);
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(2)}));
  LONGS_EQUAL(0, gateway->counters().records_rejected);
  LONGS_EQUAL(2, gateway->counters().records_spooled);
  CHECK(radio.AckedSeqs() == (std::vector<uint32_t>{1, 2}));
}

// A gateway that stops deletes what commit acks released; one that restarts on the spool
// publishes only what waits for an ack.
TEST(Gateway, ReleasedRecordsAreDeletedWhenTheGatewayStops) {
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1), MakeRecord(2)}));
  gateway->Pump(now);
  gateway->OnMessage(Committed(1001), AckJson({1}), now);
  Start(1'000);  // the old Gateway is destroyed: a clean stop
  LONGS_EQUAL(1, spool->depth());
  publisher.sent.clear();
  gateway->OnConnected(now + 1);
  CHECK(PublishedSeqs(1001) == std::vector<uint32_t>{2});
}

// A reconnect while released records wait for their deletion replays only the unconfirmed ones,
// in order; with a window of several, a record acked out of order is not published again while
// the one before it is still awaited.
TEST(Gateway, ReleasedRecordsAreNeverPublishedAgain) {
  Start(1'000, 2);
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1), MakeRecord(2), MakeRecord(3), MakeRecord(4)}));
  gateway->Pump(now);
  CHECK(PublishedSeqs(1001) == (std::vector<uint32_t>{1, 2}));
  gateway->OnMessage(Committed(1001), AckJson({2}), now + 1);
  gateway->Pump(now + 1);
  CHECK(PublishedSeqs(1001) == (std::vector<uint32_t>{1, 2, 3}));
  LONGS_EQUAL(2, gateway->in_flight());
  gateway->OnConnected(now + 2);
  CHECK(PublishedSeqs(1001) == (std::vector<uint32_t>{1, 2, 3, 1, 3}));
  LONGS_EQUAL(3, gateway->spool_depth());
  LONGS_EQUAL(3, spool->depth());  // the reconnect read every head: the release was deleted first
}

// The radio as it is: the coordinator answers NP 84 (EE=0), 66 (EE=1) and 49 (APS security) and
// refuses an ack above the limit (a link without fragmentation loses it). Two sensors' backlogs
// arrive in one read; every record is spooled once and acked once, in one ack list per sensor cut
// into as few frames as the limit allows, none above it.
TEST(Gateway, AcksAreSizedToTheCoordinatorsPayloadLimitAndNothingIsLost) {
  for (const int np : {0x54, 0x42, 49}) {
    const int ee = np == 0x54 ? 0 : 1;
    const std::string what = "NP " + std::to_string(np);
    lw::test::FakeRadio coordinator{kMode};
    coordinator.np = np;
    coordinator.ee = ee;
    gw::Spool s(dir.File("np" + std::to_string(np) + ".db"), 10'000);
    gw::GatewayOptions o;
    o.site = "s1";
    o.crusher = "c1";
    o.api_mode = kMode;
    o.log = [](const std::string&) {};
    gw::Gateway g(o, s, publisher, coordinator);
    g.OnRadioOpened(now);
    const auto answers = coordinator.TakeAnswers();
    g.OnBytes(answers.data(), answers.size(), now);
    const size_t limit = pr::RfPayloadLimit(np, ee);
    LONGS_EQUAL_TEXT(limit, g.rf_payload_limit(), what.c_str());
    std::vector<uint8_t> bytes;
    for (uint32_t seq = 1; seq <= 60; seq += 2) {
      for (const auto& f : {ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(seq), MakeRecord(seq + 1)}),
                            ReadingsFrame(kMode, kAddrB, 2002, {MakeRecord(seq + 1000)})}) {
        bytes.insert(bytes.end(), f.begin(), f.end());
      }
    }
    const auto again = ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(7)});  // a retransmission in the same read
    bytes.insert(bytes.end(), again.begin(), again.end());
    g.OnBytes(bytes.data(), bytes.size(), now);
    LONGS_EQUAL_TEXT(0, coordinator.acks_too_large, what.c_str());
    CHECK_TEXT(coordinator.largest_ack_payload <= limit, what.c_str());
    LONGS_EQUAL_TEXT(90, g.spool_depth(), what.c_str());
    std::map<uint32_t, std::vector<uint32_t>> acked;  // sensor -> seqs, in ack order
    for (const auto& a : coordinator.acks) {
      CHECK_TEXT(a.dest64 == (a.ack.sensor_id == 1001 ? kAddrA : kAddrB), what.c_str());
      acked[a.ack.sensor_id].insert(acked[a.ack.sensor_id].end(), a.ack.seqs, a.ack.seqs + a.ack.count);
    }
    std::vector<uint32_t> expect_a, expect_b;
    for (uint32_t seq = 1; seq <= 60; ++seq) expect_a.push_back(seq);
    for (uint32_t seq = 1001; seq <= 1059; seq += 2) expect_b.push_back(seq);
    CHECK_TEXT(acked[1001] == expect_a, what.c_str());  // each once, the duplicate 7 too
    CHECK_TEXT(acked[2002] == expect_b, what.c_str());
    const size_t per_ack = pr::MaxAckSeqs(limit);
    LONGS_EQUAL_TEXT((60 + per_ack - 1) / per_ack + (30 + per_ack - 1) / per_ack, coordinator.acks.size(), what.c_str());
    LONGS_EQUAL_TEXT(limit, json::parse(g.StatsJson(now))["rf_payload_limit"].get<size_t>(), what.c_str());
  }
}

// Before the coordinator answers (or when it never does) acks are sized for the smallest NP
// linerwatch supports, and an unanswered query is logged once after 5 s.
TEST(Gateway, WithoutAnAnswerAcksAreSizedForTheSmallestPayload) {
  gateway->OnRadioOpened(now);
  LONGS_EQUAL(2, radio.at_queries);
  LONGS_EQUAL(pr::kMinRfPayload, gateway->rf_payload_limit());
  publisher.connected = false;
  std::vector<uint8_t> bytes;
  for (uint32_t seq = 1; seq <= 20; seq += 2) {
    const auto f = ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(seq), MakeRecord(seq + 1)});
    bytes.insert(bytes.end(), f.begin(), f.end());
  }
  Feed(bytes);
  CHECK(radio.largest_ack_payload <= pr::kMinRfPayload);
  LONGS_EQUAL(3, radio.acks.size());  // 8 + 8 + 4 seqs
  LONGS_EQUAL(20, radio.AckedSeqs().size());
  gateway->Pump(now + 4'000);
  const auto said = [&] {
    return std::count_if(log.begin(), log.end(),
                         [](const std::string& l) { return l.find("did not answer AT NP") != std::string::npos; });
  };
  LONGS_EQUAL(0, said());
  gateway->Pump(now + 5'000);
  gateway->Pump(now + 10'000);
  LONGS_EQUAL(1, said());
}

// A sensor whose frames are larger than the link carries (older firmware relying on
// fragmentation) is still stored and acked, and counted so that the site can find it.
TEST(Gateway, AReadingsFrameAboveTheLinksLimitIsStoredAndCounted) {
  radio.np = 49;
  radio.ee = 1;
  gateway->OnRadioOpened(now);
  Feed(radio.TakeAnswers());
  Feed(ReadingsFrame(kMode, kAddrA, 1001, {MakeRecord(1), MakeRecord(2), MakeRecord(3)}));  // 64 bytes
  LONGS_EQUAL(1, gateway->counters().oversize_frames);
  LONGS_EQUAL(3, gateway->spool_depth());
  LONGS_EQUAL(3, radio.AckedSeqs().size());
}
