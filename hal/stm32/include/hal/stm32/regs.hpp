#pragma once
/// STM32 register maps for the two families this port supports. Where the families agree (GPIO,
/// IWDG, RTC wake-up timer, SPI CR1/SR/DR bits, Cortex-M core) one definition serves both; where
/// they differ (USART register layout, SPI frame-size and FIFO bits, RCC, FLASH, PWR, EXTI, ADC)
/// each family has its own namespace. Values from RM0090 (STM32F405/407) and RM0394 (STM32L431).
#include <cstddef>
#include <cstdint>

namespace lw::hal::stm32 {

// ---- Cortex-M4 core (both families) ----
namespace core {
inline constexpr uintptr_t kScbScr = 0xE000ED10;  // SLEEPDEEP = bit 2
inline constexpr uint32_t kScrSleepDeep = 1u << 2;
inline constexpr uintptr_t kNvicIser = 0xE000E100;
inline constexpr uintptr_t kSystCsr = 0xE000E010, kSystRvr = 0xE000E014, kSystCvr = 0xE000E018;
}  // namespace core

// ---- GPIO (same layout on F4 and L4) ----
namespace gpio {
inline constexpr uintptr_t kModer = 0x00, kOtyper = 0x04, kOspeedr = 0x08, kPupdr = 0x0C, kIdr = 0x10, kOdr = 0x14, kBsrr = 0x18,
                           kAfrl = 0x20, kAfrh = 0x24;
enum class Mode : uint32_t { kInput = 0, kOutput = 1, kAlternate = 2, kAnalog = 3 };
}  // namespace gpio

// ---- IWDG (same on F4 and L4, same address) ----
namespace iwdg {
inline constexpr uintptr_t kBase = 0x40003000;
inline constexpr uintptr_t kKr = 0x00, kPr = 0x04, kRlr = 0x08, kSr = 0x0C;
inline constexpr uint32_t kKeyStart = 0xCCCC, kKeyUnlock = 0x5555, kKeyReload = 0xAAAA;
inline constexpr uint32_t kSrPvu = 1u << 0, kSrRvu = 1u << 1;
}  // namespace iwdg

// ---- RTC wake-up timer (same registers on F4 and L4, same address) ----
namespace rtc {
inline constexpr uintptr_t kBase = 0x40002800;
inline constexpr uintptr_t kTr = 0x00, kDr = 0x04, kCr = 0x08, kIsr = 0x0C, kPrer = 0x10, kWutr = 0x14, kWpr = 0x24;
inline constexpr uint32_t kCrWucksel1Hz = 0x4;  // ck_spre (1 Hz from the 32.768 kHz LSE, reset PRER)
inline constexpr uint32_t kCrWucksel = 0x7, kCrBypshad = 1u << 5, kCrFmt = 1u << 6, kCrWute = 1u << 10, kCrWutie = 1u << 14;
inline constexpr uint32_t kIsrWutwf = 1u << 2, kIsrInits = 1u << 4, kIsrInitf = 1u << 6, kIsrInit = 1u << 7, kIsrWutf = 1u << 10;
inline constexpr uint32_t kPrerLse1Hz = (127u << 16) | 255u;          // 32768 / 128 / 256 = 1 Hz
inline constexpr uint32_t kDr20000101 = (6u << 13) | (1u << 8) | 1u;  // Saturday 2000-01-01
inline constexpr uint32_t kWprKey1 = 0xCA, kWprKey2 = 0x53, kWprLock = 0xFF;
inline constexpr uint32_t kWakeupIrq = 3;  // RTC_WKUP on both families
}  // namespace rtc

// ---- SPI: CR1/SR/DR bits common to both families ----
namespace spi {
inline constexpr uintptr_t kCr1 = 0x00, kCr2 = 0x04, kSr = 0x08, kDr = 0x0C;
inline constexpr uint32_t kCr1Cpha = 1u << 0, kCr1Cpol = 1u << 1, kCr1Mstr = 1u << 2, kCr1BrShift = 3, kCr1Spe = 1u << 6,
                          kCr1Lsbfirst = 1u << 7, kCr1Ssi = 1u << 8, kCr1Ssm = 1u << 9;
inline constexpr uint32_t kSrRxne = 1u << 0, kSrTxe = 1u << 1, kSrModf = 1u << 5, kSrOvr = 1u << 6, kSrBsy = 1u << 7;
}  // namespace spi

// ============================== STM32F4 (F405/F407) ==============================
namespace f4 {
inline constexpr uintptr_t kRcc = 0x40023800;
inline constexpr uintptr_t kRccAhb1enr = kRcc + 0x30, kRccApb1enr = kRcc + 0x40, kRccApb2enr = kRcc + 0x44,
                           kRccBdcr = kRcc + 0x70, kRccCsr = kRcc + 0x74;
inline constexpr uint32_t kAhb1GpioA = 1u << 0, kAhb1GpioB = 1u << 1;
inline constexpr uint32_t kApb1Usart2 = 1u << 17, kApb1Pwr = 1u << 28;
inline constexpr uint32_t kApb2Usart1 = 1u << 4, kApb2Adc1 = 1u << 8, kApb2Spi1 = 1u << 12;
inline constexpr uint32_t kBdcrLseon = 1u << 0, kBdcrLserdy = 1u << 1, kBdcrRtcselLse = 1u << 8, kBdcrRtcen = 1u << 15;
inline constexpr uint32_t kCsrRmvf = 1u << 24, kCsrBorrstf = 1u << 25, kCsrPinrstf = 1u << 26, kCsrPorrstf = 1u << 27,
                          kCsrSftrstf = 1u << 28, kCsrIwdgrstf = 1u << 29;

inline constexpr uintptr_t kGpioA = 0x40020000, kGpioB = 0x40020400;
inline constexpr uintptr_t kUsart1 = 0x40011000, kUsart2 = 0x40004400;
inline constexpr uint32_t kUsart1Irq = 37, kUsart2Irq = 38;
inline constexpr uintptr_t kSpi1 = 0x40013000;

inline constexpr uintptr_t kPwrCr = 0x40007000;
inline constexpr uint32_t kPwrCrLpds = 1u << 0, kPwrCrPdds = 1u << 1, kPwrCrCwuf = 1u << 2, kPwrCrDbp = 1u << 8;

inline constexpr uintptr_t kExti = 0x40013C00;
inline constexpr uintptr_t kExtiImr = kExti + 0x00, kExtiRtsr = kExti + 0x08, kExtiPr = kExti + 0x14;
inline constexpr uint32_t kExtiRtcWakeup = 1u << 22;

inline constexpr uintptr_t kFlash = 0x40023C00;
inline constexpr uintptr_t kFlashKeyr = kFlash + 0x04, kFlashSr = kFlash + 0x0C, kFlashCr = kFlash + 0x10;
inline constexpr uint32_t kFlashSrEop = 1u << 0, kFlashSrErrors = 0xF2u /* OPERR WRPERR PGAERR PGPERR PGSERR */,
                          kFlashSrBsy = 1u << 16;
inline constexpr uint32_t kFlashCrPg = 1u << 0, kFlashCrSer = 1u << 1, kFlashCrSnbShift = 3, kFlashCrPsizeX8 = 0u << 8,
                          kFlashCrStrt = 1u << 16, kFlashCrLock = 1u << 31;

inline constexpr uintptr_t kAdc1 = 0x40012000, kAdcCcr = 0x40012304;
inline constexpr uintptr_t kAdcSr = 0x00, kAdcCr2 = 0x08, kAdcSmpr1 = 0x0C, kAdcSqr1 = 0x2C, kAdcSqr3 = 0x34, kAdcDr = 0x4C;
inline constexpr uint32_t kAdcSrEoc = 1u << 1, kAdcCr2Adon = 1u << 0, kAdcCr2Swstart = 1u << 30, kAdcCcrTsvrefe = 1u << 23,
                          kAdcCcrPclkDiv4 = 1u << 16;
inline constexpr uint32_t kAdcChTemp = 16, kAdcChVrefint = 17;
// Factory calibration (system memory): VREFINT at 3.3 V, temperature sensor at 30 and 110 C.
inline constexpr uintptr_t kVrefintCal = 0x1FFF7A2A, kTsCal1 = 0x1FFF7A2C, kTsCal2 = 0x1FFF7A2E;
inline constexpr int32_t kCalMillivolts = 3300, kTsCal1C = 30, kTsCal2C = 110;

/// USART (F4): one status register SR and one data register DR for both directions.
struct UsartLayout {
  static constexpr uintptr_t kStatus = 0x00, kRxData = 0x04, kTxData = 0x04, kBrr = 0x08, kCr1 = 0x0C, kCr3 = 0x14;
  static constexpr uint32_t kRxne = 1u << 5, kTxe = 1u << 7, kOre = 1u << 3;
  static constexpr uint32_t kCr1Ue = 1u << 13, kCr1Te = 1u << 3, kCr1Re = 1u << 2, kCr1Rxneie = 1u << 5;
  /// ORE is cleared by reading SR then DR, which the RX drain does.
  static constexpr bool kOverrunClearedByIcr = false;
  static constexpr uintptr_t kIcr = 0;
  static constexpr uint32_t kIcrOrecf = 0;
};

/// SPI (F4): 8-bit frames are CR1.DFF = 0 (reset); no FIFO.
struct SpiLayout {
  static constexpr uint32_t kCr2 = 0;
  static constexpr bool kHasFifo = false;
};
}  // namespace f4

// ============================== STM32L4 (L431) ==============================
namespace l4 {
inline constexpr uintptr_t kRcc = 0x40021000;
inline constexpr uintptr_t kRccAhb2enr = kRcc + 0x4C, kRccApb1enr1 = kRcc + 0x58, kRccApb1enr2 = kRcc + 0x5C,
                           kRccApb2enr = kRcc + 0x60, kRccCcipr = kRcc + 0x88, kRccBdcr = kRcc + 0x90, kRccCsr = kRcc + 0x94;
inline constexpr uint32_t kAhb2GpioA = 1u << 0, kAhb2GpioB = 1u << 1, kAhb2Adc = 1u << 13;
inline constexpr uint32_t kApb1r1Pwr = 1u << 28, kApb1r1RtcApb = 1u << 10;
inline constexpr uint32_t kApb1r2Lpuart1 = 1u << 0;
inline constexpr uint32_t kApb2Spi1 = 1u << 12;
inline constexpr uint32_t kCcipLpuart1SelLse = 3u << 10, kCcipLpuart1SelMask = 3u << 10, kCcipAdcSelSysclk = 3u << 28;
inline constexpr uint32_t kBdcrLseon = 1u << 0, kBdcrLserdy = 1u << 1, kBdcrRtcselLse = 1u << 8, kBdcrRtcen = 1u << 15;
inline constexpr uint32_t kCsrRmvf = 1u << 23, kCsrPinrstf = 1u << 26, kCsrBorrstf = 1u << 27, kCsrSftrstf = 1u << 28,
                          kCsrIwdgrstf = 1u << 29;

inline constexpr uintptr_t kGpioA = 0x48000000, kGpioB = 0x48000400;
inline constexpr uintptr_t kLpuart1 = 0x40008000;
inline constexpr uint32_t kLpuart1Irq = 70;
inline constexpr uintptr_t kSpi1 = 0x40013000;

inline constexpr uintptr_t kPwrCr1 = 0x40007000, kPwrScr = 0x40007018;
inline constexpr uint32_t kPwrCr1LpmsMask = 0x7, kPwrCr1LpmsStop2 = 0x2, kPwrCr1Dbp = 1u << 8;

inline constexpr uintptr_t kExti = 0x40010400;
inline constexpr uintptr_t kExtiImr1 = kExti + 0x00, kExtiRtsr1 = kExti + 0x08, kExtiPr1 = kExti + 0x14;
inline constexpr uint32_t kExtiRtcWakeup = 1u << 20;

inline constexpr uintptr_t kFlash = 0x40022000;
inline constexpr uintptr_t kFlashKeyr = kFlash + 0x08, kFlashSr = kFlash + 0x10, kFlashCr = kFlash + 0x14;
inline constexpr uint32_t kFlashSrEop = 1u << 0,
                          kFlashSrErrors = 0xC3FAu /* OPERR PROGERR WRPERR PGAERR SIZERR PGSERR MISSERR FASTERR RDERR OPTVERR */,
                          kFlashSrBsy = 1u << 16;
inline constexpr uint32_t kFlashCrPg = 1u << 0, kFlashCrPer = 1u << 1, kFlashCrPnbShift = 3, kFlashCrPnbMask = 0xFFu << 3,
                          kFlashCrStrt = 1u << 16, kFlashCrLock = 1u << 31;
inline constexpr uintptr_t kFlashBase = 0x08000000;
inline constexpr size_t kFlashPageSize = 2048;

inline constexpr uintptr_t kAdc1 = 0x50040000, kAdcCcr = 0x50040308;
inline constexpr uintptr_t kAdcIsr = 0x00, kAdcCr = 0x08, kAdcSmpr1 = 0x14, kAdcSmpr2 = 0x18, kAdcSqr1 = 0x30, kAdcDr = 0x40;
inline constexpr uint32_t kAdcIsrAdrdy = 1u << 0, kAdcIsrEoc = 1u << 2;
inline constexpr uint32_t kAdcCrAden = 1u << 0, kAdcCrAdstart = 1u << 2, kAdcCrAdcal = 1u << 31, kAdcCrDeeppwd = 1u << 29,
                          kAdcCrAdvregen = 1u << 28;
inline constexpr uint32_t kAdcCcrVrefen = 1u << 22, kAdcCcrTsen = 1u << 23, kAdcCcrHclkDiv1 = 1u << 16;
inline constexpr uint32_t kAdcChVrefint = 0, kAdcChTemp = 17;
// Factory calibration: VREFINT at 3.0 V, temperature sensor at 30 and 130 C.
inline constexpr uintptr_t kVrefintCal = 0x1FFF75AA, kTsCal1 = 0x1FFF75A8, kTsCal2 = 0x1FFF75CA;
inline constexpr int32_t kCalMillivolts = 3000, kTsCal1C = 30, kTsCal2C = 130;

/// USART/LPUART (L4): separate ISR (status), ICR (clear), RDR and TDR; CR1 first, UE at bit 0.
struct UsartLayout {
  static constexpr uintptr_t kCr1 = 0x00, kCr3 = 0x08, kBrr = 0x0C, kStatus = 0x1C, kIcr = 0x20, kRxData = 0x24, kTxData = 0x28;
  static constexpr uint32_t kRxne = 1u << 5, kTxe = 1u << 7, kOre = 1u << 3;
  static constexpr uint32_t kCr1Ue = 1u << 0, kCr1Te = 1u << 3, kCr1Re = 1u << 2, kCr1Rxneie = 1u << 5;
  /// ORE stays set (and, with RXNEIE, keeps the interrupt asserted) until ICR.ORECF is written:
  /// a handler that only drains RDR would re-enter forever after one overrun.
  static constexpr bool kOverrunClearedByIcr = true;
  static constexpr uint32_t kIcrOrecf = 1u << 3;
};

/// SPI (L4): the frame size is CR2.DS (reset value 0111 = 8 bits) and RX goes through a 32-bit
/// FIFO; RXNE for 8-bit frames needs CR2.FRXTH = 1, and DR must be accessed as a byte (a 16-bit
/// access packs two frames).
struct SpiLayout {
  static constexpr uint32_t kCr2 = (0x7u << 8) | (1u << 12);  // DS = 8 bits, FRXTH = 1/4 FIFO
  static constexpr bool kHasFifo = true;
};
}  // namespace l4

}  // namespace lw::hal::stm32
