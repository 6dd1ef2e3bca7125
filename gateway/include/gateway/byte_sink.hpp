#pragma once
/// Where the gateway writes frames for the radio (acks to sensors). Implemented by SerialPort.
#include <cstddef>
#include <cstdint>

namespace lw::gateway {

class ByteSink {
 public:
  virtual ~ByteSink() = default;
  /// Writes all bytes or returns false. May block briefly (bounded) while the port drains.
  virtual bool Write(const uint8_t* data, size_t len) = 0;
};

}  // namespace lw::gateway
