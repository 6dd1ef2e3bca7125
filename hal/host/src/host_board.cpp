#include "hal/host/host_board.hpp"

#include <algorithm>

namespace lw::hal::host {

HostLadder::HostLadder(uint8_t loops) : loops_(loops), intact_(loops, true) {}

void HostLadder::SetIntactCount(uint8_t n) {
  for (uint8_t i = 0; i < loops_; ++i) intact_[i] = i < n;
}
void HostLadder::SetLoop(uint8_t index, bool intact) {
  if (index < loops_) intact_[index] = intact;
}
bool HostLadder::Loop(uint8_t index) const {
  return index < loops_ && intact_[index];
}

bool HostLadder::DoTransfer(const uint8_t* /*tx*/, uint8_t* rx, size_t len) {
  ++transfers_;
  if (transfer_fails_) return false;
  if (fail_next_ > 0) {
    --fail_next_;
    return false;
  }
  const size_t data_bytes = (loops_ + 7u) / 8u;
  for (size_t i = 0; i < len; ++i) {
    uint8_t byte = 0;
    if (stuck_byte_ >= 0) {
      byte = static_cast<uint8_t>(stuck_byte_);
    } else if (i < data_bytes) {
      for (size_t b = 0; b < 8; ++b) {
        const size_t loop = i * 8 + b;
        if (loop >= loops_) break;
        bool on = intact_[loop];
        if (static_cast<int>(loop) == flicker_loop_) on = flicker_phase_;
        if (on) byte = static_cast<uint8_t>(byte | (1u << b));
      }
    } else if (i == data_bytes) {
      byte = kLadderSignature;
    }
    rx[i] = byte;
  }
  flicker_phase_ = !flicker_phase_;
  return true;
}

bool HostAdc::DoRead(AdcChannel channel, int32_t* value) {
  switch (channel) {
    case AdcChannel::kBatteryMillivolts:
      *value = battery_mv_;
      return true;
    case AdcChannel::kTemperatureCelsius:
      *value = temperature_c_;
      return true;
  }
  return false;
}

void HostPower::DoSleep() {
  ++sleeps_;
  if (rtc_.alarm_armed() && rtc_.alarm() > rtc_.now()) rtc_.Set(rtc_.alarm());
}

HostFlash::HostFlash(size_t page_size, size_t page_count)
    : page_size_(page_size), pages_(page_count, std::vector<uint8_t>(page_size, 0xFF)) {}

bool HostFlash::Spend() {
  if (power_lost_) return false;
  if (budget_ == 0) {
    power_lost_ = true;
    return false;
  }
  if (budget_ > 0) --budget_;
  ++work_bytes_;
  return true;
}

uint8_t HostFlash::TearBits() {
  tear_state_ ^= tear_state_ << 13;
  tear_state_ ^= tear_state_ >> 17;
  tear_state_ ^= tear_state_ << 5;
  return static_cast<uint8_t>(tear_state_ >> 11);
}

bool HostFlash::DoErase(size_t page) {
  if (page >= pages_.size() || power_lost_) return false;
  ++erases_;
  for (auto& b : pages_[page]) {
    if (!Spend()) {
      if (tear_) {
        for (auto& c : pages_[page]) c |= TearBits();  // every cell part-way to erased
      }
      return false;
    }
    b = 0xFF;
  }
  return true;
}

bool HostFlash::DoProgram(size_t page, size_t offset, const uint8_t* data, size_t len) {
  if (page >= pages_.size() || offset + len > page_size_ || power_lost_) return false;
  for (size_t i = 0; i < len; ++i) {
    if (!Spend()) {
      if (tear_) pages_[page][offset + i] &= static_cast<uint8_t>(data[i] | TearBits());  // some bits programmed
      return false;
    }
    pages_[page][offset + i] &= data[i];
  }
  return true;
}

bool HostFlash::DoRead(size_t page, size_t offset, uint8_t* data, size_t len) {
  if (page >= pages_.size() || offset + len > page_size_) return false;
  std::copy_n(pages_[page].begin() + static_cast<long>(offset), len, data);
  return true;
}

HostRadio::HostRadio(uint64_t address64, protocol::ApiMode mode) : address64_(address64), mode_(mode), decoder_(mode) {}

size_t HostRadio::rf_payload_limit() const {
  return protocol::RfPayloadLimit(np_, ee_);
}

size_t HostRadio::DoWrite(const uint8_t* data, size_t len) {
  if (power_good_ && !power_good_()) {
    bytes_lost_to_brownout_ += len;
    return len;
  }
  decoder_.Feed(data, len, [&](protocol::DecodeEvent event) {
    if (event != protocol::DecodeEvent::kFrame) return;
    protocol::TransmitRequest req;
    if (protocol::ParseTransmitRequest(decoder_.frame_data(), decoder_.frame_length(), &req) == protocol::Status::kOk) {
      Transmit(req);
      return;
    }
    protocol::AtCommand cmd;
    if (protocol::ParseAtCommand(decoder_.frame_data(), decoder_.frame_length(), &cmd) == protocol::Status::kOk) AnswerAt(cmd);
  });
  return len;
}

void HostRadio::Transmit(const protocol::TransmitRequest& req) {
  ++transmit_requests_;
  largest_payload_ = std::max(largest_payload_, req.payload_len);
  // Copy: delivering may inject frames, which must not disturb this request's bytes.
  std::vector<uint8_t> payload(req.payload, req.payload + req.payload_len);
  const uint8_t frame_id = req.frame_id;
  const bool too_large = payload.size() > rf_payload_limit();
  const bool ok = (link_check_ ? link_check_() : link_up_) && !too_large;
  if (too_large) ++refused_too_large_;
  if (ok) {
    ++delivered_;
    if (on_deliver_) on_deliver_(address64_, payload.data(), payload.size());
  }
  if (frame_id == 0) return;
  protocol::TransmitStatus st;
  st.frame_id = frame_id;
  st.dest16 = 0x0000;
  st.delivery_status = ok          ? uint8_t{0x00}
                       : too_large ? static_cast<uint8_t>(protocol::DeliveryStatus::kDataPayloadTooLarge)
                                   : static_cast<uint8_t>(protocol::DeliveryStatus::kNetworkAckFailure);
  uint8_t frame[16];
  size_t n = 0;
  if (protocol::BuildTransmitStatus(st, frame, sizeof frame, &n) == protocol::Status::kOk) QueueFrame(frame, n);
}

void HostRadio::AnswerAt(const protocol::AtCommand& cmd) {
  ++at_queries_;
  if (!answers_at_ || cmd.frame_id == 0) return;
  uint8_t frame[16];
  size_t n = 0;
  if (protocol::BuildRadioSettingsAnswer(cmd, np_, ee_, frame, sizeof frame, &n) == protocol::Status::kOk) QueueFrame(frame, n);
}

void HostRadio::Inject(const uint8_t* payload, size_t len) {
  const protocol::ReceivePacket rx{protocol::kCoordinatorAddress64, 0x0000, 0x01, payload, len};
  uint8_t wire[protocol::kMaxWireFrame];
  const size_t n = protocol::EncodeReceivePacket(mode_, rx, wire, sizeof wire);
  to_mcu_.insert(to_mcu_.end(), wire, wire + n);
}

void HostRadio::QueueFrame(const uint8_t* frame_data, size_t len) {
  uint8_t wire[protocol::kMaxWireFrame];
  const size_t n = protocol::EncodeFrame(mode_, frame_data, len, wire, sizeof wire);
  to_mcu_.insert(to_mcu_.end(), wire, wire + n);
}

size_t HostRadio::DoRead(uint8_t* out, size_t cap) {
  size_t n = 0;
  while (n < cap && !to_mcu_.empty()) {
    out[n++] = to_mcu_.front();
    to_mcu_.pop_front();
  }
  return n;
}

HostBoard::HostBoard(uint8_t ladder_loops, uint64_t radio_address64, protocol::ApiMode mode, size_t flash_page_size,
                     size_t flash_pages)
    : ladder(ladder_loops), radio(radio_address64, mode), power(rtc), watchdog(rtc), flash(flash_page_size, flash_pages) {
  radio.set_power_good([this] { return !flash.power_lost(); });
}

Board HostBoard::board() {
  return Board{ladder, ladder_power, radio, adc, rtc, power, watchdog, flash};
}

}  // namespace lw::hal::host
