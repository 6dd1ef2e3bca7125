#include "protocol/frame_decoder.hpp"

namespace lw::protocol {
namespace {
bool IsKnownType(uint8_t t) {
  switch (static_cast<FrameType>(t)) {
    case FrameType::kAtCommand:
    case FrameType::kTransmitRequest:
    case FrameType::kAtCommandResponse:
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
  if (mode_ == ApiMode::kEscaped) return FeedEscaped(byte);
  if (queue_length_ == 0) return FeedUnescaped(byte);
  // The caller did not drain Next(): keep stream order by queueing the byte behind the others.
  if (queue_head_ + queue_length_ == sizeof(queue_)) {
    for (size_t i = 0; i < queue_length_; ++i) queue_[i] = queue_[queue_head_ + i];
    queue_head_ = 0;
  }
  if (queue_length_ < sizeof(queue_)) {
    queue_[queue_head_ + queue_length_++] = byte;
  } else {
    ++counters_.bytes_discarded;
  }
  return Next();
}

DecodeEvent FrameDecoder::Next() {
  while (queue_length_ > 0) {
    const uint8_t byte = queue_[queue_head_++];
    if (--queue_length_ == 0) queue_head_ = 0;
    const DecodeEvent ev = FeedUnescaped(byte);
    if (ev != DecodeEvent::kNone) return ev;
  }
  return DecodeEvent::kNone;
}

DecodeEvent FrameDecoder::FeedEscaped(uint8_t byte) {
  // In mode 2 a start delimiter is never escaped, so an unescaped 0x7E always begins a new frame.
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
  if (byte == kXon || byte == kXoff) {
    // Digi: in mode 2 these "must be escaped" inside a frame, sent or received, so a raw one is
    // never frame data (a flow-control byte on the line, or a sender not in mode 2). Taking it as
    // data delivered such frames whenever the checksum agreed; drop the frame instead.
    ++counters_.escape_errors;
    escape_next_ = false;
    state_ = State::kIdle;
    return DecodeEvent::kEscapeError;
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

DecodeEvent FrameDecoder::FeedUnescaped(uint8_t byte) {
  // In mode 1 a 0x7E inside a frame is legal data: only an idle decoder starts a frame on it.
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
  if (ev == DecodeEvent::kChecksumError || ev == DecodeEvent::kLengthError) Requeue();
  return ev;
}

void FrameDecoder::Requeue() {
  size_t start = 0;
  while (start < raw_length_ && raw_[start] != kStartDelimiter) ++start;
  const size_t n = raw_length_ - start;
  raw_length_ = 0;
  if (n == 0) return;
  counters_.bytes_discarded += start;
  // New queue: raw_[start..] then what was queued. Never longer than one frame when the caller
  // drains Next() (the failed frame's bytes came from the queue or the queue was empty); a
  // caller that does not may lose the excess, counted as discarded.
  size_t keep = queue_length_;
  if (n + keep > sizeof(queue_)) {
    counters_.bytes_discarded += n + keep - sizeof(queue_);
    keep = sizeof(queue_) - n;
  }
  for (size_t i = 0; i < keep; ++i) queue_[i] = queue_[queue_head_ + i];  // to the front
  for (size_t i = keep; i-- > 0;) queue_[i + n] = queue_[i];              // make room
  for (size_t i = 0; i < n; ++i) queue_[i] = raw_[start + i];
  queue_head_ = 0;
  queue_length_ = n + keep;
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
