#pragma once
/// The gateway's logic, free of I/O: bytes from the coordinator in, acks to the sensors out through
/// a ByteSink, records into the Spool, messages out through an mqtt::Publisher, commit acks in. The caller
/// (main) owns the threads: every method is called from one thread, with the current Unix time in
/// ms passed in so tests control time.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <string_view>
#include <tuple>
#include <vector>

#include "core/log.hpp"
#include "gateway/byte_sink.hpp"
#include "gateway/spool.hpp"
#include "mqtt/publisher.hpp"
#include "mqtt/topics.hpp"
#include "protocol/frame_decoder.hpp"

namespace lw::gateway {

struct GatewayOptions {
  std::string site;
  std::string crusher;
  std::string gateway_id;
  protocol::ApiMode api_mode = protocol::ApiMode::kEscaped;
  /// Reading messages of one sensor published and awaiting the server's commit ack at a time. 1
  /// keeps the server's first sight of a sensor's records in seq order whatever the broker loses.
  /// A message holds one record, or up to the server's announced batch size once it has announced
  /// one since the last connect (docs/mqtt.md, *Batches*).
  size_t window = 1;
  /// Records in one reading message at most when the server announces batches (its commit acks'
  /// `"batch"`); 1: the one-record form always. Also capped by mqtt::kMaxReadingBatch.
  size_t max_batch = 64;
  /// Device registry entries (address, sensor) at most: a radio network can announce any number
  /// of addresses. Beyond it new devices are not registered (counted, logged); their readings
  /// are still spooled and acked.
  size_t max_devices = 1000;
  /// A published record without a commit ack after this long is published again.
  int64_t republish_after_ms = 30'000;
  /// Period of `gateway/stats` (0: never).
  int64_t stats_interval_ms = 60'000;
  /// Records released by commit acks are deleted from the spool together: at the latest this long
  /// after the first of them, with the next spooled batch (same transaction), before the spool is
  /// read in full, or when the Gateway is destroyed. The sensor's next record is published at once
  /// either way; a deletion lost with a crash only publishes the record again. Each deletion
  /// rewrites a page of the (sensor, seq) index: the longer the delay, the more of a sensor's
  /// deletions share a page (50 ms: one page per record at 100 sensors).
  int64_t release_delay_ms = 200;
  /// Time (Unix ms) that stamps received records (`time` = it - age_s, `received`) and new
  /// devices, given the loop's `now_ms`; unset: `now_ms`. Set from --clock-file when a simulator
  /// runs virtual time; spool bookkeeping and every timer keep `now_ms`. Called synchronously from
  /// within OnBytes, on the thread that calls the Gateway (main's loop).
  std::function<int64_t(int64_t now_ms)> stamp_clock;
  /// Log sink (one line, no newline, as written: text from the radio and the broker unescaped, so
  /// the sink must make it safe, as core::Logger does). Defaults to stderr, escaped. Called
  /// synchronously from within the Gateway's methods, on the thread that calls them (main's loop):
  /// never concurrently.
  std::function<void(const std::string&)> log;
};

/// Counters of the gateway's own work (the frame decoder's are in DecoderCounters).
struct GatewayCounters {
  uint64_t records_received = 0;   ///< records decoded from readings payloads (duplicates too)
  uint64_t records_spooled = 0;    ///< new records stored
  uint64_t records_duplicate = 0;  ///< retransmissions of records already spooled
  uint64_t records_rejected = 0;   ///< spool full: not stored, not acked
  uint64_t bad_payloads = 0;       ///< 0x90 frames whose payload failed to decode
  uint64_t unknown_payloads = 0;   ///< 0x90 frames with a payload type we do not handle
  uint64_t malformed_frames = 0;   ///< valid checksum but a known type failed to parse
  uint64_t unknown_frames = 0;     ///< frames of a type the gateway does not handle
  uint64_t acks_sent = 0;
  uint64_t ack_write_errors = 0;
  uint64_t tx_failures = 0;        ///< 0x8B Transmit Status with a non-success delivery status
  uint64_t acks_too_large = 0;     ///< 0x8B data_payload_too_large: an ack above what the link carries
  uint64_t oversize_frames = 0;    ///< readings payloads above the coordinator's payload limit (fragmented on the air)
  uint64_t spool_errors = 0;       ///< SQLite failures (records not acked)
  uint64_t published = 0;          ///< first publications of a record
  uint64_t batches_published = 0;  ///< reading messages that carried more than one record
  uint64_t republished = 0;        ///< publications after a reconnect or the republish timeout
  uint64_t publish_refused = 0;    ///< readings the MQTT client refused to take (kept, tried again at the next Pump)
  uint64_t link_resets = 0;        ///< reconnects asked for because the link carried nothing of QoS 1 (LinkStalled)
  uint64_t committed = 0;          ///< records deleted after the server's commit ack
  uint64_t bad_commit_acks = 0;
  uint64_t commit_acks_ignored = 0;  ///< acked seqs that were not published and awaiting an ack
  uint64_t devices_refused = 0;      ///< new registry entries refused: registry full (max_devices)
  uint64_t connects = 0;
  int64_t latency_last_ms = -1;  ///< receive -> commit ack of the last committed record
  int64_t latency_max_ms = -1;
  int64_t latency_sum_ms = 0;
};

class Gateway {
 public:
  Gateway(GatewayOptions options, Spool& spool, mqtt::Publisher& publisher, ByteSink& radio);
  /// Deletes the records released by commit acks that are not deleted yet.
  ~Gateway();
  Gateway(const Gateway&) = delete;
  Gateway& operator=(const Gateway&) = delete;

  /// Bytes read from the coordinator's serial port.
  void OnBytes(const uint8_t* data, size_t len, int64_t now_ms);

  /// The coordinator's serial port was (re)opened: asks the module for NP and EE (local AT
  /// queries). Acks are sized for the smallest supported payload (protocol::kMinRfPayload) until
  /// both answers came; a coordinator that does not answer within 5 s is logged once.
  void OnRadioOpened(int64_t now_ms);
  /// The RF payload every ack is sized to now (bytes; see OnRadioOpened).
  size_t rf_payload_limit() const;

  /// The MQTT client (re)connected: publishes the retained online status and the device registry
  /// and republishes every unconfirmed record from the start of each sensor's queue.
  void OnConnected(int64_t now_ms);

  /// A message arrived on a subscribed topic (commit acks).
  void OnMessage(std::string_view topic, std::string_view payload, int64_t now_ms);
  /// Several messages at once (what one poll of the link returned): the records their commit
  /// acks release are deleted in one spool transaction.
  void OnMessages(const std::vector<std::pair<std::string_view, std::string_view>>& messages, int64_t now_ms);

  /// Publishes what is due: records (in seq order per sensor), stats. Cheap when nothing changed.
  void Pump(int64_t now_ms);

  /// True when records wait in the spool, the link says it is connected, and for three
  /// republication periods no reading publication was accepted and no commit ack released a
  /// record: the connection carries nothing of QoS 1 (seen in CI: the acks were at the broker and
  /// every republication was refused, while QoS 0 stats went out). The caller then reconnects the
  /// link and calls OnLinkReset(); the reconnect republishes every unconfirmed record.
  bool LinkStalled(int64_t now_ms) const;
  void OnLinkReset(int64_t now_ms);

  /// This gateway's topics: below `linerwatch/v1/{site}/{crusher}/`.
  const mqtt::Topics& topics() const { return topics_; }

  /// The stats message (docs/gateway.md lists the fields).
  std::string StatsJson(int64_t now_ms) const;

  const GatewayCounters& counters() const { return counters_; }
  const protocol::DecoderCounters& decoder_counters() const { return decoder_.counters(); }
  /// Records waiting for a commit ack (spooled, not released by one).
  size_t spool_depth() const { return spool_.depth() - std::min(spool_.depth(), pending_release_count_); }
  size_t in_flight() const;
  /// Records per reading message now: 1 until a commit ack announced batches since the last
  /// connect; then min(announced, max_batch, mqtt::kMaxReadingBatch).
  size_t batch_records() const { return batch_records_; }

 private:
  void OnFrame(const uint8_t* frame, size_t len, int64_t now_ms);
  void OnAtResponse(const uint8_t* frame, size_t len);
  void OnTransmitStatus(const uint8_t* frame, size_t len);
  /// The acks of one group commit: per sensor, every seq of its frames in the read, in as few
  /// frames as the payload limit allows.
  void QueueAcks(const std::vector<std::tuple<uint64_t, uint16_t, uint32_t, std::vector<uint32_t>>>& acks);
  void OnReceivePacket(const uint8_t* frame, size_t len, int64_t now_ms);
  /// Group commit: the records of every readings frame of one OnBytes call go into the spool in
  /// one (fsynced) transaction, then each frame is acked to its sensor; nothing is acked before
  /// it is on disk.
  void FlushReadings();
  /// Deletes the records released by commit acks (pending_release_) in one transaction.
  void FlushReleases();
  /// Encodes the ack frames for `seqs` into ack_out_ (written by WriteAcks).
  void QueueAck(uint64_t dest64, uint16_t dest16, uint32_t sensor_id, const std::vector<uint32_t>& seqs);
  /// Writes the queued acks to the radio in one write.
  void WriteAcks();
  /// Whether `device` goes into the registry: a sensor entry not known yet and not in `admitted`,
  /// or a node's identification (may have changed); false when the registry is full (counted,
  /// logged).
  bool AdmitDevice(const DeviceEntry& device, const std::vector<DeviceEntry>& admitted);
  /// After the spool recorded an admitted `device`: known from now on; logged and its retained
  /// message due when `changed`.
  void DeviceRecorded(const DeviceEntry& device, bool changed);
  /// AdmitDevice, then the spool records it on its own (node identification frames).
  void NoteDevice(const DeviceEntry& device);
  void PublishRecords(int64_t now_ms);
  void PublishDevices(int64_t now_ms);
  bool PublishDevice(const std::string& address, const std::vector<DeviceEntry>& entries, int64_t now_ms);
  /// Logs the first few events of a kind, then every 1000th, so a noisy radio cannot fill the disk.
  void LogLimited(const std::string& kind, const std::string& line);
  void Log(const std::string& line) const;

  GatewayOptions options_;
  Spool& spool_;
  mqtt::Publisher& publisher_;
  ByteSink& radio_;
  protocol::FrameDecoder decoder_;
  mqtt::Topics topics_;
  GatewayCounters counters_;
  // Records published and awaiting a commit ack: sensor -> seq -> when.
  struct InFlight {
    int64_t published_ms = 0;  ///< the last publication
    int64_t received_ms = 0;   ///< arrival at the gateway (latency)
  };
  std::map<std::string, std::map<uint32_t, InFlight>> in_flight_;
  // Records released by commit acks, not deleted from the spool yet (FlushReleases): sensor ->
  // seqs. Never published again meanwhile (PublishRecords skips them).
  std::map<std::string, std::vector<uint32_t>> pending_release_;
  size_t pending_release_count_ = 0;
  int64_t pending_release_since_ms_ = 0;
  /// Registry entries of addresses known only from identification frames (no sensor heard from them).
  size_t AnnouncedOnlyDevices() const;
  std::set<std::string> known_devices_;  // "address/sensor" already in the registry
  core::LogLimiter log_limiter_;
  bool records_dirty_ = true;            // every sensor's queue head must be looked at
  std::set<std::string> dirty_sensors_;  // sensors whose queue head changed since the last look
  bool all_devices_dirty_ = true;        // after a connect: every device's message
  std::set<std::string> dirty_devices_;  // addresses whose message changed
  size_t batch_records_ = 1;             ///< records per reading message (batch_records())
  int64_t next_republish_check_ms_ = 0;
  int64_t last_progress_ms_ = 0;  ///< last accepted reading publication, released record or connect
  int64_t next_stats_ms_ = 0;
  uint8_t next_frame_id_ = 1;
  // The coordinator's answers to AT NP / EE (-1: not known) and the outstanding queries.
  int radio_np_ = -1;
  int radio_ee_ = -1;
  uint8_t np_query_id_ = 0;
  uint8_t ee_query_id_ = 0;
  int64_t radio_query_deadline_ms_ = -1;  ///< when an unanswered query is logged (-1: none pending)
  // Readings frames decoded by the current OnBytes call, not spooled yet (FlushReadings).
  struct PendingFrame {
    uint64_t src64 = 0;
    uint16_t src16 = 0;
    uint32_t sensor_id = 0;
    int64_t stamp_ms = 0;
    size_t first = 0, count = 0;  ///< its records in pending_records_
  };
  std::vector<PendingFrame> pending_frames_;
  std::vector<SpoolRecord> pending_records_;
  std::vector<uint8_t> ack_out_;  ///< encoded ack frames not written yet (WriteAcks)
  size_t ack_out_count_ = 0;      ///< acks in ack_out_
};

}  // namespace lw::gateway
