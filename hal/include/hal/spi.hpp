#pragma once
#include <cstddef>
#include <cstdint>

namespace lw::hal {

/// SPI controller with the ladder's chip select handled by the port. Blocking; not ISR-safe.
class Spi {
 public:
  /// Full-duplex transfer of `len` bytes (`tx` may be null: 0x00 is clocked out). Asserts chip
  /// select (for parallel-in shift registers: latches the inputs) for the whole transfer.
  /// Returns false when the bus reports an error or times out.
  bool Transfer(const uint8_t* tx, uint8_t* rx, size_t len) { return DoTransfer(tx, rx, len); }

 protected:
  ~Spi() = default;

 private:
  virtual bool DoTransfer(const uint8_t* tx, uint8_t* rx, size_t len) = 0;
};

}  // namespace lw::hal
