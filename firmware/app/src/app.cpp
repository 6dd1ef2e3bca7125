#include "firmware/app.hpp"

#include "protocol/xbee_api.hpp"

namespace lw::firmware {
namespace {
constexpr uint16_t kFaultFlags =
    protocol::kFlagLoopHealed | protocol::kFlagNonContiguous | protocol::kFlagAllOpen | protocol::kFlagSpiStuck;
/// Records per frame at most (Transmit's fixed arrays): a 1-loop ladder on an 84-byte link.
constexpr size_t kMaxRecordsPerFrame = 8;
static_assert(protocol::MaxRecordsPerPayload(1, protocol::kMaxRfPayload) <= kMaxRecordsPerFrame,
              "Transmit's arrays hold a frame of the smallest ladder on the largest link");
static_assert(protocol::MaxRecordsPerPayload(protocol::kMaxLadderLoops, protocol::kMinRfPayload) >= 1,
              "a record of any ladder fits the smallest supported NP: no frame ever needs fragmentation");
}  // namespace

App::App(const Config& config, const hal::Board& board)
    : config_(config),
      board_(board),
      decoder_(config.api_mode),
      store_(board.flash, 0),
      jitter_state_(config.sensor_id * 2654435761u | 1u) {}

void App::Init() {
  board_.watchdog.Start(config_.watchdog_timeout_s);
  PersistentState loaded;
  if (store_.Load(&loaded)) {
    state_ = loaded;
    // A board re-provisioned for another ladder keeps its seq and drop count (a seq must never
    // repeat for this sensor id) but not the thickness, which belonged to the old ladder.
    if (state_.ladder_loops != config_.ladder_loops) state_.reported_loops = 0xFF;
  } else {
    state_ = PersistentState{};
  }
  state_.ladder_loops = config_.ladder_loops;
  // Resume above every seq that may have been used before the reset, then reserve a new block.
  next_seq_ = state_.seq_reserved_until;
  reported_loops_ = state_.reported_loops;
  dropped_before_boot_ = state_.dropped_total;  // the count covers the board's life, not one boot
  state_.boots++;
  pending_flags_ = protocol::kFlagBoot;
  if (board_.power.LastResetCause() == hal::ResetCause::kWatchdog) pending_flags_ |= protocol::kFlagWatchdogReset;
  durable_seq_limit_ = next_seq_;  // nothing reserved by this boot yet
  state_.seq_reserved_until = next_seq_ + config_.seq_reserve_block;
  dirty_ = true;
  Persist();
  QueryRadio();
}

size_t App::rf_payload_limit() const {
  if (force_min_payload_) return protocol::kMinRfPayload;
  return protocol::ClampRfPayload(protocol::RfPayloadLimit(radio_np_, radio_ee_));
}

void App::QueryRadio() {
  // Until both answers are in, frames are sized for the smallest NP: never above the link's limit.
  radio_np_ = -1;
  radio_ee_ = -1;
  const char* commands[2] = {"NP", "EE"};
  uint8_t* ids[2] = {&np_query_id_, &ee_query_id_};
  for (int i = 0; i < 2; ++i) {
    protocol::AtCommand cmd;
    frame_id_ = protocol::NextFrameId(frame_id_);
    cmd.frame_id = frame_id_;
    cmd.command[0] = commands[i][0];
    cmd.command[1] = commands[i][1];
    uint8_t wire[16];
    const size_t n = protocol::EncodeAtCommand(config_.api_mode, cmd, wire, sizeof wire);
    if (n == 0) continue;
    board_.radio.Write(wire, n);
    *ids[i] = frame_id_;
  }
  ++stats_.radio_queries;
}

bool App::HandleRadioAnswer(const uint8_t* data, size_t len) {
  protocol::AtCommandResponse rsp;
  if (protocol::ParseAtCommandResponse(data, len, &rsp) != protocol::Status::kOk) return false;
  uint64_t value = 0;
  const bool ok = rsp.Value(&value);
  if (rsp.frame_id != 0 && rsp.frame_id == np_query_id_) {
    np_query_id_ = 0;
    radio_np_ = ok && value <= 0xFF ? static_cast<int>(value) : -1;
    if (radio_np_ >= 0 && protocol::RfPayloadLimit(radio_np_, 0) < protocol::kMinRfPayload) ++stats_.np_below_minimum;
  } else if (rsp.frame_id != 0 && rsp.frame_id == ee_query_id_) {
    ee_query_id_ = 0;
    radio_ee_ = ok ? static_cast<int>(value != 0) : -1;
  }
  return true;
}

uint16_t App::reported_thickness_dmm() const {
  if (reported_loops_ == 0xFF) return 0xFFFF;
  return static_cast<uint16_t>(config_.base_offset_dmm + reported_loops_ * config_.loop_pitch_dmm);
}

uint16_t App::DroppedTotal16() const {
  const uint32_t total = dropped_total();
  return static_cast<uint16_t>(total > 0xFFFF ? 0xFFFF : total);
}

bool App::TakeSeq(uint32_t* seq) {
  // A seq may only go out when a durable reservation covers it: after a reset the board resumes
  // at the saved block end, so an unsaved reservation could hand the same seq out twice (and the
  // gateway would discard the second record as a duplicate).
  if (next_seq_ >= durable_seq_limit_) {
    state_.seq_reserved_until = next_seq_ + config_.seq_reserve_block;
    dirty_ = true;
    Persist();
    if (dirty_) return false;  // not saved: no record this wake, retried on the next one
  }
  *seq = next_seq_++;
  return true;
}

void App::Persist() {
  if (!dirty_) return;
  state_.reported_loops = reported_loops_;
  state_.dropped_total = DroppedTotal16();
  if (store_.Save(&state_)) {
    dirty_ = false;
    durable_seq_limit_ = state_.seq_reserved_until;
  } else {
    ++stats_.flash_errors;
  }
}

uint32_t App::Backoff(uint8_t attempts) {
  uint32_t delay = config_.backoff_min_s;
  for (uint8_t i = 1; i < attempts && delay < config_.backoff_max_s; ++i) delay *= 2;
  if (delay > config_.backoff_max_s) delay = config_.backoff_max_s;
  // Boards that lost the gateway together must not all retry at the same second when it returns:
  // take off up to a quarter of the delay, pseudo-random per board (xorshift32 seeded by the id).
  jitter_state_ ^= jitter_state_ << 13;
  jitter_state_ ^= jitter_state_ >> 17;
  jitter_state_ ^= jitter_state_ << 5;
  return delay - jitter_state_ % (delay / 4 + 1);
}

void App::Enqueue(uint32_t now, const LadderSample& sample, uint16_t flags, bool heartbeat) {
  QueuedRecord q;
  q.heartbeat = heartbeat;
  q.sampled_at_s = now;
  q.next_try_s = now;
  StoredRecord& r = q.record;
  // A record is queued only once the state it reflects (reported thickness, seq reservation) is
  // in flash; otherwise a reset could bring back an older thickness or hand its seq out again.
  Persist();
  if (dirty_ || !TakeSeq(&r.seq)) {
    // Keep what this record would have carried for the next attempt.
    pending_flags_ = static_cast<uint16_t>(pending_flags_ | (flags & ~protocol::kFlagHeartbeat));
    if (!heartbeat) retry_record_ = true;
    return;
  }
  retry_record_ = false;
  r.loops_intact = reported_loops_ == 0xFF ? 0 : reported_loops_;
  r.thickness_dmm = reported_thickness_dmm() == 0xFFFF ? 0 : reported_thickness_dmm();
  r.flags = static_cast<uint16_t>(flags | pending_flags_ | (heartbeat ? protocol::kFlagHeartbeat : 0));
  if (dropped_total() > 0) r.flags |= protocol::kFlagDropped;
  int32_t mv = 0, temp = 0;
  if (board_.adc.Read(hal::AdcChannel::kBatteryMillivolts, &mv)) {
    r.battery_mv = static_cast<uint16_t>(mv < 0 ? 0 : (mv > 0xFFFF ? 0xFFFF : mv));
    if (mv < config_.low_battery_mv) r.flags |= protocol::kFlagLowBattery;
  }
  if (board_.adc.Read(hal::AdcChannel::kTemperatureCelsius, &temp)) {
    r.temperature_c = static_cast<int8_t>(temp < -128 ? -128 : (temp > 127 ? 127 : temp));
  }
  for (size_t i = 0; i < protocol::kMaxBitmapBytes; ++i) r.loop_bitmap[i] = sample.intact[i];
  pending_flags_ = 0;
  const uint32_t dropped_before = queue_.dropped_total();
  queue_.Push(q);
  if (queue_.dropped_total() != dropped_before) dirty_ = true;
  ++stats_.records_queued;
  last_queued_s_ = now;
  have_queued_ = true;
}

void App::Sample(uint32_t now) {
  const LadderSample s = ReadLadder(board_.ladder_spi, board_.ladder_power, config_.votes_per_poll, config_.ladder_loops);
  uint16_t flags = s.flags;
  bool changed = false;
  // Every loop open at once is a cut cable or a dead chain, not wear, unless only the last loop
  // was left: then the sensor is consumed. Otherwise the thickness holds (flagged all_open), so a
  // cable that comes back does not leave the sensor stuck at 0 mm for the rest of the campaign.
  const bool all_open_fault = (s.flags & protocol::kFlagAllOpen) && (reported_loops_ == 0xFF || reported_loops_ > 1);
  if (s.valid && !all_open_fault) {
    if (reported_loops_ == 0xFF || s.loops_intact < reported_loops_) {
      reported_loops_ = s.loops_intact;
      changed = true;
      dirty_ = true;
    } else if (s.loops_intact > reported_loops_ && !(s.flags & protocol::kFlagFlicker)) {
      flags |= protocol::kFlagLoopHealed;  // never reported: wear is irreversible
    }
  }
  const uint16_t faults = flags & kFaultFlags;
  if (faults) ++stats_.ladder_faults;
  // No record before the first valid sample: a thickness of "unknown" would read as 0 mm
  // downstream. The boot flag and any fault ride on the first valid record.
  if (reported_loops_ == 0xFF) {
    pending_flags_ = static_cast<uint16_t>(pending_flags_ | faults);
    return;
  }
  const bool new_fault = (faults & ~last_fault_flags_) != 0;
  last_fault_flags_ = faults;
  const bool heartbeat_due = !have_queued_ || now - last_queued_s_ >= config_.heartbeat_period_s;
  if (changed || new_fault || pending_flags_ || retry_record_) {
    Enqueue(now, s, flags, false);
  } else if (heartbeat_due) {
    Enqueue(now, s, flags, true);
  }
}

void App::Transmit(uint32_t now) {
  // Sized to the radio's unfragmented payload (NP, EE): a fragmented frame is lost whole when one
  // fragment is, and a parent buffers few packets for a sleeping end device.
  const size_t rf_limit = rf_payload_limit();
  const size_t per_frame = protocol::MaxRecordsPerPayload(config_.ladder_loops, rf_limit);
  size_t due[kMaxRecordsPerFrame];
  const size_t max = per_frame < kMaxRecordsPerFrame ? per_frame : kMaxRecordsPerFrame;
  // Send every due record this wake, several per frame.
  for (int guard = 0; guard < kQueueCapacity; ++guard) {
    const size_t n = queue_.Due(now, due, max);
    if (n == 0) return;
    protocol::SensorRecord recs[kMaxRecordsPerFrame];
    for (size_t i = 0; i < n; ++i) {
      QueuedRecord& q = queue_.at(due[i]);
      recs[i] = q.ToSensorRecord(now);
      ++q.attempts;
      q.next_try_s = now + Backoff(q.attempts);
    }
    protocol::ReadingsHeader h;
    h.sensor_id = config_.sensor_id;
    h.ladder_loops = config_.ladder_loops;
    h.dropped_total = DroppedTotal16();
    uint8_t payload[protocol::kMaxRfPayload];
    size_t plen = 0;
    if (protocol::EncodeReadings(h, recs, n, payload, rf_limit, &plen) != protocol::PayloadStatus::kOk) return;
    protocol::TransmitRequest req;
    frame_id_ = protocol::NextFrameId(frame_id_);
    req.frame_id = frame_id_;
    req.dest64 = config_.coordinator_address64;
    req.payload = payload;
    req.payload_len = plen;
    uint8_t wire[protocol::kMaxWireFrame];
    const size_t wlen = protocol::EncodeTransmitRequest(config_.api_mode, req, wire, sizeof wire);
    if (wlen == 0) return;
    board_.radio.Write(wire, wlen);
    ++stats_.frames_sent;
    DrainRadio();  // an ack may already be there; it frees queue slots
  }
}

void App::HandleFrame() {
  const uint8_t* data = decoder_.frame_data();
  const size_t len = decoder_.frame_length();
  protocol::TransmitStatus st;
  if (protocol::ParseTransmitStatus(data, len, &st) == protocol::Status::kOk) {
    if (st.delivery_status != 0) ++stats_.tx_status_failures;
    if (st.delivery_status == static_cast<uint8_t>(protocol::DeliveryStatus::kDataPayloadTooLarge)) {
      // The link carries less than NP and EE said (source routing, APS): the smallest size from
      // now until the next join, which asks again.
      ++stats_.frames_too_large;
      force_min_payload_ = true;
    }
    return;
  }
  if (HandleRadioAnswer(data, len)) return;
  protocol::ModemStatus ms;
  if (protocol::ParseModemStatus(data, len, &ms) == protocol::Status::kOk) {
    // A (re)join may come with other security settings: ask again.
    if (ms.status == static_cast<uint8_t>(protocol::ModemStatusCode::kJoinedNetwork)) {
      force_min_payload_ = false;
      QueryRadio();
    }
    return;
  }
  protocol::ReceivePacket rx;
  if (protocol::ParseReceivePacket(data, len, &rx) != protocol::Status::kOk) return;
  protocol::Ack ack;
  if (protocol::DecodeAck(rx.payload, rx.payload_len, &ack) != protocol::PayloadStatus::kOk) return;
  if (ack.sensor_id != config_.sensor_id) return;
  for (size_t i = 0; i < ack.count; ++i) {
    if (queue_.Ack(ack.seqs[i])) ++stats_.records_acked;
  }
}

void App::DrainRadio() {
  uint8_t buf[64];
  for (;;) {
    const size_t n = board_.radio.Read(buf, sizeof buf);
    if (n == 0) return;
    decoder_.Feed(buf, n, [this](protocol::DecodeEvent event) {
      if (event == protocol::DecodeEvent::kFrame) HandleFrame();
    });
  }
}

uint32_t App::Step() {
  ++stats_.wakes;
  const uint32_t now = board_.rtc.NowSeconds();
  DrainRadio();
  Sample(now);  // queues a record only after the state it reflects is saved (see Enqueue)
  Transmit(now);
  DrainRadio();
  Persist();
  board_.watchdog.Kick();
  uint32_t next = now + config_.poll_period_s;
  const uint32_t due = queue_.NextDue();
  if (due > now && due < next) next = due;
  board_.rtc.SetAlarm(next);
  return next;
}

void App::RunOnce() {
  Step();
  board_.power.Sleep();
}

}  // namespace lw::firmware
