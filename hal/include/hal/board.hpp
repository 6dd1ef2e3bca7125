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

struct Board {
  Spi& ladder_spi;           ///< daisy-chained parallel-in shift registers over the ladder
  DigitalOut& ladder_power;  ///< powers the ladder only while it is read
  Uart& radio;               ///< XBee module in API mode
  Adc& adc;
  Rtc& rtc;
  Power& power;
  Watchdog& watchdog;
  FlashPages& flash;         ///< at least two pages for the state slots
};

}  // namespace lw::hal
