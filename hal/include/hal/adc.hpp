#pragma once
#include <cstdint>

namespace lw::hal {

/// What an analog read measures; the port converts to the unit named here.
enum class AdcChannel : uint8_t {
  kBatteryMillivolts = 0,   ///< battery terminal voltage, mV
  kTemperatureCelsius = 1,  ///< die or board temperature, whole degrees Celsius
};

/// Analog inputs, already converted to the channel's unit. Blocking (one conversion, < 1 ms).
class Adc {
 public:
  /// Returns false when the conversion failed; `*value` is then untouched.
  bool Read(AdcChannel channel, int32_t* value) { return DoRead(channel, value); }

 protected:
  ~Adc() = default;

 private:
  virtual bool DoRead(AdcChannel channel, int32_t* value) = 0;
};

}  // namespace lw::hal
