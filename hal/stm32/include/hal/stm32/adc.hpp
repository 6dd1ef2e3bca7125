#pragma once
/// Battery and die temperature from the internal channels. The sensor runs straight from its cell
/// (a 3.6 V Li-SOCl2 cell within the L4's 1.71-3.6 V range, no regulator), so VDDA is the battery:
/// battery_mV = V_cal x VREFINT_CAL / raw(VREFINT), with the factory calibration taken at V_cal.
/// Temperature interpolates between the two factory points TS_CAL1 and TS_CAL2.
/// Every wait is bounded and Read() returns false when a conversion does not complete. Under QEMU
/// (netduinoplus2) the F4 ADC is modelled without its end-of-conversion flag and the common
/// registers (VREFINT/sensor enable), so Read() returns false there: the record then carries no
/// battery value. The calibration words are only read after a completed conversion (QEMU maps no
/// system memory at their address).
#include <cstdint>

#include "hal/adc.hpp"
#include "hal/stm32/mmio.hpp"
#include "hal/stm32/regs.hpp"

namespace lw::hal::stm32 {

namespace detail {
template <class Io>
uint16_t Cal16(uintptr_t addr) {
  return static_cast<uint16_t>(Io::Read8(addr) | (Io::Read8(addr + 1) << 8));
}
template <class Io>
bool ToUnits(AdcChannel channel, uint32_t raw_vref, uint32_t raw_temp, uintptr_t vref_cal, uintptr_t ts1, uintptr_t ts2,
             int32_t cal_mv, int32_t t1, int32_t t2, int32_t* value) {
  if (raw_vref == 0) return false;
  const int32_t vdd_mv = static_cast<int32_t>(static_cast<uint32_t>(cal_mv) * Cal16<Io>(vref_cal) / raw_vref);
  if (channel == AdcChannel::kBatteryMillivolts) {
    *value = vdd_mv;
    return true;
  }
  const int32_t c1 = Cal16<Io>(ts1), c2 = Cal16<Io>(ts2);
  if (c2 == c1) return false;
  const int32_t raw_at_cal = static_cast<int32_t>(raw_temp) * vdd_mv / cal_mv;  // as if measured at V_cal
  *value = (raw_at_cal - c1) * (t2 - t1) / (c2 - c1) + t1;
  return true;
}
}  // namespace detail

/// STM32F4 ADC1: VREFINT = channel 17, temperature sensor = channel 16 (F40x).
template <class Io = Mmio>
class F4Adc final : public Adc {
 public:
  void Init() {
    Io::Write32(f4::kRccApb2enr, Io::Read32(f4::kRccApb2enr) | f4::kApb2Adc1);
    Io::Write32(f4::kAdcCcr, f4::kAdcCcrTsvrefe | f4::kAdcCcrPclkDiv4);
    Io::Write32(f4::kAdc1 + f4::kAdcSmpr1, (7u << 18) | (7u << 21));  // 480 cycles on ch16, ch17
    Io::Write32(f4::kAdc1 + f4::kAdcSqr1, 0);                         // one conversion
    Io::Write32(f4::kAdc1 + f4::kAdcCr2, f4::kAdcCr2Adon);
  }

 private:
  static bool Convert(uint32_t channel, uint32_t* raw) {
    Io::Write32(f4::kAdc1 + f4::kAdcSqr3, channel);
    Io::Write32(f4::kAdc1 + f4::kAdcSr, 0);
    Io::Write32(f4::kAdc1 + f4::kAdcCr2, f4::kAdcCr2Adon | f4::kAdcCr2Swstart);
    if (!WaitSet<Io>(f4::kAdc1 + f4::kAdcSr, f4::kAdcSrEoc)) return false;
    *raw = Io::Read32(f4::kAdc1 + f4::kAdcDr) & 0xFFFu;
    return true;
  }
  bool DoRead(AdcChannel channel, int32_t* value) override {
    uint32_t vref = 0, temp = 0;
    if (!Convert(f4::kAdcChVrefint, &vref)) return false;
    if (channel == AdcChannel::kTemperatureCelsius && !Convert(f4::kAdcChTemp, &temp)) return false;
    return detail::ToUnits<Io>(channel, vref, temp, f4::kVrefintCal, f4::kTsCal1, f4::kTsCal2, f4::kCalMillivolts, f4::kTsCal1C,
                               f4::kTsCal2C, value);
  }
};

/// STM32L4 ADC1: VREFINT = channel 0, temperature sensor = channel 17. Leaves deep power-down,
/// starts the regulator, calibrates, and is enabled once; sampled at 640.5 cycles (the internal
/// channels need >= 4 us).
template <class Io = Mmio>
class L4Adc final : public Adc {
 public:
  bool Init() {
    Io::Write32(l4::kRccCcipr, Io::Read32(l4::kRccCcipr) | l4::kCcipAdcSelSysclk);
    Io::Write32(l4::kRccAhb2enr, Io::Read32(l4::kRccAhb2enr) | l4::kAhb2Adc);
    Io::Write32(l4::kAdcCcr, l4::kAdcCcrVrefen | l4::kAdcCcrTsen | l4::kAdcCcrHclkDiv1);
    const uintptr_t cr = l4::kAdc1 + l4::kAdcCr;
    Io::Write32(cr, 0);  // DEEPPWD off
    Io::Write32(cr, l4::kAdcCrAdvregen);
    for (uint32_t i = 0; i < 2000; ++i) (void)Io::Read32(cr);  // t_ADCVREG_STUP = 20 us, at up to 80 MHz
    Io::Write32(cr, l4::kAdcCrAdvregen | l4::kAdcCrAdcal);
    if (!WaitClear<Io>(cr, l4::kAdcCrAdcal)) return false;
    Io::Write32(l4::kAdc1 + l4::kAdcSmpr1, 7u);        // ch0: 640.5 cycles
    Io::Write32(l4::kAdc1 + l4::kAdcSmpr2, 7u << 21);  // ch17: 640.5 cycles
    Io::Write32(l4::kAdc1 + l4::kAdcIsr, l4::kAdcIsrAdrdy);
    Io::Write32(cr, l4::kAdcCrAdvregen | l4::kAdcCrAden);
    ready_ = WaitSet<Io>(l4::kAdc1 + l4::kAdcIsr, l4::kAdcIsrAdrdy);
    return ready_;
  }

 private:
  static bool Convert(uint32_t channel, uint32_t* raw) {
    Io::Write32(l4::kAdc1 + l4::kAdcSqr1, channel << 6);  // L = 0 (one), SQ1 = channel
    Io::Write32(l4::kAdc1 + l4::kAdcIsr, l4::kAdcIsrEoc);
    const uintptr_t cr = l4::kAdc1 + l4::kAdcCr;
    Io::Write32(cr, Io::Read32(cr) | l4::kAdcCrAdstart);
    if (!WaitSet<Io>(l4::kAdc1 + l4::kAdcIsr, l4::kAdcIsrEoc)) return false;
    *raw = Io::Read32(l4::kAdc1 + l4::kAdcDr) & 0xFFFu;
    return true;
  }
  bool DoRead(AdcChannel channel, int32_t* value) override {
    if (!ready_) return false;
    uint32_t vref = 0, temp = 0;
    if (!Convert(l4::kAdcChVrefint, &vref)) return false;
    if (channel == AdcChannel::kTemperatureCelsius && !Convert(l4::kAdcChTemp, &temp)) return false;
    return detail::ToUnits<Io>(channel, vref, temp, l4::kVrefintCal, l4::kTsCal1, l4::kTsCal2, l4::kCalMillivolts, l4::kTsCal1C,
                               l4::kTsCal2C, value);
  }
  bool ready_ = false;
};

}  // namespace lw::hal::stm32
