#pragma once

namespace lw::hal {

/// A digital output (e.g. the ladder's power switch). Non-blocking; ISR-safe on every port.
class DigitalOut {
 public:
  /// Drives the pin high (`true`) or low. Takes effect before the call returns.
  void Set(bool high) { DoSet(high); }

 protected:
  ~DigitalOut() = default;

 private:
  virtual void DoSet(bool high) = 0;
};

}  // namespace lw::hal
