#include "core/cmdline.hpp"
#include "support/temp_directory.hpp"

#include <functional>
#include <map>

#include <CppUTest/TestHarness.h>

using namespace lw::core;

namespace {
std::string ErrorOf(const std::vector<std::string>& args) {
  try {
    ParseCommandLine(args, {}, [](const std::string&, const std::string&) {});
  } catch (const UsageError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST_GROUP(CommandLine) { lw::test::TempDirectory dir; };

TEST(CommandLine, ConfigFileThenFlagsInOrder) {
  const auto file = dir.Write("c.json", R"({"days": 30, "rate_hz": 1.5, "verbose": true, "name": "x"})");
  std::map<std::string, std::string> got;
  std::vector<std::string> order;
  CHECK(ParseCommandLine({"--config", file.string(), "--days=7", "--quiet"}, {"quiet"},
                         [&](const std::string& k, const std::string& v) {
                           got[k] = v;
                           order.push_back(k);
                         }));
  CHECK_EQUAL(std::string("7"), got["days"]);  // the flag overrides the file
  CHECK_EQUAL(std::string("1.5"), got["rate-hz"]);
  CHECK_EQUAL(std::string("true"), got["verbose"]);
  CHECK_EQUAL(std::string("true"), got["quiet"]);
  CHECK_EQUAL(std::string("quiet"), order.back());
}

TEST(CommandLine, BadConfigFilesAreUsageErrors) {
  const auto file = dir.Write("bad.json", R"({"days": )");
  CHECK(ErrorOf({"--config", file.string()}).find("not valid JSON") != std::string::npos);
  dir.Write("bad.json", R"({"days": [1]})");
  CHECK(ErrorOf({"--config", file.string()}).find("\"days\" must be a string, a number or a boolean") != std::string::npos);
  CHECK(ErrorOf({"--config", (dir.path() / "none.json").string()}).find("cannot read") != std::string::npos);
}

// Found by fuzz/ (fuzz_config): a number beyond double range made nlohmann::json throw
// out_of_range (not parse_error), which escaped ParseCommandLine instead of a UsageError.
TEST(CommandLine, NumberBeyondDoubleRangeInConfigIsAUsageError) {
  const auto file = dir.Write("huge.json", R"({"days": 1.5e3527})");
  const std::string e = ErrorOf({"--config", file.string()});
  CHECK_TEXT(e.find("--config") != std::string::npos && e.find("not valid JSON") != std::string::npos, e.c_str());
}

namespace {
std::string RangeErrorOf(const std::function<void()>& parse) {
  try {
    parse();
  } catch (const UsageError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

// Integer options are checked against their range and never truncated into it (a static_cast of
// 4294967297 to int is 1: the gateway took `--api-mode 4294967297` as API mode 1).
TEST(CommandLine, WholeNumbersAreRangeCheckedNeverTruncated) {
  LONGS_EQUAL(2, ParseWholeNumber("api-mode", "2", 1, 2));
  LONGS_EQUAL(-7, ParseWholeNumber("offset", "-7", -10, 10));
  LONGS_EQUAL(5, ParseWholeNumber("n", "+5", 0, 10));
  STRCMP_EQUAL("--api-mode 4294967297 is out of range (allowed: [1, 2])",
               RangeErrorOf([] { ParseWholeNumber("api-mode", "4294967297", 1, 2); }).c_str());
  STRCMP_EQUAL("--api-mode 0 is out of range (allowed: [1, 2])", RangeErrorOf([] { ParseWholeNumber("api-mode", "0", 1, 2); }).c_str());
  STRCMP_EQUAL("--n 99999999999999999999 is out of range (allowed: [0, 10])",
               RangeErrorOf([] { ParseWholeNumber("n", "99999999999999999999", 0, 10); }).c_str());
  for (const char* bad : {"", "1.5", "1e3", "12abc", " 3", "3 ", "0x10", "-", "+", "+-1"}) {
    const std::string e = RangeErrorOf([bad] { ParseWholeNumber("n", bad, 0, 10); });
    CHECK_TEXT(e == std::string("--n '") + bad + "' is not a whole number (allowed: [0, 10])", e.c_str());
  }
  // The typed accessor: a whole range of the type by default, nothing wraps.
  LONGS_EQUAL(65535, ParseInteger<uint16_t>("port", "65535"));
  STRCMP_EQUAL("--port 65536 is out of range (allowed: [0, 65535])", RangeErrorOf([] { ParseInteger<uint16_t>("port", "65536"); }).c_str());
  STRCMP_EQUAL("--seed -1 is out of range (allowed: [0, 18446744073709551615])",
               RangeErrorOf([] { ParseInteger<uint64_t>("seed", "-1"); }).c_str());
  CHECK(ParseInteger<uint64_t>("seed", "18446744073709551615") == UINT64_MAX);
  CHECK(ParseInteger<uint64_t>("seed", "9007199254740993") == 9007199254740993ull);  // beyond a double's 53 bits
  STRCMP_EQUAL("--seed 18446744073709551616 is out of range (allowed: [0, 18446744073709551615])",
               RangeErrorOf([] { ParseInteger<uint64_t>("seed", "18446744073709551616"); }).c_str());
  STRCMP_EQUAL("--ms 2147483648 is out of range (allowed: [-2147483648, 2147483647])",
               RangeErrorOf([] { ParseInteger<int>("ms", "2147483648"); }).c_str());
}
