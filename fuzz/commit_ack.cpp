// The gateway's commit-ack parser (gateway::ParseCommitAck, docs/mqtt.md). Input: the {sensor}
// level of the topic, a newline, then the payload.
// Properties: never throws; an accepted ack names a sensor (the topic's when the topic names one);
// the server's CommitAckJson of the same sensor and seqs parses back to the same ack (UTF-8 sensors).
#include <nlohmann/json.hpp>

#include <string>
#include <string_view>

#include "fuzz_support.hpp"
#include "gateway/messages.hpp"
#include "server/ingest.hpp"

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
  const auto ack = gateway::ParseCommitAck(payload, topic_sensor, &error);
  if (!ack) {
    Check(!error.empty(), "a refused commit ack without a reason");
    return 0;
  }
  Check(!ack->sensor.empty(), "an accepted commit ack without a sensor");
  Check(topic_sensor.empty() || ack->sensor == topic_sensor, "an accepted commit ack for another sensor than the topic's");
  // The server acks only sensors of UTF-8 topics (MQTT topics are UTF-8): round-trip those.
  if (!IsUtf8(ack->sensor)) return 0;
  server::Ack again{"site1", "fz1", ack->sensor, {}};
  for (uint32_t s : ack->seqs) again.seqs.push_back(s);
  const std::string json = server::CommitAckJson(again, "2026-06-01T00:00:00Z");
  std::string error2;
  const auto back = gateway::ParseCommitAck(json, ack->sensor, &error2);
  Check(back.has_value(), "the server's commit ack " + json + " is refused by the gateway: " + error2);
  Check(back->sensor == ack->sensor && back->seqs == ack->seqs, "the server's commit ack parses to another ack: " + json);
  return 0;
}
