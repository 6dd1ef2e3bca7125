#include "core/log.hpp"

#include <sstream>
#include <string>

#include <CppUTest/TestHarness.h>  // last: its leak-detection macros clash with std headers

using lw::core::Logger;
using lw::core::LogLimiter;
using lw::core::SanitizeForLog;

namespace {
size_t CountLines(const std::string& text) {
  size_t n = 0;
  for (const char ch : text) n += ch == '\n';
  return n;
}
}  // namespace

TEST_GROUP(Log){};

TEST(Log, SanitizeEscapesControlBytesAndCuts) {
  STRCMP_EQUAL("plain text 123", SanitizeForLog("plain text 123").c_str());
  STRCMP_EQUAL("a\\x0Ab\\x0Dc\\x1B[31m\\x7F\\\\x", SanitizeForLog("a\nb\rc\x1B[31m\x7F\\x").c_str());
  STRCMP_EQUAL("abc... (6 bytes)", SanitizeForLog("abcdef", 3).c_str());
}

// Finding (server): a newline plus ANSI escapes in a reading's `time` or `sensor` forged a log
// line. Every line the Logger writes is one line, whatever it is given.
TEST(Log, ALoggedFieldCannotForgeALine) {
  std::ostringstream out;
  Logger log(out, "linerwatch-server", [] { return std::string("2026-01-01T00:00:00Z"); });
  log("rejected linerwatch/v1/s/c/sensors/1/reading: time '2026\n2026-01-01T00:00:00Z linerwatch-server: \x1B[32mall good'");
  LONGS_EQUAL(1, CountLines(out.str()));
  CHECK(out.str().find('\x1B') == std::string::npos);
  CHECK(out.str().rfind("2026-01-01T00:00:00Z linerwatch-server: rejected ", 0) == 0);
  CHECK(out.str().find("\\x0A2026-01-01T00:00:00Z linerwatch-server: \\x1B[32mall good") != std::string::npos);
}

// Finding (server): 2,000 bad messages wrote 103 MB of log. A kind of message is written the
// first LogLimiter::kFirst times, then every kEvery-th with its count; each line is cut.
TEST(Log, RepeatedMessagesAreRateLimitedAndLinesAreCut) {
  std::ostringstream out;
  Logger log(out, "linerwatch-server");
  const std::string huge(50'000, 'x');
  for (int i = 0; i < 2000; ++i) log.Limited("ingest rejected", "rejected: " + huge);
  log.Limited("ingest conflict", "conflict: another kind is counted apart");
  LONGS_EQUAL(LogLimiter::kFirst + 2 + 1, CountLines(out.str()));  // 10 + the 1000th and 2000th + the other kind
  CHECK(out.str().find("(2000 so far)") != std::string::npos);
  CHECK(out.str().find("another kind") != std::string::npos);
  CHECK(out.str().size() < 14 * 2100);
}
