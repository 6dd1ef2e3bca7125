#pragma once
#include <cstdint>

namespace lw::hal {

enum class ResetCause : uint8_t { kPowerOn = 0, kWatchdog, kSoftware, kBrownout, kPin };

/// Low-power control.
class Power {
 public:
  /// Enters the lowest-power mode that keeps the RTC and RAM; returns after the RTC alarm (or a
  /// radio interrupt) wakes the core. Blocking by design.
  void Sleep() { DoSleep(); }
  /// Why the MCU last reset; stable for the whole boot.
  ResetCause LastResetCause() { return DoLastResetCause(); }

 protected:
  ~Power() = default;

 private:
  virtual void DoSleep() = 0;
  virtual ResetCause DoLastResetCause() = 0;
};

}  // namespace lw::hal
