// core::Clock: the wall clock, and the simulator's clock file with its one fallback (the last good
// value; the wall clock before the first).
#include <cstdint>
#include <string>

#include "core/atomic_file.hpp"
#include "core/clock.hpp"
#include "support/temp_directory.hpp"

#include <CppUTest/TestHarness.h>  // last

using lw::core::Clock;
using lw::core::WallClockMs;

TEST_GROUP(Clock) {
  lw::test::TempDirectory dir{"lw-clock"};
  void Set(const std::string& text) {
    lw::core::WriteFileAtomically(dir.File("clock"), text);
  }
};

TEST(Clock, WallClockIsTheSystemClock) {
  const Clock wall;
  const int64_t before = WallClockMs();
  const int64_t now = wall.NowMs();
  const int64_t after = WallClockMs();
  CHECK(before <= now && now <= after);
  CHECK(now > 1'700'000'000'000LL);  // after 2023-11: Unix ms, not seconds
  CHECK(wall.ok());
  CHECK_FALSE(wall.is_file());
  CHECK_FALSE(Clock("").is_file());
}

TEST(Clock, FileBeforeItsFirstGoodValueFallsBackToTheWallClock) {
  const Clock clock(dir.File("clock"));  // no file yet
  const int64_t before = WallClockMs();
  const int64_t now = clock.NowMs();
  CHECK(before <= now && now <= WallClockMs());
  CHECK_FALSE(clock.ok());
  Set("not a time\n");
  CHECK(clock.NowMs() >= before);
  CHECK_FALSE(clock.ok());
}

TEST(Clock, FileKeepsTheLastGoodValueWhenItTurnsBad) {
  const Clock clock(dir.File("clock"));
  CHECK(clock.is_file());
  Set("1767571200123\n");
  CHECK(clock.NowMs() == 1767571200123LL);
  CHECK(clock.ok());
  for (const char* bad : {"12x4", "", "-5", " 17", "1767571300000x", "9999999999999999999"}) {
    Set(bad);
    CHECK_TEXT(clock.NowMs() == 1767571200123LL, bad);
    CHECK_TEXT(!clock.ok(), bad);
  }
  Set("1767571300000");  // no newline
  CHECK(clock.NowMs() == 1767571300000LL);
  CHECK(clock.ok());
  Set("1767571400000\r\n");
  CHECK(clock.NowMs() == 1767571400000LL);
  std::filesystem::remove(dir.File("clock"));  // gone: the last good value
  CHECK(clock.NowMs() == 1767571400000LL);
  CHECK_FALSE(clock.ok());
}
