#include "core/cmdline.hpp"
#include "unit/core/temp_dir.hpp"

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

TEST_GROUP(CommandLine) { lw::test::ScratchDir dir; };

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
