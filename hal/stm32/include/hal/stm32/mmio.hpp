#pragma once
/// Register access for the STM32 drivers. Every driver takes its register accesses through an
/// `Io` policy: `Mmio` (volatile loads and stores, the MCU) or a register-level fake in host tests
/// (tests/unit/hal/test_stm32_spi.cpp), which models the peripheral behind the addresses.
#include <cstdint>

namespace lw::hal::stm32 {

struct Mmio {
  static uint32_t Read32(uintptr_t addr) { return *reinterpret_cast<volatile uint32_t*>(addr); }
  static void Write32(uintptr_t addr, uint32_t v) { *reinterpret_cast<volatile uint32_t*>(addr) = v; }
  /// Byte accesses: the L4 SPI packs two 8-bit frames into one 16-bit access of DR, so its 8-bit
  /// frames must be written and read as bytes.
  static uint8_t Read8(uintptr_t addr) { return *reinterpret_cast<volatile uint8_t*>(addr); }
  static void Write8(uintptr_t addr, uint8_t v) { *reinterpret_cast<volatile uint8_t*>(addr) = v; }
};

/// Bounded polling: every wait on a status flag gives up after `kSpinLimit` reads, so a
/// peripheral that never answers (absent, unclocked, or not modelled by QEMU) makes the driver
/// report a failure instead of hanging the board until the watchdog bites.
inline constexpr uint32_t kSpinLimit = 100000;

template <class Io>
bool WaitSet(uintptr_t addr, uint32_t mask, uint32_t limit = kSpinLimit) {
  for (uint32_t i = 0; i < limit; ++i)
    if ((Io::Read32(addr) & mask) == mask) return true;
  return false;
}

template <class Io>
bool WaitClear(uintptr_t addr, uint32_t mask, uint32_t limit = kSpinLimit) {
  for (uint32_t i = 0; i < limit; ++i)
    if ((Io::Read32(addr) & mask) == 0) return true;
  return false;
}

}  // namespace lw::hal::stm32
