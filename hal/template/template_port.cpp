// Template port: a compilable stub of every HAL contract, the starting point for a new MCU.
// Copy this file to hal/<mcu>/, replace each body with register-level code, and keep the
// comments' promises (blocking, ISR safety) from hal/include/hal/*.hpp.
#include "hal/board.hpp"

namespace lw::hal::template_port {

class TemplateSpi final : public Spi {
  // Configure SPI mode 0, MSB first, <= 1 MHz (long ladder cable); pulse the shift registers'
  // load line before clocking; return false on a timeout of the transfer-complete flag.
  bool DoTransfer(const uint8_t*, uint8_t* rx, size_t len) override {
    for (size_t i = 0; i < len; ++i) rx[i] = 0;
    return false;
  }
};

class TemplatePin final : public DigitalOut {
  void DoSet(bool) override {}
};

class TemplateAdc final : public Adc {
  bool DoRead(AdcChannel, int32_t*) override { return false; }
};

class TemplateUart final : public Uart {
  // TX: copy into a ring buffer drained by the TX-empty interrupt. RX: the RX interrupt pushes
  // into a hal::port::SpscRing (hal/port/spsc_ring.hpp: acquire/release indices, overrun count,
  // no masking needed where 32-bit atomics are lock-free); DoRead pops from it. The handler clears
  // the interrupt before it drains the data register, never after (docs/firmware.md: a byte
  // arriving between the drain and a later clear leaves the UART deaf for good).
  size_t DoWrite(const uint8_t*, size_t) override { return 0; }
  size_t DoRead(uint8_t*, size_t) override { return 0; }
};

class TemplateRtc final : public Rtc {
  // A hardware RTC counts seconds itself. A port that derives time from a millisecond tick uses
  // hal::port::TickCounter64 (hal/port/tick_counter.hpp): a uint32 ms count wraps in 49.7 days.
  uint32_t DoNowSeconds() override { return 0; }
  void DoSetAlarm(uint32_t) override {}
};

class TemplatePower final : public Power {
  // Enter STOP/deep-sleep with the RTC alarm and the UART RX line as wake sources.
  void DoSleep() override {}
  ResetCause DoLastResetCause() override { return ResetCause::kPowerOn; }
};

class TemplateWatchdog final : public Watchdog {
  void DoStart(uint32_t) override {}
  void DoKick() override {}
};

class TemplateFlash final : public FlashPages {
  size_t DoPageSize() override { return 2048; }
  size_t DoPageCount() override { return 2; }
  bool DoErase(size_t) override { return false; }
  bool DoProgram(size_t, size_t, const uint8_t*, size_t) override { return false; }
  bool DoRead(size_t, size_t, uint8_t*, size_t) override { return false; }
};

TemplateSpi spi;
TemplatePin ladder_power;
TemplateUart radio;
TemplateAdc adc;
TemplateRtc rtc;
TemplatePower power;
TemplateWatchdog watchdog;
TemplateFlash flash;

}  // namespace lw::hal::template_port

namespace lw::hal {
/// The template port's board (a real port defines the same function for its MCU).
Board TemplateBoard() {
  using namespace template_port;
  return Board{spi, ladder_power, radio, adc, rtc, power, watchdog, flash};
}
}  // namespace lw::hal
