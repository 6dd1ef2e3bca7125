// linerwatch-gateway end to end without I/O: arbitrary bytes from the coordinator's serial port
// (first byte: bit 0 the API mode, 1 = 1, 0 = 2; bit 1 the server announces batches) into
// gateway::Gateway with an in-memory spool, then the server's side of the conversation: every
// published reading (each record of a batch, split by mqtt::SplitReadingMessage) is validated by
// the server's ValidateReading and acknowledged with the server's commit ack
// (mqtt::EncodeCommitAck, announcing 64 records per message or not) until nothing is left.
// Properties: every message the gateway publishes (reading, status, devices, stats) is JSON; a
// reading it builds is never refused by the server as malformed or unidentifiable; each ack it
// writes to the radio decodes with the firmware's protocol library; no spool error; once every
// reading is acknowledged the spool is empty and nothing is in flight.
#include <nlohmann/json.hpp>

#include <string>

#include "fuzz_fixture.hpp"
#include "gateway/gateway.hpp"
#include "gateway/spool.hpp"
#include "mqtt/messages.hpp"
#include "mqtt/topics.hpp"
#include "server/ingest.hpp"
#include "unit/gateway/gateway_test_support.hpp"

using namespace lw;
using lw::fuzz::Check;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const protocol::ApiMode mode = (data[0] & 1) ? protocol::ApiMode::kUnescaped : protocol::ApiMode::kEscaped;
  const uint32_t announce = (data[0] & 2) ? static_cast<uint32_t>(mqtt::kMaxReadingBatch) : 0;
  gateway::Spool spool(":memory:", 1000);
  lw::test::FakePublisher publisher;
  lw::test::FakeRadio radio(mode);
  gateway::GatewayOptions options;
  options.site = "site1";
  options.crusher = "fz1";
  options.gateway_id = "gw-fuzz";
  options.api_mode = mode;
  options.log = [](const std::string&) {};
  gateway::Gateway gw(options, spool, publisher, radio);
  int64_t now_ms = fuzz::kNowS * 1000;
  gw.OnConnected(now_ms);
  gw.OnBytes(data + 1, size - 1, now_ms);
  Check(radio.other_frames == 0, "the gateway wrote a frame to the radio that is not an ack");

  const server::Registry& registry = fuzz::FixtureRegistry();
  size_t checked = 0;
  for (int round = 0; round < 100000; ++round) {
    gw.Pump(now_ms);
    std::vector<mqtt::OutMessage> sent;
    sent.swap(publisher.sent);
    size_t readings = 0;
    for (const mqtt::OutMessage& m : sent) {
      Check(nlohmann::json::accept(m.payload), "published on " + m.topic + " is not JSON: " + m.payload);
      const auto topic = mqtt::Topics::ParseAny(m.topic);
      if (!topic || topic->kind != mqtt::TopicKind::kReading) continue;
      ++readings;
      std::vector<std::string> records;
      std::string error;
      Check(mqtt::SplitReadingMessage(m.payload, &records, &error), "the server refuses the gateway's batch: " + error);
      Check(announce != 0 || records.empty(), "a batch published to a server that did not announce batches");
      Check(records.size() <= mqtt::kMaxReadingBatch && m.payload.size() <= mqtt::kMaxReadingBytes, "a batch over the limits");
      if (records.empty()) records.push_back(m.payload);
      mqtt::CommitAck ack{topic->id, {}, "2026-06-01T00:00:00Z", announce};
      for (const std::string& r : records) {
        const server::Validation v =
            server::ValidateReading({topic->site, topic->crusher, topic->id, m.topic, r}, registry, fuzz::kNowS);
        Check(!v.sensor.empty() && v.seq.has_value(), "the server cannot identify a reading the gateway built: " + v.error);
        ack.seqs.push_back(static_cast<uint32_t>(*v.seq));
      }
      gw.OnMessage(gw.topics().Committed(topic->id), mqtt::EncodeCommitAck(ack), now_ms);
      ++checked;
    }
    if (readings == 0) break;
    now_ms += 10;
  }
  Check(gw.counters().bad_commit_acks == 0, "the gateway refused the server's commit ack");
  Check(gw.counters().spool_errors == 0, "spool error on an in-memory spool (see the gateway log)");
  Check(gw.spool_depth() == 0 && gw.in_flight() == 0, "records left after every published reading was acknowledged: spool " +
                                                          std::to_string(gw.spool_depth()) + ", in flight " +
                                                          std::to_string(gw.in_flight()));
  (void)checked;
  return 0;
}
