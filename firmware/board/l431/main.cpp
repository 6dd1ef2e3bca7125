// Production firmware image: STM32L431 (Cortex-M4, 256 KiB flash, 64 KiB RAM; docs/firmware.md,
// "STM32 port"). The same App as every board on the STM32 port's drivers. Built and size-checked
// by the cross build; not run in CI (QEMU models no STM32L4).
// - LPUART1 (PA2 TX, PA3 RX, AF8) at 9600 Bd from the 32.768 kHz LSE: the XBee; it keeps
//   receiving in Stop 2 and its RX interrupt wakes the core.
// - SPI1 (PA5 SCK, PA6 MISO, AF5) + PA4 (SH/LD latch): the 74HC165 chain; PB0 switches the
//   ladder's power.
// - RTC wake-up timer at 1 Hz from the LSE, Stop 2 between wakes; SysTick (4 MHz MSI) as a
//   fallback when the LSE does not start (the board keeps running, at a higher sleep current).
// - IWDG (~32 s, kicked on every wake-up: IWDG_STOP is not assumed to be programmed).
// - Flash page 125 (0x0803E800): the provisioning record (sensor id, api mode, ladder size).
// - Flash pages 126 and 127 (0x0803F000, 2 KiB each) for the state slots.
// - ADC1: battery (VDDA from VREFINT) and die temperature.
#include "../stm32/provision.hpp"
#include "firmware/app.hpp"
#include "hal/stm32/adc.hpp"
#include "hal/stm32/clock.hpp"
#include "hal/stm32/flash.hpp"
#include "hal/stm32/gpio.hpp"
#include "hal/stm32/hc165.hpp"
#include "hal/stm32/iwdg.hpp"
#include "hal/stm32/usart.hpp"

namespace st = lw::hal::stm32;

namespace {

constexpr uint32_t kCoreHz = 4000000;  // MSI at reset: plenty for a 15-minute duty cycle
constexpr uint32_t kLseHz = 32768, kRadioBaud = 9600;
constexpr uint32_t kLpuartBrr = (256u * kLseHz + kRadioBaud / 2) / kRadioBaud;  // 874 (>= 0x300)
constexpr uint32_t kLpuartCr1Uesm = 1u << 1;                                    // wake-up from Stop
constexpr uint32_t kStatePage = 126;                                            // linker.ld STATE

st::Usart<st::l4::UsartLayout, 256> radio_uart(st::l4::kLpuart1);
st::Hc165Chain<st::l4::SpiLayout> ladder(st::l4::kSpi1, st::l4::kGpioA, 4);
st::PinOut<> ladder_power(st::l4::kGpioB, 0);
st::L4Adc<> adc;
st::RtcWakeupClock<st::L4RtcFamily> rtc_clock;
st::SysTickClock systick_clock;
bool on_rtc = false;
st::Iwdg<> watchdog;
st::L4PageFlash<> flash(kStatePage);

void EnableClocksAndPins() {
  st::Mmio::Write32(st::l4::kRccAhb2enr, st::Mmio::Read32(st::l4::kRccAhb2enr) | st::l4::kAhb2GpioA | st::l4::kAhb2GpioB);
  st::Mmio::Write32(st::l4::kRccApb1enr2, st::Mmio::Read32(st::l4::kRccApb1enr2) | st::l4::kApb1r2Lpuart1);
  st::Mmio::Write32(st::l4::kRccApb2enr, st::Mmio::Read32(st::l4::kRccApb2enr) | st::l4::kApb2Spi1);
  st::Mmio::Write32(st::l4::kRccCcipr,
                    (st::Mmio::Read32(st::l4::kRccCcipr) & ~st::l4::kCcipLpuart1SelMask) | st::l4::kCcipLpuart1SelLse);
  constexpr uint32_t kLpuartPins[] = {2, 3}, kSpiPins[] = {5, 6};
  for (uint32_t pin : kLpuartPins) st::ConfigurePin<>(st::l4::kGpioA, pin, st::gpio::Mode::kAlternate, 8);
  for (uint32_t pin : kSpiPins) st::ConfigurePin<>(st::l4::kGpioA, pin, st::gpio::Mode::kAlternate, 5);
}

constexpr uint16_t kBoardId = lw::protocol::kBoards[1].id;
static_assert(lw::protocol::kBoards[1].id == 0x0431, "kBoards[1] is l431");

}  // namespace

extern "C" __attribute__((used, section(".lw_board"))) const lw::board::BoardMarker lw_board_marker =
    lw::board::MakeBoardMarker(kBoardId);

extern "C" void SysTick_Handler() {
  systick_clock.OnTick();
}
extern "C" void RTC_WKUP_IRQHandler() {
  rtc_clock.OnWakeup();
}
extern "C" void LPUART1_IRQHandler() {
  radio_uart.OnInterrupt();
}

int main() {
  // A production board talks only with its record (page 125, written by scripts/flash): without
  // one, or with one for another board, it halts before its radio or watchdog start.
  lw::firmware::Config config{};
  if (lw::board::ApplyProvision(kBoardId, lw::protocol::kBoards[1].provision_address, config) !=
      lw::board::ProvisionResult::kApplied)
    lw::board::HaltUnprovisioned();
  const lw::hal::ResetCause cause = st::ResetCauseFromCsrL4();
  // The LSE first: it clocks the RTC and the radio's LPUART.
  on_rtc = rtc_clock.Init(cause);
  if (!on_rtc) systick_clock.Init(kCoreHz, cause);
  EnableClocksAndPins();
  radio_uart.Init(kLpuartBrr, kLpuartCr1Uesm);
  ladder.Init(0);  // SCK = 4 MHz / 2
  ladder_power.Init();
  (void)adc.Init();  // a failed calibration leaves Read() failing: records carry no battery value
  rtc_clock.KeepAliveInSleep(&watchdog);
  st::Mmio::Write32(st::core::kNvicIser + 8, 1u << (st::l4::kLpuart1Irq - 64));
  lw::hal::Rtc& rtc = on_rtc ? static_cast<lw::hal::Rtc&>(rtc_clock) : systick_clock;
  lw::hal::Power& power = on_rtc ? static_cast<lw::hal::Power&>(rtc_clock) : systick_clock;
  const lw::hal::Board board{ladder, ladder_power, radio_uart, adc, rtc, power, watchdog, flash};
  // Production tunables (config.hpp defaults). watchdog_timeout_s (1860 s) is clamped by the IWDG
  // to ~32 s of awake time; the sleep loop kicks it on each 1 Hz wake-up.
  static lw::firmware::App app(config, board);
  app.Init();
  for (;;) app.RunOnce();
}
