#pragma once
/// The server's MQTT loop (docs/performance.md, *Ingest*): drains the link, keeps reading messages
/// and drops (and logs) the rest, commits readings in groups (one fsync'ed transaction per batch),
/// sends each batch's commit acks to its gateway and, every turn, what the caller publishes (the
/// wear worker's retained wear and alarms). Runs on the thread that owns the link.
#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "core/log.hpp"
#include "mqtt/link.hpp"
#include "mqtt/outbox.hpp"
#include "mqtt/topics.hpp"
#include "server/ingest.hpp"
#include "server/metrics.hpp"

namespace lw::server {

/// The commit ack messages of `acks` (Ingestor's, one per site, crusher and sensor): on each
/// sensor's `.../committed` topic, QoS 1, not retained, as many as mqtt::EncodeCommitAcks needs
/// for its seqs; `now_s` is their time.
std::vector<mqtt::OutMessage> CommitAckMessages(const std::vector<Ack>& acks, const std::string& topic_root, int64_t now_s);

/// The log line of a message on `topic`, which is not a reading topic (the server subscribes to
/// `readings_filter` only: one of these is a broken broker, a man in the middle or a misconfigured
/// bridge). A topic over 200 bytes is cut at a character's start and its length given.
std::string IgnoredTopicLine(const std::string& topic, size_t payload_bytes, const std::string& readings_filter);

struct MqttIngestOptions {
  std::string broker;     ///< for the log lines
  std::string client_id;  ///< for the log lines
  std::string topic_root;
  int64_t batch_max = 1000;     ///< readings per transaction at most
  int64_t commit_delay_ms = 5;  ///< group commit: wait this long for more readings before a commit
};

class MqttIngestLoop {
 public:
  struct Hooks {
    /// A gateway's status message (or last will); false: not one (logged as ignored).
    std::function<bool(const mqtt::ParsedTopic& topic, const std::string& payload)> status;
    /// A batch was committed and its acks sent (or queued).
    std::function<void(const IngestResult& result)> committed;
    /// Once a turn, after the commits: the caller's publishing (on this thread, with this link).
    std::function<void(mqtt::Publisher& link)> publish;
  };
  /// `now_s`: the server's "now" (unix seconds) for commit acks. The parts outlive the loop.
  MqttIngestLoop(MqttIngestOptions options, mqtt::Link& link, Ingestor& ingestor, ServerMetrics& metrics, core::Logger& log,
                 std::function<int64_t()> now_s, Hooks hooks);

  /// Runs until `stop` becomes true (checked every 20 ms at most).
  void Run(const std::atomic<bool>& stop);

 private:
  void Collect(int64_t now_ms, std::vector<Incoming>* batch);
  void CommitAndAck(std::vector<Incoming>* batch);
  void LogStats(int64_t now_ms);

  MqttIngestOptions o_;
  mqtt::Link& link_;
  Ingestor& ingestor_;
  ServerMetrics& metrics_;
  core::Logger& log_;
  std::function<int64_t()> now_s_;
  Hooks hooks_;
  const std::string readings_filter_;
  int ignored_logged_ = 0;         ///< this minute's lines about ignored messages
  uint64_t ignored_unlogged_ = 0;  ///< this minute's ignored messages beyond them
  int64_t last_stats_ms_;
  // Commit acks the link refused (not connected) wait here and go first at the next turn, instead
  // of being dropped (the gateway would wait for its republication).
  mqtt::Outbox acks_;
  uint64_t acks_dropped_logged_ = 0;
  IngestCounters last_counters_;
};

}  // namespace lw::server
