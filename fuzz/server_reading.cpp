// The server's reading ingest (server/ingest.hpp): the MQTT topic, a newline, then the payload, as
// the MQTT loop hands them to the Ingestor (mqtt::Topics::ParseAny, ValidateReading, Ingest into SQLite)
// against the fixture crusher "fz1".
// Properties: ValidateReading and Ingest never throw; a message is stored, a duplicate, a conflict
// or rejected (exactly one); a message that named its sensor (the topic's) and seq under the crusher's
// own site is acknowledged with that seq (a rejected one too, once quarantined); the commit ack the server publishes for it
// parses in the gateway (mqtt::DecodeCommitAck) to the same sensor and seqs.
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "fuzz_fixture.hpp"
#include "mqtt/messages.hpp"
#include "mqtt/topics.hpp"
#include "server/ingest.hpp"
#include "server/store.hpp"

using namespace lw;
using lw::fuzz::Check;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static std::unique_ptr<server::Store> store;
  static std::unique_ptr<server::Ingestor> ingestor;
  static size_t runs = 0;
  if (!store || ++runs % 20000 == 0) {  // a fresh database now and then: memory stays bounded
    ingestor.reset();
    store.reset();
    store = std::make_unique<server::Store>(":memory:");
    ingestor = std::make_unique<server::Ingestor>(*store, fuzz::FixtureRegistry(), [] { return fuzz::kNowS; });
  }
  const std::string_view in(reinterpret_cast<const char*>(data), size);
  const size_t nl = in.find('\n');
  const std::string topic(in.substr(0, nl));
  const std::string payload(nl == std::string_view::npos ? std::string_view() : in.substr(nl + 1));
  const auto t = mqtt::Topics::ParseAny(topic);
  if (!t || t->kind != mqtt::TopicKind::kReading) return 0;
  const server::Incoming msg{t->site, t->crusher, t->id, topic, payload};
  const server::Validation v = server::ValidateReading(msg, fuzz::FixtureRegistry(), fuzz::kNowS);
  Check(v.reading.has_value() || !v.error.empty(), "a refused reading without a reason");

  // The crusher's site before this message (a first valid reading binds it): a message under
  // another site is quarantined and, by design, never acknowledged (docs/security.md).
  const std::optional<std::string> site_before = ingestor->SiteOf(t->crusher);
  const server::IngestResult r = ingestor->Ingest({msg});
  const std::optional<std::string> site_after = ingestor->SiteOf(t->crusher);
  const bool own_site = (site_before && *site_before == t->site) || (site_after && *site_after == t->site);
  Check(r.stored + r.duplicates + r.conflicts + r.rejected == 1, "one message was not counted exactly once");
  // ValidateReading knows no site binding: under a foreign site Ingest may reject a valid reading.
  if (own_site) Check(v.reading.has_value() == (r.rejected == 0), "Ingest and ValidateReading disagree on the message");
  if (v.sensor == t->id && v.seq && own_site) {
    Check(r.acks.size() == 1 && r.acks[0].sensor == v.sensor && r.acks[0].seqs == std::vector<int64_t>{*v.seq},
          "a message naming sensor " + v.sensor + " seq " + std::to_string(*v.seq) + " was not acknowledged");
  }
  for (const server::Ack& a : r.acks) {
    const std::string json = mqtt::EncodeCommitAck({a.sensor, {a.seqs.begin(), a.seqs.end()}, "2026-06-01T00:00:00Z"});
    std::string error;
    const auto back = mqtt::DecodeCommitAck(json, a.sensor, &error);
    Check(back.has_value(), "the gateway refuses the server's commit ack " + json + ": " + error);
    Check(back->seqs.size() == a.seqs.size(), "the gateway reads other seqs from " + json);
    for (size_t i = 0; i < a.seqs.size(); ++i) Check(back->seqs[i] == a.seqs[i], "the gateway reads other seqs from " + json);
  }
  return 0;
}
