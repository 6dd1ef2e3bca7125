// The STM32 port's ADC and IWDG drivers (hal/stm32/adc.hpp, iwdg.hpp) against register-level
// fakes: the F4 ADC (SWSTART, EOC cleared by reading DR) and the L4 ADC (ADCAL, ADEN/ADRDY,
// ADSTART, EOC), with the factory calibration words in system memory; an F4 ADC as QEMU models it
// (no EOC) must fail the read, bounded, without touching the calibration words QEMU does not map.
#include <cstdint>
#include <map>
#include <vector>

#include "hal/stm32/adc.hpp"
#include "hal/stm32/iwdg.hpp"
#include "hal/stm32/regs.hpp"

#include <CppUTest/TestHarness.h>

namespace st = lw::hal::stm32;

namespace {

enum class Family { kF4, kL4 };

// Raw 12-bit readings of a 3.6 V cell at 25 C, and the factory words (VREFINT taken at V_cal).
struct AdcModel {
  explicit AdcModel(Family f) : family(f) {}
  Family family;
  bool has_eoc = true;  // false: QEMU's F4 ADC
  uint32_t raw_vref = 0, raw_temp = 0;
  std::map<uintptr_t, uint8_t> system_memory;
  std::map<uintptr_t, uint32_t> regs;
  int status_reads = 0;
  bool calibration_read = false;

  void SetCal(uintptr_t addr, uint16_t v) {
    system_memory[addr] = static_cast<uint8_t>(v);
    system_memory[addr + 1] = static_cast<uint8_t>(v >> 8);
  }
  uintptr_t Base() const { return family == Family::kF4 ? st::f4::kAdc1 : st::l4::kAdc1; }
  uint32_t Channel() {
    return family == Family::kF4 ? regs[Base() + st::f4::kAdcSqr3] & 0x1F : (regs[Base() + st::l4::kAdcSqr1] >> 6) & 0x1F;
  }
  uint32_t Convert() {
    const uint32_t ch = Channel();
    if (family == Family::kF4) return ch == st::f4::kAdcChVrefint ? raw_vref : ch == st::f4::kAdcChTemp ? raw_temp : 0;
    return ch == st::l4::kAdcChVrefint ? raw_vref : ch == st::l4::kAdcChTemp ? raw_temp : 0;
  }
  uint32_t Read(uintptr_t a, int size) {
    if (a >= 0x1FFF0000 && a < 0x20000000) {
      calibration_read = true;
      CHECK_EQUAL(1, size);
      return system_memory.count(a) ? system_memory[a] : 0;
    }
    if (family == Family::kF4 && a == Base() + st::f4::kAdcSr) ++status_reads;
    if (family == Family::kL4 && a == Base() + st::l4::kAdcIsr) ++status_reads;
    if (family == Family::kF4 && a == Base() + st::f4::kAdcDr) regs[Base() + st::f4::kAdcSr] &= ~st::f4::kAdcSrEoc;
    if (family == Family::kL4 && a == Base() + st::l4::kAdcDr) regs[Base() + st::l4::kAdcIsr] &= ~st::l4::kAdcIsrEoc;
    return regs[a];
  }
  void Write(uintptr_t a, uint32_t v) {
    if (family == Family::kF4) {
      if (a == Base() + st::f4::kAdcCr2 && (v & st::f4::kAdcCr2Swstart) && (v & st::f4::kAdcCr2Adon) && has_eoc) {
        regs[Base() + st::f4::kAdcDr] = Convert();
        regs[Base() + st::f4::kAdcSr] |= st::f4::kAdcSrEoc;
        v &= ~st::f4::kAdcCr2Swstart;
      }
      regs[a] = v;
      return;
    }
    if (a == Base() + st::l4::kAdcIsr) {
      regs[a] &= ~v;  // write 1 to clear
      return;
    }
    if (a == Base() + st::l4::kAdcCr) {
      const bool regulator = (v & st::l4::kAdcCrAdvregen) && !(v & st::l4::kAdcCrDeeppwd);
      if ((v & st::l4::kAdcCrAdcal) && regulator) v &= ~st::l4::kAdcCrAdcal;  // calibration done
      if ((v & st::l4::kAdcCrAden) && regulator) regs[Base() + st::l4::kAdcIsr] |= st::l4::kAdcIsrAdrdy;
      if ((v & st::l4::kAdcCrAdstart) && (v & st::l4::kAdcCrAden)) {
        regs[Base() + st::l4::kAdcDr] = Convert();
        regs[Base() + st::l4::kAdcIsr] |= st::l4::kAdcIsrEoc;
        v &= ~st::l4::kAdcCrAdstart;
      }
    }
    regs[a] = v;
  }
};

AdcModel* g_adc = nullptr;
struct AdcIo {
  static uint32_t Read32(uintptr_t a) { return g_adc->Read(a, 4); }
  static void Write32(uintptr_t a, uint32_t v) { g_adc->Write(a, v); }
  static uint8_t Read8(uintptr_t a) { return static_cast<uint8_t>(g_adc->Read(a, 1)); }
  static void Write8(uintptr_t a, uint8_t v) { g_adc->Write(a, v); }
};

// A 3.6 V cell with the die at `die_c`: VREFINT 1.21 V, the sensor 0.76 V at 25 C and 2.5 mV/C.
void Wire(AdcModel& m, int32_t cal_mv, uintptr_t vref_cal, uintptr_t ts1, uintptr_t ts2, int32_t t1, int32_t t2,
          int32_t die_c = 25) {
  const double vref = 1.21, v25 = 0.76, slope = 0.0025;
  m.SetCal(vref_cal, static_cast<uint16_t>(vref / (cal_mv / 1000.0) * 4095.0 + 0.5));
  m.SetCal(ts1, static_cast<uint16_t>((v25 + slope * (t1 - 25)) / (cal_mv / 1000.0) * 4095.0 + 0.5));
  m.SetCal(ts2, static_cast<uint16_t>((v25 + slope * (t2 - 25)) / (cal_mv / 1000.0) * 4095.0 + 0.5));
  m.raw_vref = static_cast<uint32_t>(vref / 3.6 * 4095.0 + 0.5);
  m.raw_temp = static_cast<uint32_t>((v25 + slope * (die_c - 25)) / 3.6 * 4095.0 + 0.5);
}

}  // namespace

TEST_GROUP(Stm32Adc){void teardown() override{g_adc = nullptr;
}
}
;

TEST(Stm32Adc, F4ReadsTheBatteryFromVrefintAndTheDieTemperature) {
  AdcModel m(Family::kF4);
  Wire(m, 3300, st::f4::kVrefintCal, st::f4::kTsCal1, st::f4::kTsCal2, 30, 110);
  g_adc = &m;
  st::F4Adc<AdcIo> adc;
  adc.Init();
  lw::hal::Adc& a = adc;
  int32_t mv = 0, c = 0;
  CHECK_TRUE(a.Read(lw::hal::AdcChannel::kBatteryMillivolts, &mv));
  CHECK(mv >= 3590 && mv <= 3610);
  CHECK_TRUE(a.Read(lw::hal::AdcChannel::kTemperatureCelsius, &c));
  CHECK(c >= 23 && c <= 27);
  Wire(m, 3300, st::f4::kVrefintCal, st::f4::kTsCal1, st::f4::kTsCal2, 30, 110,
       85);  // far from the first calibration point: the second one's temperature matters
  CHECK_TRUE(a.Read(lw::hal::AdcChannel::kTemperatureCelsius, &c));
  CHECK(c >= 83 && c <= 87);
}

TEST(Stm32Adc, L4ReadsTheBatteryFromVrefintAndTheDieTemperature) {
  AdcModel m(Family::kL4);
  Wire(m, 3000, st::l4::kVrefintCal, st::l4::kTsCal1, st::l4::kTsCal2, 30, 130);
  g_adc = &m;
  st::L4Adc<AdcIo> adc;
  CHECK_TRUE(adc.Init());
  lw::hal::Adc& a = adc;
  int32_t mv = 0, c = 0;
  CHECK_TRUE(a.Read(lw::hal::AdcChannel::kBatteryMillivolts, &mv));
  CHECK(mv >= 3590 && mv <= 3610);
  CHECK_TRUE(a.Read(lw::hal::AdcChannel::kTemperatureCelsius, &c));
  CHECK(c >= 23 && c <= 27);
  Wire(m, 3000, st::l4::kVrefintCal, st::l4::kTsCal1, st::l4::kTsCal2, 30, 130,
       85);  // far from the first calibration point: the second one's temperature matters
  CHECK_TRUE(a.Read(lw::hal::AdcChannel::kTemperatureCelsius, &c));
  CHECK(c >= 83 && c <= 87);
}

TEST(Stm32Adc, AnF4AdcWithoutEndOfConversionAsQemuModelsItFailsBoundedAndReadsNoCalibration) {
  AdcModel m(Family::kF4);
  m.has_eoc = false;
  g_adc = &m;
  st::F4Adc<AdcIo> adc;
  adc.Init();
  lw::hal::Adc& a = adc;
  int32_t mv = 1234;
  CHECK_FALSE(a.Read(lw::hal::AdcChannel::kBatteryMillivolts, &mv));
  LONGS_EQUAL(1234, mv);  // untouched, as the contract says
  CHECK(m.status_reads <= static_cast<int>(st::kSpinLimit) + 4);
  CHECK_FALSE(m.calibration_read);
}

namespace {
struct IwdgModel {
  std::vector<uint32_t> keys;
  uint32_t pr = 0, rlr = 0xFFF;
};
IwdgModel* g_iwdg = nullptr;
struct IwdgIo {
  static uint32_t Read32(uintptr_t a) {
    CHECK(a == st::iwdg::kBase + st::iwdg::kSr);
    return 0;  // no update in progress
  }
  static void Write32(uintptr_t a, uint32_t v) {
    if (a == st::iwdg::kBase + st::iwdg::kKr) g_iwdg->keys.push_back(v);
    if (a == st::iwdg::kBase + st::iwdg::kPr) g_iwdg->pr = v;
    if (a == st::iwdg::kBase + st::iwdg::kRlr) g_iwdg->rlr = v;
  }
  static uint8_t Read8(uintptr_t) { return 0; }
  static void Write8(uintptr_t, uint8_t) {}
};
}  // namespace

TEST_GROUP(Stm32Iwdg){void teardown() override{g_iwdg = nullptr;
}
}
;

TEST(Stm32Iwdg, StartsUnlocksProgramsAndReloadsInThatOrderAndClampsToItsLongestTimeout) {
  IwdgModel m;
  g_iwdg = &m;
  st::Iwdg<IwdgIo> iwdg;
  lw::hal::Watchdog& w = iwdg;
  w.Start(10);
  CHECK((m.keys == std::vector<uint32_t>{0xCCCC, 0x5555, 0xAAAA}));
  LONGS_EQUAL(6, m.pr);  // /256: 125 counts a second
  LONGS_EQUAL(1250, m.rlr);
  LONGS_EQUAL(10, iwdg.timeout_s());
  w.Start(1860);  // the app's default: longer than the IWDG can count
  LONGS_EQUAL(0xFFF, m.rlr);
  LONGS_EQUAL(32, iwdg.timeout_s());
  m.keys.clear();
  w.Kick();
  CHECK((m.keys == std::vector<uint32_t>{0xAAAA}));
}
