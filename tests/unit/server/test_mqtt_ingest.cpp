// The MQTT loop's units apart from a broker: commit ack messages (topic, seqs, time), the log line
// of an ignored topic, and the loop itself on a scripted link (what it hands to the ingestor and
// its hooks, and what it sends back).
#include <atomic>
#include <deque>
#include <sstream>
#include <string>
#include <vector>

#include "core/log.hpp"
#include "mqtt/messages.hpp"
#include "mqtt/topics.hpp"
#include "server/ingest.hpp"
#include "server/metrics.hpp"
#include "server/mqtt_ingest.hpp"
#include "server/registry.hpp"
#include "server/store.hpp"
#include "support/temp_directory.hpp"

#include <CppUTest/TestHarness.h>  // last: its leak-detection macros clash with std headers

using namespace lw::server;
using lw::mqtt::LinkEvent;
using lw::mqtt::OutMessage;

namespace {

/// A link whose Poll() hands out one scripted turn of events each call; after the last turn it
/// sets `*stop`, so the loop ends on its own. Publishes are kept.
class ScriptedLink : public lw::mqtt::Link {
 public:
  ScriptedLink(std::deque<std::vector<LinkEvent>> turns, std::atomic<bool>* stop) : turns_(std::move(turns)), stop_(stop) {}
  std::vector<OutMessage> sent;

  std::vector<LinkEvent> Poll(int64_t) override {
    if (turns_.empty()) {
      *stop_ = true;
      return {};
    }
    std::vector<LinkEvent> turn = std::move(turns_.front());
    turns_.pop_front();
    return turn;
  }
  void Reconnect(const std::string&) override {}
  int wake_fd() const override { return -1; }
  void Shutdown(const OutMessage&, int) override {}

 private:
  bool DoPublish(const OutMessage& m) override {
    sent.push_back(m);
    return true;
  }
  bool DoIsConnected() const override { return true; }

  std::deque<std::vector<LinkEvent>> turns_;
  std::atomic<bool>* stop_;
};

LinkEvent Message(std::string topic, std::string payload) {
  return {LinkEvent::Kind::kMessage, std::move(topic), std::move(payload)};
}

}  // namespace

TEST_GROUP(MqttIngest){};

TEST(MqttIngest, CommitAcksGoToEachSensorsCommittedTopicWithItsSeqsAndTheTime) {
  const std::vector<Ack> acks = {{"north", "c1", "s-1", {3, 4, 9}}, {"north", "c1", "s-2", {7}}};
  const std::vector<OutMessage> out = CommitAckMessages(acks, "lw", 1'700'000'000);
  LONGS_EQUAL(2, out.size());
  STRCMP_EQUAL(lw::mqtt::Topics("north", "c1", "lw").Committed("s-1").c_str(), out[0].topic.c_str());
  STRCMP_EQUAL(lw::mqtt::Topics("north", "c1", "lw").Committed("s-2").c_str(), out[1].topic.c_str());
  LONGS_EQUAL(1, out[0].qos);
  CHECK_FALSE(out[0].retained);
  std::string error;
  const auto first = lw::mqtt::DecodeCommitAck(out[0].payload, "s-1", &error);
  CHECK_TEXT(first.has_value(), error.c_str());
  CHECK((std::vector<uint32_t>{3, 4, 9}) == first->seqs);
  STRCMP_EQUAL("2023-11-14T22:13:20Z", first->time.c_str());
  const auto second = lw::mqtt::DecodeCommitAck(out[1].payload, "s-2", &error);
  CHECK_TEXT(second.has_value(), error.c_str());
  CHECK((std::vector<uint32_t>{7}) == second->seqs);
}

TEST(MqttIngest, NoAcksNoMessages) {
  CHECK(CommitAckMessages({}, "lw", 0).empty());
}

TEST(MqttIngest, AnIgnoredTopicIsNamedAndALongOneCutAtACharactersStart) {
  const std::string line = IgnoredTopicLine("lw/x/y", 12, "lw/+/+/sensors/+/reading");
  STRCMP_EQUAL(
      "broker: message on 'lw/x/y' ignored (12 bytes): not a reading topic; the server subscribes to lw/+/+/sensors/+/reading "
      "only",
      line.c_str());
  // 199 ASCII bytes, then a two-byte character across byte 200: cut before it.
  const std::string long_topic = std::string(199, 'a') + "\xC3\xA9" + std::string(50, 'b');
  const std::string cut = IgnoredTopicLine(long_topic, 0, "f");
  CHECK(cut.find("'" + std::string(199, 'a') + "... (251 bytes)'") != std::string::npos);
}

TEST(MqttIngest, TheLoopHandsReadingsToTheIngestorStatusToItsHookAndLogsTheRest) {
  lw::test::TempDirectory dir("mqtt_ingest");
  std::vector<std::string> errors;
  const auto registry = Registry::Load(dir.path(), &errors);  // no crusher: every reading is held
  Store store(":memory:");
  Ingestor ingestor(store, *registry, [] { return int64_t{1'700'000'000}; });
  ServerMetrics metrics(":memory:");
  std::ostringstream log_text;
  lw::core::Logger log(log_text, "test");

  lw::mqtt::ReadingMessage reading;
  reading.sensor = "s-1";
  reading.seq = 5;
  reading.time = "2023-11-14T22:00:00Z";
  reading.thickness_mm = 80;
  reading.battery_mv = 3000;
  const lw::mqtt::Topics topics("north", "c9", "lw");
  std::atomic<bool> stop{false};
  ScriptedLink link(
      {{LinkEvent{LinkEvent::Kind::kConnected, "", ""}, Message(topics.Reading("s-1"), lw::mqtt::EncodeReading(reading)),
        Message(topics.Status(), "{}"), Message("lw/elsewhere", "x")}},
      &stop);
  std::vector<std::string> statuses;
  std::vector<IngestResult> committed;
  int publish_turns = 0;
  MqttIngestLoop::Hooks hooks;
  hooks.status = [&](const lw::mqtt::ParsedTopic& t, const std::string&) {
    statuses.push_back(t.crusher);
    return true;
  };
  hooks.committed = [&](const IngestResult& r) { committed.push_back(r); };
  hooks.publish = [&](lw::mqtt::Publisher&) { ++publish_turns; };
  MqttIngestLoop loop(
      {"tcp://broker", "server", "lw", 1000, 0}, link, ingestor, metrics, log, [] { return int64_t{1'700'000'000}; },
      std::move(hooks));
  loop.Run(stop);

  CHECK(metrics.broker_connected());
  CHECK((std::vector<std::string>{"c9"}) == statuses);
  LONGS_EQUAL(1, committed.size());
  LONGS_EQUAL(1, committed[0].held);  // an unknown crusher's reading waits: neither stored nor acked
  LONGS_EQUAL(0, committed[0].stored);
  CHECK(link.sent.empty());
  CHECK(publish_turns >= 1);
  CHECK(log_text.str().find("connected to tcp://broker as server") != std::string::npos);
  CHECK(log_text.str().find("message on 'lw/elsewhere' ignored") != std::string::npos);
}
