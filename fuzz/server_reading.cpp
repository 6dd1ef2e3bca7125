// The server's reading ingest (server/ingest.hpp): the MQTT topic, a newline, then the payload, as
// the MQTT loop hands them to the Ingestor (mqtt::Topics::ParseAny, ValidateReading, Ingest into SQLite)
// against the fixture crusher "fz1".
// Properties: ValidateReading and Ingest never throw; a message is stored, a duplicate, a conflict,
// rejected or held (exactly one); a held one (ValidateReading's verdict) is never acknowledged; a message that named its sensor
// (the topic's) and seq under the crusher's own site is acknowledged with that seq (a rejected one too, once quarantined); the
// commit ack the server publishes for it parses in the gateway (mqtt::DecodeCommitAck) to the same sensor and seqs. A batch
// (several records in one message, docs/mqtt.md *Batches*) counts as its records, each judged as if it had come alone; a
// malformed batch is one rejected message and acknowledged by no seq.
#include <memory>
#include <set>
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
  // What the message holds: its records (a batch) or itself.
  std::vector<std::string> records;
  std::string batch_error;
  const bool batch_ok = mqtt::SplitReadingMessage(payload, &records, &batch_error);
  Check(batch_ok || !batch_error.empty(), "a refused batch without a reason");
  if (records.empty()) records.push_back(payload);
  size_t valid = 0;
  std::set<int64_t> to_ack;  // the seqs of records that named the topic's sensor and are not held
  std::set<int64_t> held;    // held records' seqs: never acknowledged (their gateway publishes them again)
  for (const std::string& record : records) {
    const server::Validation v =
        server::ValidateReading({t->site, t->crusher, t->id, topic, record}, fuzz::FixtureRegistry(), fuzz::kNowS);
    Check(v.reading.has_value() || !v.error.empty(), "a refused reading without a reason");
    Check(!v.held || !v.reading, "a held reading is also valid");
    if (batch_ok && v.reading) ++valid;
    if (batch_ok && v.sensor == t->id && v.seq) (v.held ? held : to_ack).insert(*v.seq);
  }
  for (const int64_t s : to_ack) held.erase(s);  // a seq also valid in the batch: acked for that record

  // The crusher's site before this message (a first valid reading binds it): a message under
  // another site is quarantined and, by design, never acknowledged (docs/security.md).
  const std::optional<std::string> site_before = ingestor->SiteOf(t->crusher);
  const server::IngestResult r = ingestor->Ingest({msg});
  const std::optional<std::string> site_after = ingestor->SiteOf(t->crusher);
  const bool own_site = (site_before && *site_before == t->site) || (site_after && *site_after == t->site);
  Check(r.stored + r.duplicates + r.conflicts + r.rejected + r.held == records.size(), "a record was not counted exactly once");
  if (!batch_ok) Check(r.rejected == 1 && r.acks.empty(), "a malformed batch was not rejected whole, or was acknowledged");
  // ValidateReading knows no site binding: under a foreign site Ingest may reject a valid reading.
  if (own_site) Check(valid == r.stored + r.duplicates + r.conflicts, "Ingest and ValidateReading disagree on the message");
  if (own_site && !to_ack.empty()) {
    Check(
        r.acks.size() == 1 && r.acks[0].sensor == t->id &&
            std::set<int64_t>(r.acks[0].seqs.begin(), r.acks[0].seqs.end()) == to_ack,
        "a message naming sensor " + t->id + " and " + std::to_string(to_ack.size()) + " seq(s) was not acknowledged with them");
  }
  for (const server::Ack& a : r.acks) {
    for (const int64_t s : a.seqs) Check(!held.count(s), "a held reading was acknowledged");
    const std::string json = mqtt::EncodeCommitAck({a.sensor, {a.seqs.begin(), a.seqs.end()}, "2026-06-01T00:00:00Z"});
    std::string error;
    const auto back = mqtt::DecodeCommitAck(json, a.sensor, &error);
    Check(back.has_value(), "the gateway refuses the server's commit ack " + json + ": " + error);
    Check(back->seqs.size() == a.seqs.size(), "the gateway reads other seqs from " + json);
    for (size_t i = 0; i < a.seqs.size(); ++i) Check(back->seqs[i] == a.seqs[i], "the gateway reads other seqs from " + json);
  }
  return 0;
}
