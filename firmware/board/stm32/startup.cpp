// Cortex-M startup shared by the STM32 boards (netduinoplus2 = STM32F405, l431 = STM32L431):
// vector table, .data copy, .bss and emulated-flash clear, static constructors, main. The table
// is sized for the larger of the two families (STM32L431: 83 interrupts; F405: 82); the handlers
// a board uses are strong definitions in its main.cpp, every other entry is Default_Handler.
#include <array>
#include <cstddef>
#include <cstdint>

extern "C" {
extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _sflash_emu, _eflash_emu, _estack;
extern void (*__init_array_start[])();
extern void (*__init_array_end[])();
int main();
void Reset_Handler();
void Default_Handler();
// Pure virtual calls cannot happen in a correct program; trap instead of pulling in libstdc++.
void __cxa_pure_virtual() {
  for (;;) {
  }
}
void Default_Handler() {
  for (;;) {
  }
}
void SysTick_Handler() __attribute__((weak, alias("Default_Handler")));
void RTC_WKUP_IRQHandler() __attribute__((weak, alias("Default_Handler")));
void USART1_IRQHandler() __attribute__((weak, alias("Default_Handler")));
void USART2_IRQHandler() __attribute__((weak, alias("Default_Handler")));
void LPUART1_IRQHandler() __attribute__((weak, alias("Default_Handler")));
}

void Reset_Handler() {
  for (uint32_t *src = &_sidata, *dst = &_sdata; dst < &_edata;) *dst++ = *src++;
  for (uint32_t* dst = &_sbss; dst < &_ebss;) *dst++ = 0;
  for (uint32_t* dst = &_sflash_emu; dst < &_eflash_emu;) *dst++ = 0;
  for (auto* f = __init_array_start; f < __init_array_end; ++f) (*f)();
  main();
  for (;;) {
  }
}

namespace {

using Handler = void (*)();
constexpr int kIrqs = 83;
// Interrupt numbers (RM0090 table 61, RM0394 table 46).
constexpr int kRtcWakeupIrq = 3, kUsart1Irq = 37, kUsart2Irq = 38, kLpuart1Irq = 70;

struct VectorTable {
  uint32_t* initial_sp;
  std::array<Handler, 15 + kIrqs> handlers;  // exceptions 1..15, then IRQ 0..kIrqs-1
};

constexpr std::array<Handler, 15 + kIrqs> MakeHandlers() {
  std::array<Handler, 15 + kIrqs> h{};
  for (auto& e : h) e = Default_Handler;
  h[0] = Reset_Handler;
  h[6] = h[7] = h[8] = h[9] = h[12] = nullptr;  // reserved: exceptions 7-10 and 13
  h[14] = SysTick_Handler;                      // exception 15
  h[15 + kRtcWakeupIrq] = RTC_WKUP_IRQHandler;
  h[15 + kUsart1Irq] = USART1_IRQHandler;
  h[15 + kUsart2Irq] = USART2_IRQHandler;
  h[15 + kLpuart1Irq] = LPUART1_IRQHandler;
  return h;
}

}  // namespace

__attribute__((section(".isr_vector"), used)) const VectorTable kVectors{&_estack, MakeHandlers()};
