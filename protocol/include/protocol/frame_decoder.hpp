#pragma once
/// Incremental XBee API frame decoder: feed bytes as they arrive from a UART; it reports each
/// complete, checksum-valid frame, resynchronises on the next 0x7E after any error, and counts
/// each kind of error. Freestanding, fixed buffer, no allocation. Not thread-safe; call from one
/// context (on an MCU: the task loop, not the UART ISR).
#include <cstddef>
#include <cstdint>

#include "protocol/xbee_api.hpp"

namespace lw::protocol {

/// Per-kind error and traffic counters. Monotonic until Reset(); 64-bit: noise on a serial line at
/// 115200 Bd would wrap a 32-bit bytes_discarded within 5 days, inside a campaign.
struct DecoderCounters {
  uint64_t frames_ok = 0;
  uint64_t bytes_discarded = 0;  ///< bytes outside any frame (garbage before a delimiter)
  uint64_t checksum_errors = 0;
  uint64_t escape_errors = 0;     ///< mode 2: 0x7D followed by 0x7E, or a raw 0x11 / 0x13 inside a frame
  uint64_t length_errors = 0;     ///< declared length 0 or above kMaxFrameData
  uint64_t truncated_frames = 0;  ///< a new delimiter arrived before the frame was complete (mode 2)
  uint64_t unknown_types = 0;     ///< valid frame whose API identifier is not a FrameType (still delivered)
};

enum class DecodeEvent : uint8_t {
  kNone = 0,  ///< byte consumed, no complete frame yet
  kFrame,     ///< a valid frame is available through frame_data()/frame_length()
  kChecksumError,
  kEscapeError,
  kLengthError,
  kTruncated,
};

class FrameDecoder {
 public:
  explicit FrameDecoder(ApiMode mode) : mode_(mode) {}

  /// Consumes one byte and returns the first event it completes. One byte can complete more than
  /// one frame (API mode 1: a frame cut short by a new delimiter is only noticed when its checksum
  /// fails, and the bytes it swallowed are then decoded again): call Next() until it returns
  /// kNone before the next Feed(), or use Feed(data, len, on_event), which does.
  /// After kFrame, frame_data()/frame_length() stay valid until the next Feed() or Next().
  DecodeEvent Feed(uint8_t byte);

  /// The next event from bytes already fed (kNone when there is none; always kNone in mode 2).
  DecodeEvent Next();

  /// Feeds `len` bytes and calls `on_event(DecodeEvent)` for every event in stream order
  /// (frame_data() holds the frame during a kFrame call).
  template <typename OnEvent>
  void Feed(const uint8_t* data, size_t len, OnEvent&& on_event) {
    for (size_t i = 0; i < len; ++i) {
      for (DecodeEvent ev = Feed(data[i]); ev != DecodeEvent::kNone; ev = Next()) on_event(ev);
    }
  }

  /// Frame data of the last complete frame: API identifier first, without length and checksum.
  const uint8_t* frame_data() const { return buffer_; }
  size_t frame_length() const { return frame_length_; }
  /// API identifier of the last complete frame.
  uint8_t frame_type() const { return frame_length_ ? buffer_[0] : 0; }

  const DecoderCounters& counters() const { return counters_; }
  void ResetCounters() { counters_ = DecoderCounters{}; }
  ApiMode mode() const { return mode_; }

 private:
  enum class State : uint8_t { kIdle, kLengthHigh, kLengthLow, kData, kChecksum };
  static constexpr size_t kRawCapacity = kMaxFrameData + 3;  // length (2), data, checksum
  DecodeEvent Accept(uint8_t byte);                          // one unescaped byte
  DecodeEvent FeedEscaped(uint8_t byte);
  DecodeEvent FeedUnescaped(uint8_t byte);
  // API mode 1 only: after a checksum or length error the bytes of the failed frame may hold the
  // start of the next frame (the failed one was truncated); queue them again from the next 0x7E,
  // ahead of anything still queued.
  void Requeue();

  ApiMode mode_;
  State state_ = State::kIdle;
  bool escape_next_ = false;
  uint16_t expected_ = 0;
  size_t received_ = 0;
  size_t frame_length_ = 0;
  uint8_t sum_ = 0;
  uint8_t buffer_[kMaxFrameData] = {};
  uint8_t raw_[kRawCapacity] = {};  // mode 1: bytes after the delimiter of the current frame
  size_t raw_length_ = 0;
  // Mode 1: bytes to decode again (never more than one frame's worth when Next() is drained).
  uint8_t queue_[kRawCapacity] = {};
  size_t queue_head_ = 0;
  size_t queue_length_ = 0;
  DecoderCounters counters_;
};

}  // namespace lw::protocol
