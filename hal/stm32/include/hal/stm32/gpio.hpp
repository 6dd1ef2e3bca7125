#pragma once
/// GPIO pin configuration and output (same registers on STM32F4 and STM32L4). The port's RCC code
/// enables the GPIO clock before these are used.
#include "hal/gpio.hpp"
#include "hal/stm32/mmio.hpp"
#include "hal/stm32/regs.hpp"

namespace lw::hal::stm32 {

template <class Io = Mmio>
void ConfigurePin(uintptr_t port, uint32_t pin, gpio::Mode mode, uint32_t alternate = 0) {
  const uint32_t shift = pin * 2u;
  Io::Write32(port + gpio::kModer, (Io::Read32(port + gpio::kModer) & ~(3u << shift)) | (static_cast<uint32_t>(mode) << shift));
  const uintptr_t afr = port + (pin < 8 ? gpio::kAfrl : gpio::kAfrh);
  const uint32_t af_shift = (pin % 8u) * 4u;
  Io::Write32(afr, (Io::Read32(afr) & ~(0xFu << af_shift)) | ((alternate & 0xFu) << af_shift));
}

/// Sets or clears `pin` of `port` atomically through BSRR (ISR-safe: no read-modify-write).
template <class Io = Mmio>
void WritePin(uintptr_t port, uint32_t pin, bool high) {
  Io::Write32(port + gpio::kBsrr, high ? (1u << pin) : (1u << (pin + 16u)));
}

/// A push-pull output (the ladder's power switch).
template <class Io = Mmio>
class PinOut final : public DigitalOut {
 public:
  PinOut(uintptr_t port, uint32_t pin) : port_(port), pin_(pin) {}
  void Init() {
    WritePin<Io>(port_, pin_, false);
    ConfigurePin<Io>(port_, pin_, gpio::Mode::kOutput);
  }

 private:
  void DoSet(bool high) override { WritePin<Io>(port_, pin_, high); }
  uintptr_t port_;
  uint32_t pin_;
};

}  // namespace lw::hal::stm32
