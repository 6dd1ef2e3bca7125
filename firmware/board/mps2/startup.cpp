// Minimal Cortex-M startup: vector table, .data copy, .bss clear, static constructors, main.
#include <cstdint>

extern "C" {
extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _sflash_emu, _eflash_emu, _estack;
extern void (*__init_array_start[])();
extern void (*__init_array_end[])();
int main();
void Reset_Handler();
void Default_Handler();
void SysTick_Handler();
void Uart0Rx_Handler();
void Uart1Rx_Handler();
// Pure virtual calls cannot happen in a correct program; trap instead of pulling in libstdc++.
void __cxa_pure_virtual() {
  for (;;) {
  }
}
}

void Default_Handler() {
  for (;;) {
  }
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

using Handler = void (*)();

// 16 system exceptions, then the AN386 interrupts (UART0 RX = 0, UART1 RX = 2).
__attribute__((section(".isr_vector"), used)) const Handler kVectors[16 + 8] = {
    reinterpret_cast<Handler>(&_estack),
    Reset_Handler,
    Default_Handler,  // NMI
    Default_Handler,  // HardFault
    Default_Handler,  // MemManage
    Default_Handler,  // BusFault
    Default_Handler,  // UsageFault
    nullptr,
    nullptr,
    nullptr,
    nullptr,
    Default_Handler,  // SVCall
    Default_Handler,  // DebugMon
    nullptr,
    Default_Handler,  // PendSV
    SysTick_Handler,
    Uart0Rx_Handler,  // IRQ 0
    Default_Handler,  // IRQ 1 UART0 TX
    Uart1Rx_Handler,  // IRQ 2
    Default_Handler,
    Default_Handler,
    Default_Handler,
    Default_Handler,
    Default_Handler,
};
