#pragma once
/// Time bases and sleep for the STM32 port.
/// - SysTickClock: the Cortex-M SysTick at 1 kHz into a 64-bit millisecond count; Sleep() is WFI
///   in Sleep mode (SysTick stops in Stop mode, so it cannot be the wake source there). The
///   netduinoplus2 image uses it: QEMU models SysTick but not the STM32 RTC.
/// - RtcWakeupClock<Family>: seconds from the RTC calendar (LSE, backup domain: it keeps counting
///   through sleep and resets, as the Rtc contract asks; started at 2000-01-01 on the first power-up),
///   woken every second by the RTC wake-up timer; Sleep() enters Stop (F4: Stop with the low-power regulator; L4: Stop 2, ~1.3 uA
///   with the RTC) until the alarm second, kicking the IWDG on each wake-up (it cannot be frozen on
///   the F4, and its longest timeout is ~32 s). The production image (STM32L431) uses it.
#include <atomic>
#include <cstdint>

#include "hal/port/tick_counter.hpp"
#include "hal/power.hpp"
#include "hal/rtc.hpp"
#include "hal/stm32/mmio.hpp"
#include "hal/stm32/regs.hpp"
#include "hal/watchdog.hpp"

namespace lw::hal::stm32 {

class SysTickClock final : public Rtc, public Power {
 public:
  /// Starts SysTick at 1 kHz from the `core_hz` processor clock (RVR is 24 bits: up to 16.7 GHz);
  /// `cause` is what LastResetCause() reports (the family's ResetCauseFromCsr*()).
  void Init(uint32_t core_hz, ResetCause cause) {
    cause_ = cause;
    Mmio::Write32(core::kSystRvr, core_hz / 1000u - 1u);
    Mmio::Write32(core::kSystCvr, 0);
    Mmio::Write32(core::kSystCsr, 0x7);  // processor clock, interrupt, enable
  }
  /// SysTick interrupt only.
  void OnTick() { ms_.Tick(); }
  uint64_t millis() const { return ms_.Read(); }

 private:
  uint32_t DoNowSeconds() override { return static_cast<uint32_t>(ms_.Seconds()); }
  void DoSetAlarm(uint32_t at_seconds) override { alarm_s_ = at_seconds; }
  void DoSleep() override {
    while (ms_.Seconds() < alarm_s_) __asm volatile("wfi");
  }
  ResetCause DoLastResetCause() override { return cause_; }
  port::TickCounter64 ms_;
  uint32_t alarm_s_ = 0;
  ResetCause cause_ = ResetCause::kPowerOn;
};

/// Seconds since 2000-01-01 00:00:00 from the RTC's BCD time (TR, 24-hour) and date (DR)
/// registers, the same on F4 and L4; years 2000-2099 (every fourth one a leap year).
constexpr uint32_t CalendarSeconds(uint32_t tr, uint32_t dr) {
  const auto bcd = [](uint32_t v, uint32_t shift, uint32_t tens_mask) {
    return ((v >> (shift + 4)) & tens_mask) * 10u + ((v >> shift) & 0xFu);
  };
  const uint32_t year = bcd(dr, 16, 0xF), month = bcd(dr, 8, 0x1), day = bcd(dr, 0, 0x3);
  const uint32_t hours = bcd(tr, 16, 0x3), minutes = bcd(tr, 8, 0x7), seconds = bcd(tr, 0, 0x7);
  constexpr uint32_t kBefore[12] = {0, 31, 59, 90, 120, 151, 181, 212, 243, 273, 304, 334};
  const uint32_t m = (month >= 1 && month <= 12) ? month : 1;
  uint32_t days = year * 365u + (year + 3u) / 4u + kBefore[m - 1] + (day > 0 ? day - 1 : 0);
  if (year % 4u == 0 && m > 2) ++days;  // this year's 29 February is behind
  return ((days * 24u + hours) * 60u + minutes) * 60u + seconds;
}

/// Family hooks for RtcWakeupClock: the backup-domain and EXTI registers and the Stop entry.
struct F4RtcFamily {
  static constexpr uintptr_t kRccBdcr = f4::kRccBdcr, kExtiImr = f4::kExtiImr, kExtiRtsr = f4::kExtiRtsr, kExtiPr = f4::kExtiPr;
  static constexpr uint32_t kExtiLine = f4::kExtiRtcWakeup;
  static void EnableBackupAccess() {
    Mmio::Write32(f4::kRccApb1enr, Mmio::Read32(f4::kRccApb1enr) | f4::kApb1Pwr);
    Mmio::Write32(f4::kPwrCr, Mmio::Read32(f4::kPwrCr) | f4::kPwrCrDbp);
  }
  /// Stop mode with the low-power regulator (PDDS = 0, LPDS = 1); wake-up flags cleared first.
  static void ConfigureStop() {
    Mmio::Write32(f4::kPwrCr, (Mmio::Read32(f4::kPwrCr) & ~f4::kPwrCrPdds) | f4::kPwrCrLpds | f4::kPwrCrCwuf);
  }
};
struct L4RtcFamily {
  static constexpr uintptr_t kRccBdcr = l4::kRccBdcr, kExtiImr = l4::kExtiImr1, kExtiRtsr = l4::kExtiRtsr1,
                             kExtiPr = l4::kExtiPr1;
  static constexpr uint32_t kExtiLine = l4::kExtiRtcWakeup;
  static void EnableBackupAccess() {
    Mmio::Write32(l4::kRccApb1enr1, Mmio::Read32(l4::kRccApb1enr1) | l4::kApb1r1Pwr | l4::kApb1r1RtcApb);
    Mmio::Write32(l4::kPwrCr1, Mmio::Read32(l4::kPwrCr1) | l4::kPwrCr1Dbp);
  }
  /// Stop 2 (LPMS = 010): RTC, LPUART1 and the SRAM kept.
  static void ConfigureStop() {
    Mmio::Write32(l4::kPwrCr1, (Mmio::Read32(l4::kPwrCr1) & ~l4::kPwrCr1LpmsMask) | l4::kPwrCr1LpmsStop2);
    Mmio::Write32(l4::kPwrScr, 0x1F);  // clear the wake-up flags
  }
};

template <class Family>
class RtcWakeupClock final : public Rtc, public Power {
 public:
  /// Starts the LSE, clocks the RTC from it and arms the 1 Hz wake-up interrupt. Returns false
  /// (and leaves the RTC alone) when the LSE or the RTC never answers within the bounded waits:
  /// no crystal, or a machine that does not model them (QEMU), so a board can fall back to
  /// SysTickClock instead of hanging.
  bool Init(ResetCause cause) {
    cause_ = cause;
    Family::EnableBackupAccess();
    if ((Mmio::Read32(Family::kRccBdcr) & f4::kBdcrRtcen) == 0) {  // RTCEN/LSEON bits agree on both
      Mmio::Write32(Family::kRccBdcr, Mmio::Read32(Family::kRccBdcr) | f4::kBdcrLseon);
      if (!WaitSet<Mmio>(Family::kRccBdcr, f4::kBdcrLserdy, kLseStartSpins)) return false;
      Mmio::Write32(Family::kRccBdcr, Mmio::Read32(Family::kRccBdcr) | f4::kBdcrRtcselLse | f4::kBdcrRtcen);
    }
    Mmio::Write32(rtc::kBase + rtc::kWpr, rtc::kWprKey1);
    Mmio::Write32(rtc::kBase + rtc::kWpr, rtc::kWprKey2);
    bool writable = true;
    if ((Mmio::Read32(rtc::kBase + rtc::kIsr) & rtc::kIsrInits) == 0) {  // first power-up: start the calendar
      Mmio::Write32(rtc::kBase + rtc::kIsr, 0xFFFFFFFFu);                // INIT = 1; writing 1 leaves the rc_w0 flags
      writable = WaitSet<Mmio>(rtc::kBase + rtc::kIsr, rtc::kIsrInitf);
      if (writable) {
        Mmio::Write32(rtc::kBase + rtc::kPrer, rtc::kPrerLse1Hz & 0x7FFFu);  // synchronous first, then asynchronous
        Mmio::Write32(rtc::kBase + rtc::kPrer, rtc::kPrerLse1Hz);
        Mmio::Write32(rtc::kBase + rtc::kTr, 0);
        Mmio::Write32(rtc::kBase + rtc::kDr, rtc::kDr20000101);
        Mmio::Write32(rtc::kBase + rtc::kCr, Mmio::Read32(rtc::kBase + rtc::kCr) & ~rtc::kCrFmt);
      }
      Mmio::Write32(rtc::kBase + rtc::kIsr, Mmio::Read32(rtc::kBase + rtc::kIsr) & ~rtc::kIsrInit);
    }
    // Read the calendar counters directly (no shadow registers to resynchronise after Stop).
    Mmio::Write32(rtc::kBase + rtc::kCr,
                  (Mmio::Read32(rtc::kBase + rtc::kCr) | rtc::kCrBypshad) & ~(rtc::kCrWute | rtc::kCrWutie));
    writable = writable && WaitSet<Mmio>(rtc::kBase + rtc::kIsr, rtc::kIsrWutwf);
    if (writable) {
      Mmio::Write32(rtc::kBase + rtc::kWutr, 0);  // every second
      Mmio::Write32(rtc::kBase + rtc::kCr,
                    (Mmio::Read32(rtc::kBase + rtc::kCr) & ~rtc::kCrWucksel) | rtc::kCrWucksel1Hz | rtc::kCrWute | rtc::kCrWutie);
    }
    Mmio::Write32(rtc::kBase + rtc::kWpr, rtc::kWprLock);
    if (!writable) return false;
    Mmio::Write32(Family::kExtiImr, Mmio::Read32(Family::kExtiImr) | Family::kExtiLine);
    Mmio::Write32(Family::kExtiRtsr, Mmio::Read32(Family::kExtiRtsr) | Family::kExtiLine);
    Mmio::Write32(core::kNvicIser, 1u << rtc::kWakeupIrq);
    return true;
  }
  /// Kicked on each wake-up of Sleep() (null: none).
  void KeepAliveInSleep(Watchdog* watchdog) { watchdog_ = watchdog; }

  /// RTC_WKUP interrupt only: clears WUTF (rc_w0, keeping INIT) and the EXTI line.
  void OnWakeup() {
    Mmio::Write32(rtc::kBase + rtc::kIsr, ~rtc::kIsrWutf & ~rtc::kIsrInit & 0x1FFFFu);
    Mmio::Write32(Family::kExtiPr, Family::kExtiLine);
  }

 private:
  // The crystal takes up to ~2 s after power-on. 20 million polls of BDCR: about 20 s at the
  // L431's 4 MHz, about 0.7 s at the F405's 168 MHz (a real F405 board would poll longer).
  static constexpr uint32_t kLseStartSpins = 20000000;
  /// With BYPSHAD the counters are read live: time, date, time again, until the two times agree
  /// (a second boundary between the reads would pair a new time with an old date at midnight).
  uint32_t DoNowSeconds() override {
    uint32_t tr = Mmio::Read32(rtc::kBase + rtc::kTr), dr = 0;
    for (int i = 0; i < 4; ++i) {
      dr = Mmio::Read32(rtc::kBase + rtc::kDr);
      const uint32_t again = Mmio::Read32(rtc::kBase + rtc::kTr);
      if (again == tr) break;
      tr = again;
    }
    return CalendarSeconds(tr, dr);
  }
  void DoSetAlarm(uint32_t at_seconds) override { alarm_s_ = at_seconds; }
  void DoSleep() override {
    Family::ConfigureStop();
    Mmio::Write32(core::kScbScr, Mmio::Read32(core::kScbScr) | core::kScrSleepDeep);
    while (DoNowSeconds() < alarm_s_) {
      __asm volatile("dsb\n wfi");
      if (watchdog_) watchdog_->Kick();
    }
    Mmio::Write32(core::kScbScr, Mmio::Read32(core::kScbScr) & ~core::kScrSleepDeep);
  }
  ResetCause DoLastResetCause() override { return cause_; }
  uint32_t alarm_s_ = 0;
  Watchdog* watchdog_ = nullptr;
  ResetCause cause_ = ResetCause::kPowerOn;
};

/// Reads and clears the reset flags (RCC_CSR). Unknown or none (QEMU reads 0): power-on.
inline ResetCause ResetCauseFromCsrF4() {
  const uint32_t csr = Mmio::Read32(f4::kRccCsr);
  Mmio::Write32(f4::kRccCsr, csr | f4::kCsrRmvf);
  if (csr & f4::kCsrIwdgrstf) return ResetCause::kWatchdog;
  if (csr & f4::kCsrSftrstf) return ResetCause::kSoftware;
  if (csr & f4::kCsrPorrstf) return ResetCause::kPowerOn;  // POR also sets BOR and PIN
  if (csr & f4::kCsrBorrstf) return ResetCause::kBrownout;
  if (csr & f4::kCsrPinrstf) return ResetCause::kPin;
  return ResetCause::kPowerOn;
}
inline ResetCause ResetCauseFromCsrL4() {
  const uint32_t csr = Mmio::Read32(l4::kRccCsr);
  Mmio::Write32(l4::kRccCsr, csr | l4::kCsrRmvf);
  if (csr & l4::kCsrIwdgrstf) return ResetCause::kWatchdog;
  if (csr & l4::kCsrSftrstf) return ResetCause::kSoftware;
  if (csr & l4::kCsrBorrstf) return ResetCause::kPowerOn;  // the L4's BOR flag is its power-on flag
  if (csr & l4::kCsrPinrstf) return ResetCause::kPin;
  return ResetCause::kPowerOn;
}

}  // namespace lw::hal::stm32
