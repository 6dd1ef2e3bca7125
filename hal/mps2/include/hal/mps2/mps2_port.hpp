#pragma once
/// HAL port for the Arm MPS2 AN386 FPGA image (Cortex-M4) as qemu-system-arm emulates it: the
/// CI target that proves the firmware boots and talks on real registers. Production boards use a
/// low-power part (docs/firmware.md); their ports follow this one's shape.
///
/// - UART0 (CMSDK APB UART, 0x40004000): the XBee radio, RX by interrupt into a ring buffer.
/// - UART1 (0x40005000): the test path standing in for the SPI ladder (port::UartLadder, shared
///   with the netduinoplus2 image). The host sends frames `0x55, n, n bytes` (the shift
///   registers' image, loop i = bit i%8 of byte i/8); Transfer() returns the latest image followed
///   by the chain's signature byte.
/// - SysTick at 1 kHz: the RTC (seconds since boot, from a 64-bit millisecond count) and the
///   wake-up alarm; Sleep() is WFI.
/// - CMSDK watchdog (0x40008000): resets the core when not kicked.
/// - Flash: the AN386 has no flash controller (code runs from SSRAM), so the page store is two
///   RAM pages; a production port programs the MCU's own flash here.
/// - ADC: none on the board; fixed battery and temperature values.
#include <cstddef>
#include <cstdint>

#include "hal/board.hpp"
#include "hal/port/spsc_ring.hpp"
#include "hal/port/tick_counter.hpp"
#include "hal/port/uart_ladder.hpp"

namespace lw::hal::mps2 {

/// CMSDK APB UART: TX by polling, RX by interrupt into a ring of kRing bytes (CmsdkUart<kRing>).
class CmsdkUartBase : public Uart {
 public:
  explicit CmsdkUartBase(uintptr_t base) : base_(base) {}
  /// Enables TX, RX and the RX interrupt; `baud_div` = system clock / baud.
  void Init(uint32_t baud_div);

 protected:
  ~CmsdkUartBase() = default;
  bool RxReady() const;
  uint8_t RxByte() const;
  void ClearRxInterrupt() const;

 private:
  size_t DoWrite(const uint8_t* data, size_t len) override;
  uintptr_t base_;
};

/// kRing sizes the RX ring to what arrives between two drains of the task loop (the radio: acks
/// and transmit statuses while the board sleeps; the ladder test path: one 19-byte image).
template <size_t kRing>
class CmsdkUart final : public CmsdkUartBase {
 public:
  using CmsdkUartBase::CmsdkUartBase;
  /// Called from the RX interrupt handler. The interrupt is cleared before the drain, not after:
  /// the RX interrupt is a status bit held high from a byte's arrival until it is cleared, so a
  /// byte arriving between the drain's last look and a clear after it raised no new edge, was
  /// cleared unread, and with the one-byte holding register full no byte ever came again: the
  /// radio went deaf for good (acks never read, every record resent until the queue filled).
  /// Cleared first, any byte after the clear raises the interrupt again.
  void OnRxInterrupt() {
    ClearRxInterrupt();
    while (RxReady()) rx_.Push(RxByte());
  }
  /// Received bytes dropped because the task loop did not drain the ring in time.
  uint32_t rx_overruns() const { return rx_.overruns(); }

 private:
  size_t DoRead(uint8_t* out, size_t cap) override {
    size_t n = 0;
    while (n < cap && rx_.Pop(&out[n])) ++n;
    return n;
  }
  port::SpscRing<kRing> rx_;
};

/// The ladder test path over UART1 (shared with the netduinoplus2 image).
using UartLadder = port::UartLadder;

class Led final : public DigitalOut {
 private:
  void DoSet(bool high) override;
};

class FixedAdc final : public Adc {
 private:
  bool DoRead(AdcChannel channel, int32_t* value) override;
};

class SysTickClock final : public Rtc, public Power {
 public:
  /// Starts SysTick at 1 kHz from a `core_hz` clock.
  void Init(uint32_t core_hz);
  /// SysTick interrupt only.
  void OnTick() { ms_.Tick(); }
  /// Milliseconds since boot, 64-bit: no wrap in a campaign (a uint32 wrapped after 49.7 days).
  uint64_t millis() const { return ms_.Read(); }

 private:
  uint32_t DoNowSeconds() override { return static_cast<uint32_t>(ms_.Seconds()); }
  void DoSetAlarm(uint32_t at_seconds) override { alarm_s_ = at_seconds; }
  void DoSleep() override;
  ResetCause DoLastResetCause() override { return ResetCause::kPowerOn; }
  port::TickCounter64 ms_;
  uint32_t alarm_s_ = 0;
};

class CmsdkWatchdog final : public Watchdog {
 public:
  explicit CmsdkWatchdog(uint32_t core_hz) : core_hz_(core_hz) {}

 private:
  void DoStart(uint32_t timeout_s) override;
  void DoKick() override;
  uint32_t core_hz_;
  uint32_t reload_ = 0;
};

class RamFlash final : public FlashPages {
 public:
  static constexpr size_t kPageSize = 256;
  static constexpr size_t kPages = 2;

 private:
  size_t DoPageSize() override { return kPageSize; }
  size_t DoPageCount() override { return kPages; }
  bool DoErase(size_t page) override;
  bool DoProgram(size_t page, size_t offset, const uint8_t* data, size_t len) override;
  bool DoRead(size_t page, size_t offset, uint8_t* data, size_t len) override;
  uint8_t pages_[kPages][kPageSize];
};

}  // namespace lw::hal::mps2
