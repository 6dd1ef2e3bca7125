#pragma once
#include <cstddef>
#include <cstdint>

namespace lw::hal {

/// Serial port to the radio module. The port buffers received bytes (ISR -> ring buffer); the
/// application drains them from its task loop. Not ISR-safe.
class Uart {
 public:
  /// Queues `len` bytes for transmission; returns how many were accepted (may be fewer when the
  /// transmit buffer is full). Non-blocking.
  size_t Write(const uint8_t* data, size_t len) { return DoWrite(data, len); }
  /// Copies up to `cap` received bytes into `out`; returns the count (0 when none). Non-blocking.
  size_t Read(uint8_t* out, size_t cap) { return DoRead(out, cap); }

 protected:
  ~Uart() = default;

 private:
  virtual size_t DoWrite(const uint8_t* data, size_t len) = 0;
  virtual size_t DoRead(uint8_t* out, size_t cap) = 0;
};

}  // namespace lw::hal
