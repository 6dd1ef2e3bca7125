#pragma once
#include <cstdint>

namespace lw::hal {

/// Independent watchdog: resets the MCU when not kicked within the timeout. Once started it
/// cannot be stopped (also not during sleep: the timeout must exceed the longest sleep).
class Watchdog {
 public:
  /// Starts the watchdog with `timeout_s` seconds (a port rounds up to what its prescaler
  /// allows). Called once at boot; a second call only restarts the countdown. Non-blocking.
  void Start(uint32_t timeout_s) { DoStart(timeout_s); }
  /// Restarts the countdown. Non-blocking; ISR-safe.
  void Kick() { DoKick(); }

 protected:
  ~Watchdog() = default;

 private:
  virtual void DoStart(uint32_t timeout_s) = 0;
  virtual void DoKick() = 0;
};

}  // namespace lw::hal
