#pragma once
/// Everything the firmware application needs from a board, by reference. A port builds one of
/// these from its drivers; the host port builds it from simulator-controlled fakes.
#include "hal/adc.hpp"
#include "hal/flash.hpp"
#include "hal/gpio.hpp"
#include "hal/power.hpp"
#include "hal/rtc.hpp"
#include "hal/spi.hpp"
#include "hal/uart.hpp"
#include "hal/watchdog.hpp"

namespace lw::hal {

/// Non-owning: the port owns the drivers and must outlive every Board (and App) built from them.
struct Board {
  Spi& ladder_spi;           ///< daisy-chained parallel-in shift registers over the ladder
  DigitalOut& ladder_power;  ///< powers the ladder only while it is read
  Uart& radio;               ///< XBee module in API mode
  Adc& adc;                  ///< battery (mV) and temperature (degrees C)
  Rtc& rtc;                  ///< seconds clock with the wake-up alarm
  Power& power;              ///< sleep and reset cause
  Watchdog& watchdog;        ///< independent watchdog, kicked once per wake
  FlashPages& flash;         ///< at least two pages for the state slots
};

}  // namespace lw::hal
