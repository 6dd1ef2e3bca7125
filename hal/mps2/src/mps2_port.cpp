#include "hal/mps2/mps2_port.hpp"

namespace lw::hal::mps2 {
namespace {

inline volatile uint32_t& Reg(uintptr_t addr) {
  return *reinterpret_cast<volatile uint32_t*>(addr);
}

// CMSDK APB UART registers.
constexpr uintptr_t kUartData = 0x00, kUartState = 0x04, kUartCtrl = 0x08, kUartIntClear = 0x0C, kUartBaudDiv = 0x10;
constexpr uint32_t kStateTxFull = 1u << 0, kStateRxFull = 1u << 1;
constexpr uint32_t kCtrlTxEn = 1u << 0, kCtrlRxEn = 1u << 1, kCtrlRxIntEn = 1u << 3;
constexpr uint32_t kIntRx = 1u << 1;

// SysTick.
constexpr uintptr_t kSystCsr = 0xE000E010, kSystRvr = 0xE000E014, kSystCvr = 0xE000E018;

// CMSDK APB watchdog.
constexpr uintptr_t kWdogBase = 0x40008000;
constexpr uintptr_t kWdogLoad = 0x00, kWdogCtrl = 0x08, kWdogIntClr = 0x0C, kWdogLock = 0xC00;
constexpr uint32_t kWdogUnlock = 0x1ACCE551;

// FPGA IO LEDs.
constexpr uintptr_t kFpgaLed = 0x40028000;

}  // namespace

void CmsdkUartBase::Init(uint32_t baud_div) {
  Reg(base_ + kUartBaudDiv) = baud_div;
  Reg(base_ + kUartCtrl) = kCtrlTxEn | kCtrlRxEn | kCtrlRxIntEn;
}

bool CmsdkUartBase::RxReady() const {
  return (Reg(base_ + kUartState) & kStateRxFull) != 0;
}

uint8_t CmsdkUartBase::RxByte() const {
  return static_cast<uint8_t>(Reg(base_ + kUartData));
}

void CmsdkUartBase::ClearRxInterrupt() const {
  Reg(base_ + kUartIntClear) = kIntRx;
}

size_t CmsdkUartBase::DoWrite(const uint8_t* data, size_t len) {
  for (size_t i = 0; i < len; ++i) {
    while (Reg(base_ + kUartState) & kStateTxFull) {
    }
    Reg(base_ + kUartData) = data[i];
  }
  return len;
}

void Led::DoSet(bool high) {
  Reg(kFpgaLed) = high ? 1u : 0u;
}

bool FixedAdc::DoRead(AdcChannel channel, int32_t* value) {
  *value = channel == AdcChannel::kBatteryMillivolts ? 3600 : 25;
  return true;
}

void SysTickClock::Init(uint32_t core_hz) {
  Reg(kSystRvr) = core_hz / 1000u - 1u;
  Reg(kSystCvr) = 0;
  Reg(kSystCsr) = 0x7;  // processor clock, interrupt, enable
}

void SysTickClock::DoSleep() {
  while (ms_.Seconds() < alarm_s_) {
    __asm volatile("wfi");
  }
}

void CmsdkWatchdog::DoStart(uint32_t timeout_s) {
  // Interrupt + reset enabled: the core resets on the second expiry, so load half the timeout.
  const uint64_t ticks = static_cast<uint64_t>(timeout_s) * core_hz_ / 2u;
  reload_ = ticks > 0xFFFFFFFFu ? 0xFFFFFFFFu : static_cast<uint32_t>(ticks);
  Reg(kWdogBase + kWdogLock) = kWdogUnlock;
  Reg(kWdogBase + kWdogLoad) = reload_;
  Reg(kWdogBase + kWdogCtrl) = 0x3;  // interrupt + reset enable: resets on the second expiry
  Reg(kWdogBase + kWdogLock) = 0;
}

void CmsdkWatchdog::DoKick() {
  Reg(kWdogBase + kWdogLock) = kWdogUnlock;
  Reg(kWdogBase + kWdogIntClr) = 1;
  Reg(kWdogBase + kWdogLoad) = reload_;
  Reg(kWdogBase + kWdogLock) = 0;
}

bool RamFlash::DoErase(size_t page) {
  if (page >= kPages) return false;
  for (auto& b : pages_[page]) b = 0xFF;
  return true;
}

bool RamFlash::DoProgram(size_t page, size_t offset, const uint8_t* data, size_t len) {
  if (page >= kPages || offset + len > kPageSize) return false;
  for (size_t i = 0; i < len; ++i) pages_[page][offset + i] &= data[i];
  return true;
}

bool RamFlash::DoRead(size_t page, size_t offset, uint8_t* data, size_t len) {
  if (page >= kPages || offset + len > kPageSize) return false;
  for (size_t i = 0; i < len; ++i) data[i] = pages_[page][offset + i];
  return true;
}

}  // namespace lw::hal::mps2
