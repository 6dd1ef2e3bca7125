// The gateway's commit-ack parser (mqtt::DecodeCommitAck, docs/mqtt.md). Input: the {sensor}
// level of the topic, a newline, then the payload.
// Properties: never throws; an accepted ack names a sensor (the topic's when the topic names one);
// the server's mqtt::EncodeCommitAcks of the same sensor, seqs and batch announcement parse back to the same ack (UTF-8
// sensors), each within the gateway's limits.
#include <nlohmann/json.hpp>

#include <string>
#include <vector>
#include <string_view>

#include "fuzz_support.hpp"
#include "mqtt/messages.hpp"

using namespace lw;
using lw::fuzz::Check;

namespace {

bool IsUtf8(const std::string& s) {
  try {
    (void)nlohmann::json(s).dump();
    return true;
  } catch (const nlohmann::json::type_error&) {
    return false;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view in(reinterpret_cast<const char*>(data), size);
  const size_t nl = in.find('\n');
  const std::string topic_sensor(nl == std::string_view::npos ? std::string_view() : in.substr(0, nl));
  const std::string_view payload = nl == std::string_view::npos ? in : in.substr(nl + 1);
  std::string error;
  const auto ack = mqtt::DecodeCommitAck(payload, topic_sensor, &error);
  if (!ack) {
    Check(!error.empty(), "a refused commit ack without a reason");
    return 0;
  }
  Check(!ack->sensor.empty(), "an accepted commit ack without a sensor");
  Check(topic_sensor.empty() || ack->sensor == topic_sensor, "an accepted commit ack for another sensor than the topic's");
  // The server acks only sensors of UTF-8 topics (MQTT topics are UTF-8): round-trip those.
  if (!IsUtf8(ack->sensor)) return 0;
  const mqtt::CommitAck again{ack->sensor, ack->seqs, "2026-06-01T00:00:00Z", ack->batch};
  // The server sends its ack as messages the gateway accepts (each within kMaxCommitAckBytes and
  // kMaxCommitAckSeqs); together they hold the same seqs. None only when the sensor name alone is
  // too long for one message (found by this target: a 20 KB topic level of control characters,
  // escaped six-fold, made the one commit ack 65,559 bytes, which the gateway refused).
  const auto messages = mqtt::EncodeCommitAcks(again);
  if (messages.empty()) {
    const mqtt::CommitAck bare{ack->sensor, {4294967295u}, "2026-06-01T00:00:00Z", ack->batch};
    Check(mqtt::EncodeCommitAck(bare).size() > mqtt::kMaxCommitAckBytes,
          "no commit ack message although the sensor name fits one");
    return 0;
  }
  std::vector<uint32_t> seqs;
  for (const std::string& json : messages) {
    std::string error2;
    const auto back = mqtt::DecodeCommitAck(json, ack->sensor, &error2);
    Check(back.has_value(), "the server's commit ack " + json.substr(0, 200) + " is refused by the gateway: " + error2);
    Check(back->sensor == ack->sensor, "the server's commit ack names another sensor: " + json.substr(0, 200));
    Check(back->batch == ack->batch, "the server's commit ack announces another batch size: " + json.substr(0, 200));
    seqs.insert(seqs.end(), back->seqs.begin(), back->seqs.end());
  }
  Check(seqs == ack->seqs, "the server's commit ack messages hold other seqs than the ack");
  return 0;
}
