#include "server/mqtt_ingest.hpp"

#include <poll.h>

#include <algorithm>
#include <chrono>
#include <iterator>
#include <thread>

#include "core/clock.hpp"
#include "core/time.hpp"
#include "mqtt/messages.hpp"

namespace lw::server {
namespace {

int64_t WallMs() {
  return core::WallClockMs();
}

// Messages on topics that are not readings are logged at most kIgnoredLogged lines a minute; the
// rest are counted in the minute's stats line.
constexpr int kIgnoredLogged = 10;

}  // namespace

std::vector<mqtt::OutMessage> CommitAckMessages(const std::vector<Ack>& acks, const std::string& topic_root, int64_t now_s) {
  const std::string when = core::FormatIsoSeconds(now_s);
  std::vector<mqtt::OutMessage> out;
  for (const Ack& a : acks) {
    const std::string topic = mqtt::Topics(a.site, a.crusher, topic_root).Committed(a.sensor);
    // Seqs are validated to 0..2^32-1 before they are stored or acked.
    for (std::string& m : mqtt::EncodeCommitAcks({a.sensor, {a.seqs.begin(), a.seqs.end()}, when, mqtt::kMaxReadingBatch})) {
      out.push_back({topic, std::move(m), 1, false});
    }
  }
  return out;
}

std::string IgnoredTopicLine(const std::string& topic, size_t payload_bytes, const std::string& readings_filter) {
  // Topics are UTF-8 without control characters (the link refuses others).
  std::string shown = topic;
  if (shown.size() > 200) {
    size_t cut = 200;
    while (cut > 0 && (static_cast<unsigned char>(shown[cut]) & 0xC0) == 0x80) --cut;
    shown = shown.substr(0, cut) + "... (" + std::to_string(topic.size()) + " bytes)";
  }
  return "broker: message on '" + shown + "' ignored (" + std::to_string(payload_bytes) +
         " bytes): not a reading topic; the server subscribes to " + readings_filter + " only";
}

MqttIngestLoop::MqttIngestLoop(MqttIngestOptions options, mqtt::Link& link, Ingestor& ingestor, ServerMetrics& metrics,
                               core::Logger& log, std::function<int64_t()> now_s, Hooks hooks)
    : o_(std::move(options)),
      link_(link),
      ingestor_(ingestor),
      metrics_(metrics),
      log_(log),
      now_s_(std::move(now_s)),
      hooks_(std::move(hooks)),
      readings_filter_(mqtt::Topics::ReadingsFilter(o_.topic_root)),
      last_stats_ms_(WallMs()) {}

void MqttIngestLoop::Collect(int64_t now_ms, std::vector<Incoming>* batch) {
  std::vector<mqtt::LinkEvent> polled = link_.Poll(now_ms);
  if (batch->capacity() < batch->size() + polled.size()) batch->reserve(2 * (batch->size() + polled.size()));
  for (mqtt::LinkEvent& e : polled) {
    if (e.kind == mqtt::LinkEvent::Kind::kConnected) {
      metrics_.SetBrokerConnected(true);
      log_("connected to " + o_.broker + " as " + o_.client_id);
    } else if (e.kind == mqtt::LinkEvent::Kind::kDisconnected) {
      metrics_.SetBrokerConnected(false);
      log_("broker: " + e.payload);
    } else if (auto t = mqtt::Topics::ParseAny(e.topic, o_.topic_root); t && t->kind == mqtt::TopicKind::kReading) {
      batch->push_back({std::move(t->site), std::move(t->crusher), std::move(t->id), std::move(e.topic), std::move(e.payload)});
    } else if (t && t->kind == mqtt::TopicKind::kStatus && hooks_.status && hooks_.status(*t, e.payload)) {
      // taken by the status hook (the alarms)
    } else if (ignored_logged_ < kIgnoredLogged) {
      ++ignored_logged_;
      log_(IgnoredTopicLine(e.topic, e.payload.size(), readings_filter_));
    } else {
      ++ignored_unlogged_;
    }
  }
}

void MqttIngestLoop::CommitAndAck(std::vector<Incoming>* batch) {
  const size_t max = static_cast<size_t>(o_.batch_max);
  for (size_t start = 0; start < batch->size(); start += max) {
    const size_t end = std::min(batch->size(), start + max);
    std::vector<Incoming> part(std::make_move_iterator(batch->begin() + static_cast<std::ptrdiff_t>(start)),
                               std::make_move_iterator(batch->begin() + static_cast<std::ptrdiff_t>(end)));
    IngestResult r;
    try {
      r = ingestor_.Ingest(std::move(part));
    } catch (const std::exception& e) {
      // Nothing of the batch is stored and nothing is acked: the gateway republishes it.
      log_(std::string("database error, batch not stored (the gateway will resend it): ") + e.what());
      continue;
    }
    for (const Ack& a : r.acks) metrics_.CountAcked(a.seqs.size());
    for (mqtt::OutMessage& m : CommitAckMessages(r.acks, o_.topic_root, now_s_())) acks_.Send(link_, std::move(m));
    if (hooks_.committed) hooks_.committed(r);
  }
}

void MqttIngestLoop::LogStats(int64_t now_ms) {
  if (now_ms - last_stats_ms_ < 60'000) return;
  const IngestCounters c = ingestor_.Counters();
  if (c.stored != last_counters_.stored || c.rejected != last_counters_.rejected || c.duplicates != last_counters_.duplicates) {
    log_("stored " + std::to_string(c.stored) + ", duplicates " + std::to_string(c.duplicates) + ", rejected " +
         std::to_string(c.rejected) + " since start");
  }
  last_counters_ = c;
  last_stats_ms_ = now_ms;
  if (ignored_unlogged_ > 0) {
    log_("broker: " + std::to_string(ignored_unlogged_) + " more messages on topics that are not readings ignored");
  }
  ignored_logged_ = 0;
  ignored_unlogged_ = 0;
}

void MqttIngestLoop::Run(const std::atomic<bool>& stop) {
  // Kept from turn to turn with its room: grown from empty at each turn, it moved every message it
  // held (five strings each) at each doubling (3 % of the server's CPU at 7,000 messages a second).
  std::vector<Incoming> batch;
  while (!stop) {
    const int64_t now = WallMs();
    acks_.Flush(link_);
    metrics_.SetAcksDropped(acks_.dropped());
    if (acks_.dropped() != acks_dropped_logged_) {
      log_("commit acks waiting for the broker beyond " + std::to_string(acks_.size()) + ": dropped the oldest " +
           std::to_string(acks_.dropped() - acks_dropped_logged_) + " (their gateways republish those records)");
      acks_dropped_logged_ = acks_.dropped();
    }
    batch.clear();
    Collect(now, &batch);
    // Group commit: one fsync'ed transaction per batch, so when readings are arriving give the
    // next ones commit_delay_ms to join this one instead of committing them one by one. The whole
    // delay, not until the next message: woken at each arrival, committing then made transactions
    // of ~70 readings at 7,000 a second, and SQLite rewrote each touched page to the WAL every few.
    // Checked every millisecond (a full batch commits at once), not at every arrival: a wake-up
    // per message cost the main loop a poll and a context switch each.
    if (!batch.empty() && o_.commit_delay_ms > 0) {
      using Steady = std::chrono::steady_clock;  // a wall-clock step must not stretch the wait
      const Steady::time_point deadline = Steady::now() + std::chrono::milliseconds(o_.commit_delay_ms);
      while (batch.size() < static_cast<size_t>(o_.batch_max)) {
        const Steady::time_point now_steady = Steady::now();
        if (now_steady >= deadline) break;
        std::this_thread::sleep_for(std::min<Steady::duration>(deadline - now_steady, std::chrono::milliseconds(1)));
        Collect(WallMs(), &batch);
      }
    }
    CommitAndAck(&batch);
    if (hooks_.publish) hooks_.publish(link_);
    LogStats(now);
    pollfd pfd{link_.wake_fd(), POLLIN, 0};
    ::poll(&pfd, 1, 20);
  }
}

}  // namespace lw::server
