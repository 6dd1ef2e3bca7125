// The STM32 RTC clock's seconds (hal/stm32/clock.hpp, CalendarSeconds): the RTC calendar's BCD
// time and date registers, as both families lay them out, to seconds since 2000-01-01.
#include <cstdint>

#include "hal/stm32/clock.hpp"

#include <CppUTest/TestHarness.h>

namespace {

// TR: HT HU : MNT MNU : ST SU (24-hour); DR: YT YU, weekday, MT MU, DT DU.
constexpr uint32_t Tr(uint32_t h, uint32_t m, uint32_t s) {
  return ((h / 10) << 20) | ((h % 10) << 16) | ((m / 10) << 12) | ((m % 10) << 8) | ((s / 10) << 4) | (s % 10);
}
constexpr uint32_t Dr(uint32_t y, uint32_t mo, uint32_t d, uint32_t weekday) {
  return ((y / 10) << 20) | ((y % 10) << 16) | (weekday << 13) | ((mo / 10) << 12) | ((mo % 10) << 8) | ((d / 10) << 4) |
         (d % 10);
}

}  // namespace

TEST_GROUP(Stm32Rtc){};

TEST(Stm32Rtc, CalendarRegistersToSecondsSince2000) {
  using lw::hal::stm32::CalendarSeconds;
  LONGS_EQUAL(0, CalendarSeconds(0, lw::hal::stm32::rtc::kDr20000101));  // the first power-up's start
  LONGS_EQUAL(5184000, CalendarSeconds(Tr(0, 0, 0), Dr(0, 3, 1, 3)));    // 2000 is a leap year
  LONGS_EQUAL(730944000, CalendarSeconds(Tr(0, 0, 0), Dr(23, 3, 1, 3)));
  LONGS_EQUAL(762523200, CalendarSeconds(Tr(12, 0, 0), Dr(24, 2, 29, 4)));
  LONGS_EQUAL(849591300, CalendarSeconds(Tr(5, 35, 0), Dr(26, 12, 3, 4)));
  UNSIGNED_LONGS_EQUAL(3155759999u, CalendarSeconds(Tr(23, 59, 59), Dr(99, 12, 31, 4)));
}

TEST(Stm32Rtc, SecondsAreMonotonicAcrossEveryDayOfALeapYearAndTheNewYear) {
  using lw::hal::stm32::CalendarSeconds;
  constexpr uint32_t kDays[12] = {31, 29, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  uint32_t last = CalendarSeconds(Tr(23, 59, 59), Dr(27, 12, 31, 5));
  for (uint32_t month = 1; month <= 12; ++month) {
    for (uint32_t day = 1; day <= kDays[month - 1]; ++day) {
      const uint32_t midnight = CalendarSeconds(Tr(0, 0, 0), Dr(28, month, day, 1));
      LONGS_EQUAL(last + 1, midnight);  // 23:59:59 the day before, then 00:00:00
      last = CalendarSeconds(Tr(23, 59, 59), Dr(28, month, day, 1));
      LONGS_EQUAL(midnight + 86399, last);
    }
  }
  LONGS_EQUAL(last + 1, CalendarSeconds(Tr(0, 0, 0), Dr(29, 1, 1, 1)));
}
