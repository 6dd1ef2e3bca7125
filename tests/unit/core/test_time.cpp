#include "core/time.hpp"

#include <cstdio>
#include <ctime>

#include <CppUTest/TestHarness.h>

using namespace lw::core;

TEST_GROUP(Time){};

TEST(Time, ParsesTheUsualIsoForms) {
  const auto base = ParseIsoTime("2026-03-01T12:00:00Z");
  CHECK(base.has_value());
  STRCMP_EQUAL("2026-03-01T12:00:00Z", FormatIsoTime(*base).c_str());
  CHECK(ParseIsoTime("2026-03-01 12:00:00") == base);
  CHECK(ParseIsoTime("2026-03-01T12:00:00.750Z") == base);
  CHECK(ParseIsoTime("2026-03-01T14:00:00+02:00") == base);
  CHECK(ParseIsoTime("2026-03-01T07:00:00-0500") == base);
  CHECK(ParseIsoTime("2026-03-01T12:00Z") == base);
  STRCMP_EQUAL("2026-03-01T00:00:00Z", FormatIsoTime(*ParseIsoTime("2026-03-01")).c_str());
}

TEST(Time, RefusesImpossibleAndMalformedTimes) {
  for (const char* bad : {"", "2026-02-30", "2026-13-01T00:00:00Z", "2026-03-01T25:00:00Z", "yesterday", "2026/03/01",
                          "2026-03-01T12:00:00Q", "2026-03-01T12"}) {
    CHECK_FALSE(ParseIsoTime(bad).has_value());
  }
}

TEST(Time, DayArithmetic) {
  const auto a = *ParseIsoTime("2026-03-01");
  DOUBLES_EQUAL(1.5, DaysBetween(a, *ParseIsoTime("2026-03-02T12:00:00Z")), 1e-12);
  STRCMP_EQUAL("2026-03-03T06:00:00Z", FormatIsoTime(AddDays(a, 2.25)).c_str());
}

// The formatter writes its digits itself for years 0-9999 and falls back to snprintf outside them:
// both give strftime's %Y-%m-%dT%H:%M:%SZ with the year at least 4 digits.
TEST(Time, FormatsEverySecondOfTheDayAndYearAsStrftimeDoes) {
  for (int64_t s : {int64_t{0}, int64_t{59}, int64_t{3599}, int64_t{86399}, int64_t{951782400}, int64_t{1772366400},
                    int64_t{253402300799}, int64_t{-62167219200}, int64_t{-1}, int64_t{253402300800}}) {
    const std::time_t t = static_cast<std::time_t>(s);
    std::tm tm{};
    gmtime_r(&t, &tm);
    char want[40];
    std::snprintf(want, sizeof want, "%04d-%02d-%02dT%02d:%02d:%02dZ", tm.tm_year + 1900, tm.tm_mon + 1, tm.tm_mday, tm.tm_hour,
                  tm.tm_min, tm.tm_sec);
    STRCMP_EQUAL(want, FormatIsoTime(TimePoint(std::chrono::seconds(s))).c_str());
  }
}
