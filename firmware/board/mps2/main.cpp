// Firmware image for the MPS2 AN386 board (qemu-system-arm -M mps2-an386): the same App as every
// board, on register-level drivers. Tunables for this image: fast polls so a CI run sees many
// cycles in seconds.
#include "firmware/app.hpp"
#include "hal/mps2/mps2_port.hpp"

namespace {

constexpr uint32_t kCoreHz = 25000000;  // MPS2 FPGA system clock
constexpr uint32_t kBaudDiv = kCoreHz / 115200;

// The radio ring holds what arrives while the board sleeps (acks and transmit statuses, ~100 B
// per batch); the ladder test path's ring six shift-register images (0x55, n, n <= 17 bytes):
// it is drained only when the firmware reads the ladder, and an emulator held up by a loaded
// host can receive several of the test's images meanwhile (with one image's room, 32 B, a step
// was lost once in CI: test_integration_firmware_qemu).
lw::hal::mps2::CmsdkUart<256> radio_uart(0x40004000);
lw::hal::mps2::CmsdkUart<128> ladder_uart(0x40005000);
lw::hal::mps2::UartLadder ladder(ladder_uart);
lw::hal::mps2::Led ladder_power;
lw::hal::mps2::FixedAdc adc;
lw::hal::mps2::SysTickClock clock;
lw::hal::mps2::CmsdkWatchdog watchdog(kCoreHz);
// Flash on a real board: its own region (linker.ld FLASH_EMU), outside the RAM budget.
__attribute__((section(".flash_emu"))) lw::hal::mps2::RamFlash flash;

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

}  // namespace

extern "C" void SysTick_Handler() {
  clock.OnTick();
}
extern "C" void Uart0Rx_Handler() {
  radio_uart.OnRxInterrupt();
}
extern "C" void Uart1Rx_Handler() {
  ladder_uart.OnRxInterrupt();
}

int main() {
  radio_uart.Init(kBaudDiv);
  ladder_uart.Init(kBaudDiv);
  clock.Init(kCoreHz);
  // NVIC: UART0 RX = IRQ 0, UART1 RX = IRQ 2.
  *reinterpret_cast<volatile uint32_t*>(0xE000E100) = (1u << 0) | (1u << 2);
  const lw::hal::Board board{ladder, ladder_power, radio_uart, adc, clock, clock, watchdog, flash};
  static lw::firmware::App app(MakeConfig(), board);
  app.Init();
  for (;;) app.RunOnce();
}
