#include "gateway/gateway.hpp"

#include <algorithm>
#include <cstdio>
#include <exception>
#include <utility>

#include "gateway/messages.hpp"
#include "protocol/sensor_payload.hpp"
#include "protocol/xbee_api.hpp"

namespace lw::gateway {
namespace {

constexpr size_t kMaxRecordsPerMessage = 8;
/// Ack bytes written to the radio in one write at most (a few dozen acks).
constexpr size_t kAckWriteBytes = 1024;
/// Released records waiting for their deletion at most (then deleted at once).
constexpr size_t kMaxPendingReleases = 1000;

std::string FrameTypeHex(uint8_t type) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "0x%02X", type);
  return buf;
}

}  // namespace

Gateway::Gateway(GatewayOptions options, Spool& spool, mqtt::Publisher& publisher, ByteSink& radio)
    : options_(std::move(options)),
      spool_(spool),
      publisher_(publisher),
      radio_(radio),
      decoder_(options_.api_mode),
      topics_(options_.site, options_.crusher) {
  if (options_.window == 0) options_.window = 1;
  options_.max_batch = std::clamp<size_t>(options_.max_batch, 1, mqtt::kMaxReadingBatch);
  for (const DeviceEntry& d : spool_.Devices()) known_devices_.insert(d.address + "/" + d.sensor);
}

Gateway::~Gateway() {
  FlushReleases();
}

void Gateway::FlushReleases() {
  if (pending_release_.empty()) return;
  try {
    spool_.Confirm(pending_release_);
  } catch (const std::exception& e) {
    // Kept in the spool: read again with every head and published again, acked again.
    ++counters_.spool_errors;
    records_dirty_ = true;
    LogLimited("spool_error", std::string("spool: deleting committed records failed (kept, will be republished): ") + e.what());
  }
  pending_release_.clear();
  pending_release_count_ = 0;
}

void Gateway::Log(const std::string& line) const {
  // Lines carry node identifiers, topics and message text from the radio and the broker. A sink
  // makes them safe itself (the program's core::Logger: escaping here too would show a backslash
  // as four); without one, escape control characters so nothing can forge or garble a line.
  if (options_.log) {
    options_.log(line);
  } else {
    std::fprintf(stderr, "%s\n", SanitizeForLog(line).c_str());
  }
}

void Gateway::LogLimited(const std::string& kind, const std::string& line) {
  if (const auto admitted = log_limiter_.Admit(kind, line)) Log(*admitted);
}

void Gateway::OnBytes(const uint8_t* data, size_t len, int64_t now_ms) {
  decoder_.Feed(data, len, [&](protocol::DecodeEvent event) {
    switch (event) {
      case protocol::DecodeEvent::kNone:
        break;
      case protocol::DecodeEvent::kFrame:
        OnFrame(decoder_.frame_data(), decoder_.frame_length(), now_ms);
        break;
      case protocol::DecodeEvent::kChecksumError:
        LogLimited("checksum", "serial: frame with a bad checksum dropped");
        break;
      case protocol::DecodeEvent::kEscapeError:
        LogLimited("escape", "serial: frame with an escape error dropped");
        break;
      case protocol::DecodeEvent::kLengthError:
        LogLimited("length", "serial: frame with an invalid length dropped");
        break;
      case protocol::DecodeEvent::kTruncated:
        LogLimited("truncated", "serial: truncated frame dropped");
        break;
    }
  });
  FlushReadings();
}

void Gateway::OnFrame(const uint8_t* frame, size_t len, int64_t now_ms) {
  const uint8_t type = len ? frame[0] : 0;
  switch (static_cast<protocol::FrameType>(type)) {
    case protocol::FrameType::kReceivePacket:
      OnReceivePacket(frame, len, now_ms);
      return;
    case protocol::FrameType::kNodeIdentification: {
      protocol::NodeIdentification ni;
      if (protocol::ParseNodeIdentification(frame, len, &ni) != protocol::Status::kOk) {
        ++counters_.malformed_frames;
        LogLimited("malformed", "serial: malformed node identification frame (" + std::to_string(len) + " bytes)");
        return;
      }
      DeviceEntry d;
      d.address = mqtt::AddressHex(ni.remote64);
      d.node_identifier = ni.node_identifier;
      d.device_type = ni.device_type;
      d.first_seen_ms = now_ms;
      NoteDevice(d);
      return;
    }
    case protocol::FrameType::kTransmitStatus:
      OnTransmitStatus(frame, len);
      return;
    case protocol::FrameType::kAtCommandResponse:
      OnAtResponse(frame, len);
      return;
    case protocol::FrameType::kModemStatus: {
      protocol::ModemStatus ms;
      if (protocol::ParseModemStatus(frame, len, &ms) == protocol::Status::kOk) {
        Log(std::string("radio: modem status ") + protocol::ModemStatusName(ms.status));
      } else {
        ++counters_.malformed_frames;
      }
      return;
    }
    case protocol::FrameType::kTransmitRequest:
    case protocol::FrameType::kAtCommand:
      break;
  }
  ++counters_.unknown_frames;
  LogLimited("unknown_frame",
             "serial: frame of unhandled type " + FrameTypeHex(type) + " (" + std::to_string(len) + " bytes) ignored");
}

void Gateway::OnTransmitStatus(const uint8_t* frame, size_t len) {
  protocol::TransmitStatus st;
  if (protocol::ParseTransmitStatus(frame, len, &st) != protocol::Status::kOk) {
    ++counters_.malformed_frames;
    LogLimited("malformed", "serial: malformed transmit status frame");
    return;
  }
  if (st.delivery_status == static_cast<uint8_t>(protocol::DeliveryStatus::kSuccess)) return;
  ++counters_.tx_failures;
  char dest[8];
  std::snprintf(dest, sizeof dest, "%04X", static_cast<unsigned>(st.dest16));
  std::string why = protocol::DeliveryStatusName(st.delivery_status);
  if (st.delivery_status == static_cast<uint8_t>(protocol::DeliveryStatus::kDataPayloadTooLarge)) {
    ++counters_.acks_too_large;
    why += ": the link carries less than the coordinator's NP and EE say (APS encryption or source routing?)";
  }
  LogLimited("tx_failure",
             std::string("radio: ack delivery to 16-bit address ") + dest + " failed: " + why + " (the sensor retransmits)");
}

void Gateway::OnRadioOpened(int64_t now_ms) {
  radio_np_ = -1;
  radio_ee_ = -1;
  uint8_t* ids[2] = {&np_query_id_, &ee_query_id_};
  const char* commands[2] = {"NP", "EE"};
  std::vector<uint8_t> out;
  for (int i = 0; i < 2; ++i) {
    protocol::AtCommand cmd;
    cmd.frame_id = next_frame_id_;
    next_frame_id_ = protocol::NextFrameId(next_frame_id_);
    cmd.command[0] = commands[i][0];
    cmd.command[1] = commands[i][1];
    uint8_t wire[16];
    const size_t n = protocol::EncodeAtCommand(options_.api_mode, cmd, wire, sizeof wire);
    out.insert(out.end(), wire, wire + n);
    *ids[i] = cmd.frame_id;
  }
  radio_query_deadline_ms_ = now_ms + 5000;
  if (!radio_.Write(out.data(), out.size())) {
    LogLimited("at_write", "serial: writing the AT NP / EE queries failed; acks stay sized for " +
                               std::to_string(protocol::kMinRfPayload) + " bytes");
  }
}

size_t Gateway::rf_payload_limit() const {
  return protocol::ClampRfPayload(protocol::RfPayloadLimit(radio_np_, radio_ee_));
}

void Gateway::OnAtResponse(const uint8_t* frame, size_t len) {
  protocol::AtCommandResponse rsp;
  if (protocol::ParseAtCommandResponse(frame, len, &rsp) != protocol::Status::kOk) {
    ++counters_.malformed_frames;
    return;
  }
  const std::string name(rsp.command, 2);
  uint64_t value = 0;
  const bool ok = rsp.Value(&value);
  if (rsp.frame_id == 0 || (rsp.frame_id != np_query_id_ && rsp.frame_id != ee_query_id_)) return;
  if (!ok) {
    Log("radio: the coordinator answered AT " + name + " with status " + std::to_string(rsp.status) + "; acks stay sized for " +
        std::to_string(protocol::kMinRfPayload) + " bytes");
  } else if (rsp.frame_id == np_query_id_) {
    radio_np_ = static_cast<int>(std::min<uint64_t>(value, 0xFF));
  } else {
    radio_ee_ = value != 0 ? 1 : 0;
  }
  (rsp.frame_id == np_query_id_ ? np_query_id_ : ee_query_id_) = 0;
  if (np_query_id_ != 0 || ee_query_id_ != 0 || radio_np_ < 0 || radio_ee_ < 0) return;
  radio_query_deadline_ms_ = -1;
  const size_t raw = protocol::RfPayloadLimit(radio_np_, radio_ee_);
  std::string line = "radio: coordinator NP " + std::to_string(radio_np_) + ", EE " + std::to_string(radio_ee_) +
                     ": RF payloads of at most " + std::to_string(rf_payload_limit()) + " bytes (acks of up to " +
                     std::to_string(protocol::MaxAckSeqs(rf_payload_limit())) + " seqs)";
  if (raw < protocol::kMinRfPayload) {
    line += "; WARNING: below the " + std::to_string(protocol::kMinRfPayload) +
            " bytes one record of a 128-loop ladder needs: larger frames are fragmented (docs/gateway.md, "
            "*Coordinator set-up*)";
  }
  Log(line);
}

void Gateway::OnReceivePacket(const uint8_t* frame, size_t len, int64_t now_ms) {
  protocol::ReceivePacket rx;
  if (protocol::ParseReceivePacket(frame, len, &rx) != protocol::Status::kOk) {
    ++counters_.malformed_frames;
    LogLimited("malformed", "serial: malformed receive packet frame (" + std::to_string(len) + " bytes)");
    return;
  }
  const std::string source = mqtt::AddressHex(rx.src64);
  if (radio_np_ >= 0 && radio_ee_ >= 0 && rx.payload_len > rf_payload_limit()) {
    // Stored all the same; the sender relies on fragmentation (its firmware does not size frames
    // to NP), and a fragmented packet is lost whole when one fragment is.
    ++counters_.oversize_frames;
    LogLimited("oversize", "radio: " + std::to_string(rx.payload_len) + "-byte payload from " + source + " is above the link's " +
                               std::to_string(rf_payload_limit()) +
                               " bytes: it was fragmented on the air (update that sensor's firmware)");
  }
  const uint8_t payload_type = protocol::PayloadType(rx.payload, rx.payload_len);
  if (payload_type != protocol::kMsgReadings) {
    ++counters_.unknown_payloads;
    LogLimited("unknown_payload",
               "radio: payload of unknown type " + FrameTypeHex(payload_type) + " from " + source + " ignored");
    return;
  }
  protocol::ReadingsHeader header;
  protocol::SensorRecord records[kMaxRecordsPerMessage];
  size_t count = 0;
  const protocol::PayloadStatus status =
      protocol::DecodeReadings(rx.payload, rx.payload_len, &header, records, kMaxRecordsPerMessage, &count);
  if (status != protocol::PayloadStatus::kOk) {
    ++counters_.bad_payloads;
    LogLimited("bad_payload",
               std::string("radio: bad readings payload from ") + source + ": " + protocol::PayloadStatusName(status));
    return;
  }
  counters_.records_received += count;
  const std::string sensor = std::to_string(header.sensor_id);
  // Read the stamp clock only now, after the frame's bytes were read: a simulator holds its
  // virtual clock still until the ack below comes back.
  const int64_t stamp_ms = options_.stamp_clock ? options_.stamp_clock(now_ms) : now_ms;
  ReadingContext context{rx.src64, options_.gateway_id, stamp_ms};
  PendingFrame pending;
  pending.src64 = rx.src64;
  pending.src16 = rx.src16;
  pending.sensor_id = header.sensor_id;
  pending.stamp_ms = stamp_ms;
  pending.first = pending_records_.size();
  pending.count = count;
  for (size_t i = 0; i < count; ++i) {
    SpoolRecord r;
    r.sensor = sensor;
    r.seq = records[i].seq;
    r.received_ms = now_ms;
    r.heartbeat = (records[i].flags & protocol::kFlagHeartbeat) != 0;
    r.payload = ReadingJson(header, records[i], context);
    pending_records_.push_back(std::move(r));
  }
  pending_frames_.push_back(pending);
}

void Gateway::FlushReadings() {
  if (pending_frames_.empty()) return;
  std::vector<PendingFrame> frames;
  std::vector<SpoolRecord> batch;
  frames.swap(pending_frames_);
  batch.swap(pending_records_);
  // A sender's first registry entry goes into the same transaction (no fsync of its own).
  std::vector<DeviceEntry> devices;
  for (const PendingFrame& f : frames) {
    DeviceEntry d;
    d.address = mqtt::AddressHex(f.src64);
    d.sensor = std::to_string(f.sensor_id);
    d.first_seen_ms = f.stamp_ms;
    if (AdmitDevice(d, devices)) devices.push_back(std::move(d));
  }
  std::vector<InsertOutcome> outcomes;
  std::vector<bool> devices_changed;
  const uint64_t evicted_before = spool_.evicted();
  try {
    // The records released since the last deletion go in the same transaction (one fsync).
    outcomes = spool_.Insert(batch, pending_release_, devices, &devices_changed);
    pending_release_.clear();
    pending_release_count_ = 0;
    // A full spool evicted the oldest heartbeat, maybe another sensor's head: look at every head.
    if (spool_.evicted() != evicted_before) records_dirty_ = true;
  } catch (const std::exception& e) {
    // The transaction rolled back: none of these records is stored and none is acked.
    for (const PendingFrame& f : frames) {
      ++counters_.spool_errors;
      LogLimited("spool_error",
                 "spool: records from sensor " + std::to_string(f.sensor_id) + " not stored (not acked): " + e.what());
    }
    return;
  }
  // One ack list per sender and sensor, in the order they first came; a seq once.
  std::vector<std::tuple<uint64_t, uint16_t, uint32_t, std::vector<uint32_t>>> acks;
  for (const PendingFrame& f : frames) {
    const std::string sensor = std::to_string(f.sensor_id);
    auto entry = std::find_if(acks.begin(), acks.end(),
                              [&](const auto& a) { return std::get<0>(a) == f.src64 && std::get<2>(a) == f.sensor_id; });
    if (entry == acks.end()) entry = acks.insert(acks.end(), {f.src64, f.src16, f.sensor_id, {}});
    std::vector<uint32_t>& ack_seqs = std::get<3>(*entry);
    const auto ack = [&ack_seqs](uint32_t seq) {
      if (std::find(ack_seqs.begin(), ack_seqs.end(), seq) == ack_seqs.end()) ack_seqs.push_back(seq);
    };
    for (size_t i = f.first; i < f.first + f.count; ++i) {
      switch (outcomes[i]) {
        case InsertOutcome::kStored:
          ++counters_.records_spooled;
          ack(batch[i].seq);
          dirty_sensors_.insert(sensor);
          break;
        case InsertOutcome::kDuplicate:
          ++counters_.records_duplicate;
          ack(batch[i].seq);
          break;
        case InsertOutcome::kRejectedFull:
          ++counters_.records_rejected;
          LogLimited("spool_full", "spool: full (" + std::to_string(spool_.depth()) + " records), record " + sensor + "/" +
                                       std::to_string(batch[i].seq) + " not acked; the sensor keeps it");
          break;
      }
    }
  }
  QueueAcks(acks);
  WriteAcks();
  for (size_t i = 0; i < devices.size(); ++i) DeviceRecorded(devices[i], devices_changed[i]);
}

void Gateway::QueueAcks(const std::vector<std::tuple<uint64_t, uint16_t, uint32_t, std::vector<uint32_t>>>& acks) {
  for (const auto& [dest64, dest16, sensor_id, seqs] : acks) {
    if (!seqs.empty()) QueueAck(dest64, dest16, sensor_id, seqs);
  }
}

void Gateway::QueueAck(uint64_t dest64, uint16_t dest16, uint32_t sensor_id, const std::vector<uint32_t>& seqs) {
  // As many seqs per ack as the link carries unfragmented: a sleeping sensor's parent holds few
  // packets for it, and a fragmented one is lost whole when one fragment is.
  const size_t per_ack = protocol::MaxAckSeqs(rf_payload_limit());
  for (size_t start = 0; start < seqs.size(); start += per_ack) {
    protocol::Ack ack;
    ack.sensor_id = sensor_id;
    const size_t n = std::min(per_ack, seqs.size() - start);
    for (size_t i = 0; i < n; ++i) ack.seqs[i] = seqs[start + i];
    ack.count = static_cast<uint8_t>(n);
    uint8_t payload[protocol::kMaxRfPayload];
    size_t payload_len = 0;
    uint8_t wire[protocol::kMaxWireFrame];
    protocol::TransmitRequest req;
    req.frame_id = next_frame_id_;
    next_frame_id_ = protocol::NextFrameId(next_frame_id_);
    req.dest64 = dest64;
    req.dest16 = dest16;
    if (protocol::EncodeAck(ack, payload, rf_payload_limit(), &payload_len) != protocol::PayloadStatus::kOk) return;
    req.payload = payload;
    req.payload_len = payload_len;
    const size_t wire_len = protocol::EncodeTransmitRequest(options_.api_mode, req, wire, sizeof wire);
    if (wire_len == 0) {
      ++counters_.ack_write_errors;
      LogLimited("ack_write", "serial: encoding an ack to " + mqtt::AddressHex(dest64) + " failed (the sensor retransmits)");
      continue;
    }
    if (ack_out_.size() + wire_len > kAckWriteBytes) WriteAcks();
    ack_out_.insert(ack_out_.end(), wire, wire + wire_len);
    ++ack_out_count_;
  }
}

void Gateway::WriteAcks() {
  if (ack_out_.empty()) return;
  // The acks of a group commit in one write (a few hundred bytes at most each): one system call
  // instead of one per frame. Each write may wait up to its bound for the port to drain.
  if (radio_.Write(ack_out_.data(), ack_out_.size())) {
    counters_.acks_sent += ack_out_count_;
  } else {
    counters_.ack_write_errors += ack_out_count_;
    LogLimited("ack_write", "serial: writing " + std::to_string(ack_out_count_) + " ack(s) failed (the sensors retransmit)");
  }
  ack_out_.clear();
  ack_out_count_ = 0;
}

bool Gateway::AdmitDevice(const DeviceEntry& device, const std::vector<DeviceEntry>& admitted) {
  const std::string key = device.address + "/" + device.sensor;
  // Sensors are checked in memory on every frame; the database is touched only for news.
  const bool known = known_devices_.count(key) != 0;
  if (!device.sensor.empty() && known) return false;
  for (const DeviceEntry& a : admitted) {
    if (a.address == device.address && a.sensor == device.sensor) return false;  // already in this batch
  }
  if (!known && known_devices_.size() + admitted.size() >= options_.max_devices) {
    ++counters_.devices_refused;
    LogLimited("registry_full", "registry: full (" + std::to_string(known_devices_.size()) + " entries, --max-devices); " +
                                    (device.sensor.empty() ? std::string("node") : "sensor " + device.sensor) + " at " +
                                    device.address + " not registered (its readings are still spooled)");
    return false;
  }
  // Identification frames cost nothing to forge: addresses known only from them take at most half
  // of the registry, so a radio announcing made-up addresses cannot keep new sensors out.
  if (!known && device.sensor.empty()) {
    size_t announced = AnnouncedOnlyDevices();
    for (const DeviceEntry& a : admitted) announced += a.sensor.empty() ? 1 : 0;
    if (announced >= (options_.max_devices + 1) / 2) {
      ++counters_.devices_refused;
      LogLimited("registry_full", "registry: full for addresses known only from identification frames (" +
                                      std::to_string(announced) + ", half of --max-devices); node at " + device.address +
                                      " not registered");
      return false;
    }
  }
  return true;
}

size_t Gateway::AnnouncedOnlyDevices() const {
  // Keys are "address/sensor", sorted: an address's node entry "address/" comes just before its
  // sensors' entries, if it has any.
  size_t n = 0;
  for (auto it = known_devices_.begin(); it != known_devices_.end(); ++it) {
    if (it->empty() || it->back() != '/') continue;
    const auto next = std::next(it);
    if (next == known_devices_.end() || next->rfind(*it, 0) != 0) ++n;
  }
  return n;
}

void Gateway::DeviceRecorded(const DeviceEntry& device, bool changed) {
  const bool known = !known_devices_.insert(device.address + "/" + device.sensor).second;
  if (!changed) return;
  // New entries are logged each (at most --max-devices lines); changes of a known node's
  // identification are rate limited (a radio can send them without end).
  const std::string line = "registry: " + (device.sensor.empty() ? std::string("node") : "sensor " + device.sensor) + " at " +
                           device.address + (device.node_identifier.empty() ? "" : " \"" + device.node_identifier + "\"");
  if (known) {
    LogLimited("registry_update", line);
  } else {
    Log(line);
  }
  dirty_devices_.insert(device.address);
}

void Gateway::NoteDevice(const DeviceEntry& device) {
  if (!AdmitDevice(device, {})) return;
  bool changed = false;
  try {
    changed = spool_.RecordDevice(device);
  } catch (const std::exception& e) {
    ++counters_.spool_errors;
    LogLimited("spool_error", std::string("spool: device registry: ") + e.what());
    return;
  }
  DeviceRecorded(device, changed);
}

void Gateway::OnConnected(int64_t now_ms) {
  ++counters_.connects;
  // Whatever was in flight may have been lost with the old connection (or the broker): start
  // every sensor's queue over, in order.
  in_flight_.clear();
  // The server behind the broker may have changed: one record per message until it announces
  // batches again (in a commit ack).
  batch_records_ = 1;
  last_progress_ms_ = now_ms;
  records_dirty_ = true;  // every sensor
  all_devices_dirty_ = true;
  publisher_.Publish({topics_.Status(), mqtt::EncodeStatus({true, options_.gateway_id, mqtt::IsoUtc(now_ms)}), 1, true});
  Pump(now_ms);
}

void Gateway::OnMessage(std::string_view topic, std::string_view payload, int64_t now_ms) {
  OnMessages({{topic, payload}}, now_ms);
}

void Gateway::OnMessages(const std::vector<std::pair<std::string_view, std::string_view>>& messages, int64_t now_ms) {
  // Every acked seq of every message, released in one spool transaction.
  std::map<std::string, std::vector<uint32_t>> release;
  for (const auto& [topic, payload] : messages) {
    // {root}sensors/{sensor}/committed
    const auto parsed = topics_.Parse(topic);
    if (!parsed || parsed->kind != mqtt::TopicKind::kCommitted) {
      LogLimited("unexpected_topic", "mqtt: message on unexpected topic " + std::string(topic) + " ignored");
      continue;
    }
    std::string error;
    const auto ack = mqtt::DecodeCommitAck(payload, parsed->id, &error);
    if (!ack) {
      ++counters_.bad_commit_acks;
      LogLimited("bad_commit", "mqtt: bad commit ack on " + std::string(topic) + ": " + error);
      continue;
    }
    // The latest ack says what the server takes: an ack without "batch" (a server that does not
    // know the batch form) turns batches off at once.
    const size_t batch = std::min<size_t>(std::max<uint32_t>(ack->batch, 1), options_.max_batch);
    if (batch != batch_records_) {
      Log("mqtt: the server takes " + (batch > 1 ? "up to " + std::to_string(batch) + " records" : std::string("one record")) +
          " per reading message");
      batch_records_ = batch;
      records_dirty_ = true;  // every sensor's next records may now go together
    }
    // Only records this gateway published and is waiting for are released. The server acks what
    // it received; anything else (a seq never published since the last connect, or not spooled)
    // cannot be the server's answer to us, so a forged or stale ack cannot empty the backlog. A
    // genuine late ack that is skipped costs one republication.
    size_t awaited = 0;
    auto it = in_flight_.find(ack->sensor);
    for (uint32_t seq : ack->seqs) {
      if (it != in_flight_.end() && it->second.count(seq)) {
        release[ack->sensor].push_back(seq);
        ++awaited;
      } else {
        ++counters_.commit_acks_ignored;
      }
    }
    if (awaited < ack->seqs.size()) {
      LogLimited("ack_ignored", "mqtt: commit ack on " + std::string(topic) + " names " +
                                    std::to_string(ack->seqs.size() - awaited) +
                                    " seq(s) not published and awaiting an ack; ignored");
    }
  }
  if (release.empty()) return;
  // Released at once: each sensor's next record is published at the next Pump. The deletions
  // wait for the next spooled batch or release_delay_ms (FlushReleases), so that a hundred
  // sensors' acks cost one transaction, not a hundred.
  if (pending_release_count_ == 0) pending_release_since_ms_ = now_ms;
  for (const auto& [sensor, seqs] : release) {
    auto it = in_flight_.find(sensor);
    if (it == in_flight_.end()) continue;
    std::vector<uint32_t>& pending = pending_release_[sensor];
    for (uint32_t seq : seqs) {
      const auto flight = it->second.find(seq);
      if (flight == it->second.end()) continue;  // named twice
      pending.push_back(seq);
      ++pending_release_count_;
      const int64_t latency = std::max<int64_t>(0, now_ms - flight->second.received_ms);
      ++counters_.committed;
      counters_.latency_last_ms = latency;
      counters_.latency_max_ms = std::max(counters_.latency_max_ms, latency);
      counters_.latency_sum_ms += latency;
      it->second.erase(flight);
    }
    if (it->second.empty()) in_flight_.erase(it);
    dirty_sensors_.insert(sensor);
  }
  last_progress_ms_ = now_ms;
  if (pending_release_count_ >= kMaxPendingReleases) FlushReleases();
}

size_t Gateway::in_flight() const {
  size_t n = 0;
  for (const auto& [sensor, seqs] : in_flight_) n += seqs.size();
  return n;
}

void Gateway::Pump(int64_t now_ms) {
  // The wall clock may step back (NTP on a box without RTC): never wait longer than one period.
  next_republish_check_ms_ = std::min(next_republish_check_ms_, now_ms + options_.republish_after_ms);
  next_stats_ms_ = std::min(next_stats_ms_, now_ms + options_.stats_interval_ms);
  if (pending_release_count_ > 0 &&
      (now_ms - pending_release_since_ms_ >= options_.release_delay_ms || now_ms < pending_release_since_ms_)) {
    FlushReleases();
  }
  if (radio_query_deadline_ms_ >= 0 && now_ms >= radio_query_deadline_ms_) {
    radio_query_deadline_ms_ = -1;
    Log("radio: the coordinator did not answer AT NP / EE within 5 s (API mode " +
        std::to_string(static_cast<int>(options_.api_mode)) +
        " as its AP? docs/gateway.md, *First light*): acks stay sized for " + std::to_string(protocol::kMinRfPayload) + " bytes");
  }
  if (publisher_.IsConnected()) {
    // Readings first: a registry of many radios must not delay them.
    if (records_dirty_ || !dirty_sensors_.empty() || now_ms >= next_republish_check_ms_) PublishRecords(now_ms);
    if (all_devices_dirty_ || !dirty_devices_.empty()) PublishDevices(now_ms);
  }
  if (options_.stats_interval_ms > 0 && now_ms >= next_stats_ms_) {
    next_stats_ms_ = now_ms + options_.stats_interval_ms;
    if (publisher_.IsConnected()) publisher_.Publish({topics_.Stats(), StatsJson(now_ms), 0, false});
  }
}

bool Gateway::LinkStalled(int64_t now_ms) const {
  return publisher_.IsConnected() && spool_depth() > 0 && now_ms - last_progress_ms_ > 3 * options_.republish_after_ms;
}

void Gateway::OnLinkReset(int64_t now_ms) {
  ++counters_.link_resets;
  last_progress_ms_ = now_ms;
}

bool Gateway::PublishDevice(const std::string& address, const std::vector<DeviceEntry>& entries, int64_t now_ms) {
  if (entries.empty()) return true;
  return publisher_.Publish({topics_.Device(address), DeviceJson(entries, options_.gateway_id, now_ms), 1, true});
}

void Gateway::PublishDevices(int64_t now_ms) {
  // One small retained message per radio, and only for what changed: a new address costs one
  // message, not the whole registry (300 announced nodes made 4 MB when it was one message).
  try {
    if (all_devices_dirty_) {
      for (const DeviceEntry& d : spool_.Devices()) dirty_devices_.insert(d.address);
      all_devices_dirty_ = false;
    }
    // Stops at the first refusal (client buffer full): the rest go on a later Pump, none twice.
    for (auto it = dirty_devices_.begin(); it != dirty_devices_.end();) {
      if (!PublishDevice(*it, spool_.Devices(*it), now_ms)) return;
      it = dirty_devices_.erase(it);
    }
  } catch (const std::exception& e) {
    ++counters_.spool_errors;
    LogLimited("spool_error", std::string("spool: reading the device registry: ") + e.what());
  }
}

void Gateway::PublishRecords(int64_t now_ms) {
  // Every sensor after a connect, a failed publication or when a republication may be due; else
  // only the sensors whose queue head changed (a record spooled or confirmed): at a hundred
  // sensors, reading every head on each commit ack cost more than the rest of the round trip.
  const bool all = records_dirty_ || now_ms >= next_republish_check_ms_;
  // Reading every head: the released records are deleted first. Else a sensor's released records
  // (still in the spool) are read past: its next `window` records follow them.
  if (all) FlushReleases();
  // `window` messages per sensor in flight, each of up to batch_records_ records.
  const size_t per_sensor = options_.window * batch_records_;
  std::vector<SpoolRecord> heads;
  try {
    if (all) {
      heads = spool_.Heads(per_sensor);
    } else {
      std::map<std::string, size_t> limits;
      for (const std::string& sensor : dirty_sensors_) {
        const auto pending = pending_release_.find(sensor);
        limits.emplace_hint(limits.end(), sensor, per_sensor + (pending == pending_release_.end() ? 0 : pending->second.size()));
      }
      heads = spool_.Heads(limits, pending_release_);
    }
  } catch (const std::exception& e) {
    ++counters_.spool_errors;
    LogLimited("spool_error", std::string("spool: reading records: ") + e.what());
    return;
  }
  const std::set<std::string> touched = std::move(dirty_sensors_);
  dirty_sensors_.clear();
  records_dirty_ = false;
  // Forget in-flight entries that are no longer at the head (committed or evicted).
  std::map<std::string, std::map<uint32_t, InFlight>> kept;
  int64_t next_due = now_ms + options_.republish_after_ms;
  bool all_sent = true;
  // Records to publish go out in messages of up to batch_records_ records of one sensor in seq
  // order (heads are sorted so), within the reading message's size limit. A republication (no
  // commit ack within republish_after_ms) goes alone in the one-record form: a server that lost
  // the batch form (replaced by an older one) still takes it and acks it.
  std::vector<const SpoolRecord*> group;
  size_t group_bytes = 0;
  const auto publish_group = [&] {
    if (group.empty()) return;
    const SpoolRecord& head = *group.front();
    const bool first = in_flight_[head.sensor].count(head.seq) == 0;
    std::string payload;
    if (group.size() == 1) {
      payload = head.payload;
    } else {
      std::vector<std::string_view> texts;
      texts.reserve(group.size());
      for (const SpoolRecord* r : group) texts.push_back(r->payload);
      payload = mqtt::EncodeReadingBatch(head.sensor, texts);
    }
    if (!publisher_.Publish({topics_.Reading(head.sensor), std::move(payload), 1, false})) {
      ++counters_.publish_refused;
      all_sent = false;
      if (!first) kept[head.sensor][head.seq] = in_flight_[head.sensor][head.seq];  // a republication is alone
    } else {
      for (const SpoolRecord* r : group) kept[r->sensor][r->seq] = {now_ms, r->received_ms};
      if (first) {
        counters_.published += group.size();
      } else {
        counters_.republished += group.size();
      }
      if (group.size() > 1) ++counters_.batches_published;
      last_progress_ms_ = now_ms;
    }
    group.clear();
    group_bytes = 0;
  };
  // Batch envelope: `{"records":[` ... `],"sensor":"..."}` and a comma per record.
  const auto envelope = [](const SpoolRecord& r) { return r.sensor.size() + 32; };
  for (const SpoolRecord& r : heads) {
    auto& sensor_flight = in_flight_[r.sensor];
    auto found = sensor_flight.find(r.seq);
    const bool first = found == sensor_flight.end();
    if (!first && found->second.published_ms <= now_ms && now_ms - found->second.published_ms < options_.republish_after_ms) {
      kept[r.sensor][r.seq] = found->second;
      next_due = std::min(next_due, found->second.published_ms + options_.republish_after_ms);
      continue;
    }
    if (!group.empty() && (!first || group.front()->sensor != r.sensor || group.size() >= batch_records_ ||
                           group_bytes + r.payload.size() + 1 > mqtt::kMaxReadingBytes)) {
      publish_group();
    }
    if (group.empty()) group_bytes = envelope(r);
    group.push_back(&r);
    group_bytes += r.payload.size() + 1;
    if (!first) publish_group();
  }
  publish_group();
  if (all) {
    in_flight_ = std::move(kept);
    next_republish_check_ms_ = next_due;
  } else {
    for (const std::string& sensor : touched) {
      auto k = kept.find(sensor);
      if (k == kept.end()) {
        in_flight_.erase(sensor);
      } else {
        in_flight_[sensor] = std::move(k->second);
      }
    }
    // The other sensors' in-flight records keep their due times.
    next_republish_check_ms_ = std::min(next_republish_check_ms_, next_due);
  }
  if (!all_sent) {
    records_dirty_ = true;  // retry on the next Pump
  }
}

std::string Gateway::StatsJson(int64_t now_ms) const {
  const protocol::DecoderCounters& d = decoder_.counters();
  mqtt::StatsMessage m;
  m.gateway = options_.gateway_id;
  m.time = mqtt::IsoUtc(now_ms);
  m.counters = {
      {"frames_ok", d.frames_ok},
      {"checksum_errors", d.checksum_errors},
      {"escape_errors", d.escape_errors},
      {"length_errors", d.length_errors},
      {"truncated_frames", d.truncated_frames},
      {"bytes_discarded", d.bytes_discarded},
      {"unknown_types", d.unknown_types},
      {"unknown_frames", counters_.unknown_frames},
      {"malformed_frames", counters_.malformed_frames},
      {"bad_payloads", counters_.bad_payloads},
      {"unknown_payloads", counters_.unknown_payloads},
      {"records_received", counters_.records_received},
      {"records_spooled", counters_.records_spooled},
      {"records_duplicate", counters_.records_duplicate},
      {"records_rejected", counters_.records_rejected},
      {"records_evicted", spool_.evicted()},
      {"acks_sent", counters_.acks_sent},
      {"ack_write_errors", counters_.ack_write_errors},
      {"tx_failures", counters_.tx_failures},
      {"acks_too_large", counters_.acks_too_large},
      {"oversize_frames", counters_.oversize_frames},
      {"rf_payload_limit", rf_payload_limit()},
      {"spool_errors", counters_.spool_errors},
      {"spool_depth", spool_depth()},
      {"spool_max_records", spool_.max_records()},
      {"in_flight", in_flight()},
      {"published", counters_.published},
      {"batches_published", counters_.batches_published},
      {"batch_records", batch_records_},
      {"republished", counters_.republished},
      {"publish_refused", counters_.publish_refused},
      {"link_resets", counters_.link_resets},
      {"committed", counters_.committed},
      {"bad_commit_acks", counters_.bad_commit_acks},
      {"commit_acks_ignored", counters_.commit_acks_ignored},
      {"devices", known_devices_.size()},
      {"max_devices", options_.max_devices},
      {"devices_refused", counters_.devices_refused},
      {"connects", counters_.connects},
  };
  m.latency_last_ms = counters_.latency_last_ms;
  m.latency_max_ms = counters_.latency_max_ms;
  m.latency_mean_ms = counters_.committed ? counters_.latency_sum_ms / static_cast<int64_t>(counters_.committed) : -1;
  return mqtt::EncodeStats(m);  // gateway_id may not be UTF-8: the encoder replaces, never throws
}

}  // namespace lw::gateway
