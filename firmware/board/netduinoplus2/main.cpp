// Firmware image for the STM32F405 as qemu-system-arm -M netduinoplus2 models it: the same App
// as every board, on the STM32 port's register-level drivers (hal/stm32). What QEMU 7.2 models
// of the F405 decides what runs here (docs/firmware.md, "STM32 port"):
// - USART1 (0x40011000, IRQ 37): the XBee radio, first -serial.
// - USART2 (0x40004400, IRQ 38): the ladder test path (second -serial; QEMU's SPI bus has no
//   shift registers to attach). The SPI driver for the real chain (Hc165Chain) is tested on the
//   host against a register-level model of the F4 and L4 SPI and a 74HC165 chain.
// - Time and sleep: the board first starts the RTC wake-up clock (LSE, 1 Hz, Stop mode), as the
//   production board does. QEMU models no RTC and no RCC: the LSE never reports ready, the bounded
//   wait gives up (about 4 s of emulated spinning at boot), Init() returns false and the board falls
//   back to SysTick at 1 kHz with WFI sleep.
// - IWDG, GPIO: not modelled (reads 0, writes ignored); the drivers run and have no effect, and the
//   reset cause (RCC_CSR) reads as power-on.
// - ADC1: modelled without the end-of-conversion flag: Read() fails (bounded), no battery value.
// - Flash: F4SectorFlash on sectors 2-3 when the flash interface answers (CR.LOCK = 1 after reset);
//   QEMU's F405 flash is a ROM without an interface (CR reads 0), so two RAM pages stand in
//   (linker.ld FLASH_EMU).
// Tunables for this image: fast polls so a CI run sees many cycles in seconds.
#include "firmware/app.hpp"
#include "../stm32/provision.hpp"
#include "hal/port/uart_ladder.hpp"
#include "hal/stm32/adc.hpp"
#include "hal/stm32/clock.hpp"
#include "hal/stm32/flash.hpp"
#include "hal/stm32/gpio.hpp"
#include "hal/stm32/iwdg.hpp"
#include "hal/stm32/usart.hpp"

namespace st = lw::hal::stm32;

namespace {

// The machine's fixed SYSCLK (netduinoplus2: 168 MHz, no RCC model); APB2 84 MHz, APB1 42 MHz.
// A real F405 starts on its 16 MHz HSI: a board image for one would set up the PLL first.
constexpr uint32_t kCoreHz = 168000000;
constexpr uint32_t kBaud = 115200;
constexpr uint32_t kUsart1Brr = (kCoreHz / 2 + kBaud / 2) / kBaud;  // APB2
constexpr uint32_t kUsart2Brr = (kCoreHz / 4 + kBaud / 2) / kBaud;  // APB1

// The radio ring holds what arrives while the board sleeps (as on MPS2); the ladder test path's
// ring six 15-byte images (an emulator held up by a loaded host may get several; MPS2 lost a step
// once with room for two), 96 B rather than MPS2's 128 to keep this image within its 4 KiB.
st::Usart<st::f4::UsartLayout, 256> radio_uart(st::f4::kUsart1);
st::Usart<st::f4::UsartLayout, 96> ladder_uart(st::f4::kUsart2);
lw::hal::port::UartLadder ladder(ladder_uart);
st::PinOut<> ladder_power(st::f4::kGpioB, 0);
st::F4Adc<> adc;
st::RtcWakeupClock<st::F4RtcFamily> rtc_clock;
st::SysTickClock clock;
st::Iwdg<> watchdog;
st::F4SectorFlash<> sector_flash(2);
__attribute__((section(".flash_emu"))) st::RamFlash<256, 2> ram_flash;

lw::firmware::Config MakeConfig() {
  lw::firmware::Config c;
  c.sensor_id = 1001;
  c.poll_period_s = 1;
  c.heartbeat_period_s = 5;
  c.backoff_min_s = 1;
  c.backoff_max_s = 8;
  c.watchdog_timeout_s = 10;
  return c;
}

void EnableClocksAndPins() {
  st::Mmio::Write32(st::f4::kRccAhb1enr, st::Mmio::Read32(st::f4::kRccAhb1enr) | st::f4::kAhb1GpioA | st::f4::kAhb1GpioB);
  st::Mmio::Write32(st::f4::kRccApb2enr, st::Mmio::Read32(st::f4::kRccApb2enr) | st::f4::kApb2Usart1);
  st::Mmio::Write32(st::f4::kRccApb1enr, st::Mmio::Read32(st::f4::kRccApb1enr) | st::f4::kApb1Usart2);
  // USART1 TX/RX = PA9/PA10, USART2 TX/RX = PA2/PA3: alternate function 7.
  constexpr uint32_t kUartPins[] = {9, 10, 2, 3};
  for (uint32_t pin : kUartPins) st::ConfigurePin<>(st::f4::kGpioA, pin, st::gpio::Mode::kAlternate, 7);
}

constexpr uint16_t kBoardId = lw::protocol::kBoards[0].id;
static_assert(lw::protocol::kBoards[0].id == 0x0405, "kBoards[0] is netduinoplus2");

}  // namespace

extern "C" __attribute__((used, section(".lw_board"))) const lw::board::BoardMarker lw_board_marker =
    lw::board::MakeBoardMarker(kBoardId);

extern "C" void SysTick_Handler() {
  clock.OnTick();
}
extern "C" void RTC_WKUP_IRQHandler() {
  rtc_clock.OnWakeup();
}
extern "C" void USART1_IRQHandler() {
  radio_uart.OnInterrupt();
}
extern "C" void USART2_IRQHandler() {
  ladder_uart.OnInterrupt();
}

int main() {
  // The record in sector 4 (written by scripts/flash, or by QEMU's loader in the tests) gives the
  // sensor id; without one the image runs as sensor 1001, a record for another board stops it.
  lw::firmware::Config config = MakeConfig();
  if (lw::board::ApplyProvision(kBoardId, lw::protocol::kBoards[0].provision_address, config) ==
      lw::board::ProvisionResult::kRefused)
    lw::board::HaltUnprovisioned();
  const lw::hal::ResetCause cause = st::ResetCauseFromCsrF4();
  EnableClocksAndPins();
  radio_uart.Init(kUsart1Brr);
  ladder_uart.Init(kUsart2Brr);
  ladder_power.Init();
  adc.Init();
  const bool on_rtc = rtc_clock.Init(cause);
  if (!on_rtc) clock.Init(kCoreHz, cause);
  // NVIC: USART1 = IRQ 37, USART2 = IRQ 38 (ISER1 bits 5 and 6).
  st::Mmio::Write32(st::core::kNvicIser + 4, (1u << (st::f4::kUsart1Irq - 32)) | (1u << (st::f4::kUsart2Irq - 32)));
  rtc_clock.KeepAliveInSleep(&watchdog);
  lw::hal::Rtc& rtc = on_rtc ? static_cast<lw::hal::Rtc&>(rtc_clock) : clock;
  lw::hal::Power& power = on_rtc ? static_cast<lw::hal::Power&>(rtc_clock) : clock;
  lw::hal::FlashPages& flash = sector_flash.Present() ? static_cast<lw::hal::FlashPages&>(sector_flash) : ram_flash;
  const lw::hal::Board board{ladder, ladder_power, radio_uart, adc, rtc, power, watchdog, flash};
  static lw::firmware::App app(config, board);
  app.Init();
  for (;;) app.RunOnce();
}
