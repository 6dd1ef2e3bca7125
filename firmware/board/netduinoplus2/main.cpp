// Firmware image for the STM32F405 as qemu-system-arm -M netduinoplus2 models it: the same App
// as every board, on the STM32 port's register-level drivers (hal/stm32). What QEMU 7.2 models
// of the F405 decides what runs here (docs/firmware.md, "STM32 port"):
// - USART1 (0x40011000, IRQ 37): the XBee radio, first -serial.
// - USART2 (0x40004400, IRQ 38): the ladder test path (second -serial; QEMU's SPI bus has no
//   shift registers to attach). The SPI driver for the real chain (Hc165Chain) is tested on the
//   host against a register-level model of the F4 and L4 SPI and a 74HC165 chain.
// - SysTick at 1 kHz for time and wake-up (QEMU has no STM32 RTC model); Sleep() is WFI.
// - IWDG, RCC, GPIO: not modelled (reads 0, writes ignored); the drivers' waits are bounded, so
//   they return at once and the reset cause reads as power-on.
// - ADC1: modelled without the end-of-conversion flag: Read() fails (bounded), no battery value.
// - Flash: a ROM without a flash interface: two RAM pages stand in (linker.ld FLASH_EMU).
// Tunables for this image: fast polls so a CI run sees many cycles in seconds.
#include "firmware/app.hpp"
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

// Ring sizes as on the MPS2 image: the radio ring holds what arrives while the board sleeps; the
// ladder ring several test-path images (an emulator held up by a loaded host may get a few).
st::Usart<st::f4::UsartLayout, 256> radio_uart(st::f4::kUsart1);
st::Usart<st::f4::UsartLayout, 128> ladder_uart(st::f4::kUsart2);
lw::hal::port::UartLadder ladder(ladder_uart);
st::PinOut<> ladder_power(st::f4::kGpioB, 0);
st::F4Adc adc;
st::SysTickClock clock;
st::Iwdg<> watchdog;
__attribute__((section(".flash_emu"))) st::RamFlash<256, 2> flash;

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

}  // namespace

extern "C" void SysTick_Handler() {
  clock.OnTick();
}
extern "C" void USART1_IRQHandler() {
  radio_uart.OnInterrupt();
}
extern "C" void USART2_IRQHandler() {
  ladder_uart.OnInterrupt();
}

int main() {
  const lw::hal::ResetCause cause = st::ResetCauseFromCsrF4();
  EnableClocksAndPins();
  radio_uart.Init(kUsart1Brr);
  ladder_uart.Init(kUsart2Brr);
  ladder_power.Init();
  adc.Init();
  clock.Init(kCoreHz, cause);
  // NVIC: USART1 = IRQ 37, USART2 = IRQ 38 (ISER1 bits 5 and 6).
  st::Mmio::Write32(st::core::kNvicIser + 4, (1u << (st::f4::kUsart1Irq - 32)) | (1u << (st::f4::kUsart2Irq - 32)));
  const lw::hal::Board board{ladder, ladder_power, radio_uart, adc, clock, clock, watchdog, flash};
  static lw::firmware::App app(MakeConfig(), board);
  app.Init();
  for (;;) app.RunOnce();
}
