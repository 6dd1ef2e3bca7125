#pragma once
#include <cstdint>

namespace lw::hal {

/// Why the MCU last reset (ports map their reset-status register onto these).
enum class ResetCause : uint8_t {
  kPowerOn = 0,  ///< supply applied (or the cause is unknown)
  kWatchdog,     ///< the watchdog was not kicked in time
  kSoftware,     ///< the firmware requested the reset
  kBrownout,     ///< the supply dipped below the brown-out threshold
  kPin,          ///< the reset pin was pulled
};

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
