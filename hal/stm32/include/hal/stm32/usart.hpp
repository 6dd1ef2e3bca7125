#pragma once
/// USART driver shared by the STM32F4 USART and the STM32L4 USART/LPUART: TX by polling TXE
/// (bounded), RX by the RXNE interrupt into a ring. `Layout` (f4::UsartLayout, l4::UsartLayout)
/// holds what differs between the families: register offsets, the UE bit, and how an overrun is
/// cleared.
#include <atomic>
#include <cstddef>
#include <cstdint>

#include "hal/port/spsc_ring.hpp"
#include "hal/stm32/mmio.hpp"
#include "hal/stm32/regs.hpp"
#include "hal/uart.hpp"

namespace lw::hal::stm32 {

template <class Layout, size_t kRing, class Io = Mmio>
class Usart final : public Uart {
 public:
  explicit Usart(uintptr_t base) : base_(base) {}

  /// `brr`: the baud rate register value (USART: f_ck / baud; LPUART: 256 f_ck / baud). Enables TX,
  /// RX and the RX interrupt; `cr1_extra`/`cr3_extra` add family bits (e.g. the L4 LPUART's wake-up
  /// from Stop). The port enables the peripheral's clock and pins first.
  void Init(uint32_t brr, uint32_t cr1_extra = 0, uint32_t cr3_extra = 0) {
    Io::Write32(base_ + Layout::kCr1, 0);
    Io::Write32(base_ + Layout::kBrr, brr);
    Io::Write32(base_ + Layout::kCr3, cr3_extra);
    const uint32_t cr1 = Layout::kCr1Te | Layout::kCr1Re | Layout::kCr1Rxneie | cr1_extra;
    Io::Write32(base_ + Layout::kCr1, cr1);
    Io::Write32(base_ + Layout::kCr1, cr1 | Layout::kCr1Ue);
  }

  /// The USART interrupt handler. On STM32 reading the data register is what clears RXNE (and on
  /// F4 the SR-then-DR read clears an overrun), so no byte can arrive unseen between a drain and a
  /// clear: a byte after the last read sets RXNE, which keeps the interrupt pending. On L4 an
  /// overrun must be cleared through ICR first, or the handler would be re-entered forever.
  void OnInterrupt() {
    uint32_t status = Io::Read32(base_ + Layout::kStatus);
    if (status & Layout::kOre) {
      hw_overruns_.store(hw_overruns_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
      if constexpr (Layout::kOverrunClearedByIcr) Io::Write32(base_ + Layout::kIcr, Layout::kIcrOrecf);
    }
    while (status & Layout::kRxne) {
      rx_.Push(static_cast<uint8_t>(Io::Read32(base_ + Layout::kRxData)));
      status = Io::Read32(base_ + Layout::kStatus);
    }
  }

  /// Bytes dropped because the task loop did not drain the ring in time.
  uint32_t rx_overruns() const { return rx_.overruns(); }
  /// Bytes the hardware lost (a byte arrived before the handler read the previous one).
  uint32_t hw_overruns() const { return hw_overruns_.load(std::memory_order_relaxed); }

 private:
  size_t DoWrite(const uint8_t* data, size_t len) override {
    for (size_t i = 0; i < len; ++i) {
      if (!WaitSet<Io>(base_ + Layout::kStatus, Layout::kTxe)) return i;  // TX stalled: report what went
      Io::Write32(base_ + Layout::kTxData, data[i]);
    }
    return len;
  }
  size_t DoRead(uint8_t* out, size_t cap) override {
    size_t n = 0;
    while (n < cap && rx_.Pop(&out[n])) ++n;
    return n;
  }

  uintptr_t base_;
  port::SpscRing<kRing> rx_;
  std::atomic<uint32_t> hw_overruns_{0};
};

}  // namespace lw::hal::stm32
