#pragma once
#include <cstdint>

namespace lw::hal {

/// Real-time clock with one alarm; keeps running through sleep and resets (battery domain).
class Rtc {
 public:
  /// Seconds since an arbitrary epoch fixed at manufacture; monotonic. ISR-safe.
  uint32_t NowSeconds() { return DoNowSeconds(); }
  /// Arms the wake-up alarm for the absolute time `at_seconds` (replaces any earlier alarm).
  void SetAlarm(uint32_t at_seconds) { DoSetAlarm(at_seconds); }

 protected:
  ~Rtc() = default;

 private:
  virtual uint32_t DoNowSeconds() = 0;
  virtual void DoSetAlarm(uint32_t at_seconds) = 0;
};

}  // namespace lw::hal
