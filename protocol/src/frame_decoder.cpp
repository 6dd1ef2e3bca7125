#include "protocol/frame_decoder.hpp"

namespace lw::protocol {
namespace {
bool IsKnownType(uint8_t t) {
  switch (static_cast<FrameType>(t)) {
    case FrameType::kTransmitRequest:
    case FrameType::kModemStatus:
    case FrameType::kTransmitStatus:
    case FrameType::kReceivePacket:
    case FrameType::kNodeIdentification:
      return true;
  }
  return false;
}
}  // namespace

DecodeEvent FrameDecoder::Feed(uint8_t byte) {
  // A start delimiter always begins a new frame: in mode 2 it can never appear escaped, and in
  // mode 1 a 0x7E inside a frame is only legal as data, so only treat it as a restart while idle
  // (mode 1) or anywhere (mode 2).
  if (mode_ == ApiMode::kEscaped) {
    if (byte == kStartDelimiter) {
      DecodeEvent ev = DecodeEvent::kNone;
      if (escape_next_) {
        ++counters_.escape_errors;
        ev = DecodeEvent::kEscapeError;
      } else if (state_ != State::kIdle) {
        ++counters_.truncated_frames;
        ev = DecodeEvent::kTruncated;
      }
      escape_next_ = false;
      state_ = State::kLengthHigh;
      return ev;
    }
    if (state_ == State::kIdle) {
      ++counters_.bytes_discarded;
      return DecodeEvent::kNone;
    }
    if (escape_next_) {
      escape_next_ = false;
      return Accept(static_cast<uint8_t>(byte ^ kEscapeXor));
    }
    if (byte == kEscape) {
      escape_next_ = true;
      return DecodeEvent::kNone;
    }
    return Accept(byte);
  }
  return FeedUnescaped(byte);
}

DecodeEvent FrameDecoder::FeedUnescaped(uint8_t byte) {
  if (state_ == State::kIdle) {
    if (byte == kStartDelimiter) {
      state_ = State::kLengthHigh;
      raw_length_ = 0;
    } else {
      ++counters_.bytes_discarded;
    }
    return DecodeEvent::kNone;
  }
  if (raw_length_ < sizeof(raw_)) raw_[raw_length_++] = byte;
  const DecodeEvent ev = Accept(byte);
  if ((ev == DecodeEvent::kChecksumError || ev == DecodeEvent::kLengthError) && !replaying_) {
    return Resync(ev);
  }
  return ev;
}

DecodeEvent FrameDecoder::Resync(DecodeEvent error) {
  // Copy out: replaying refills raw_.
  uint8_t pending[sizeof(raw_)];
  const size_t n = raw_length_;
  for (size_t i = 0; i < n; ++i) pending[i] = raw_[i];
  size_t start = 0;
  while (start < n && pending[start] != kStartDelimiter) ++start;
  if (start == n) return error;
  counters_.bytes_discarded += static_cast<uint32_t>(start);
  replaying_ = true;
  DecodeEvent last = error;
  for (size_t i = start; i < n; ++i) {
    const DecodeEvent ev = FeedUnescaped(pending[i]);
    if (ev == DecodeEvent::kFrame && i + 1 == n) last = ev;
  }
  replaying_ = false;
  return last;
}

DecodeEvent FrameDecoder::Accept(uint8_t byte) {
  switch (state_) {
    case State::kIdle:
      return DecodeEvent::kNone;
    case State::kLengthHigh:
      expected_ = static_cast<uint16_t>(byte << 8);
      state_ = State::kLengthLow;
      return DecodeEvent::kNone;
    case State::kLengthLow:
      expected_ = static_cast<uint16_t>(expected_ | byte);
      if (expected_ == 0 || expected_ > kMaxFrameData) {
        ++counters_.length_errors;
        state_ = State::kIdle;
        return DecodeEvent::kLengthError;
      }
      received_ = 0;
      sum_ = 0;
      frame_length_ = 0;
      state_ = State::kData;
      return DecodeEvent::kNone;
    case State::kData:
      buffer_[received_++] = byte;
      sum_ = static_cast<uint8_t>(sum_ + byte);
      if (received_ == expected_) state_ = State::kChecksum;
      return DecodeEvent::kNone;
    case State::kChecksum:
      state_ = State::kIdle;
      if (static_cast<uint8_t>(sum_ + byte) != 0xFF) {
        ++counters_.checksum_errors;
        return DecodeEvent::kChecksumError;
      }
      frame_length_ = received_;
      ++counters_.frames_ok;
      if (!IsKnownType(buffer_[0])) ++counters_.unknown_types;
      return DecodeEvent::kFrame;
  }
  return DecodeEvent::kNone;
}

}  // namespace lw::protocol
