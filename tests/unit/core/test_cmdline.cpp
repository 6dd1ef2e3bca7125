// core::ParseOptions, the one command-line parser: a table of options drives parsing, the checks
// of every value, the config file and --help; every error names the flag (or file and key) and the
// bad value.
#include "core/cmdline.hpp"
#include "support/temp_directory.hpp"

#include <functional>
#include <string>
#include <vector>

#include <CppUTest/TestHarness.h>

using namespace lw::core;

namespace {

const OptionTable& Table() {
  static const OptionTable table{{
      Option::Text("serial", "PATH", "coordinator serial port").Required(),
      Option::Whole("baud", "N", 1200, 921600, "serial baud rate (default 9600)"),
      Option::Number("loss", "P", NumberRange{0, 1, false, true}, "probability that a packet is lost\n(default 0)"),
      Option::Number("republish-after", "S", NumberRange::Positive(), "seconds"),
      Option::Unsigned("seed", "N", "random seed"),
      Option::Text("effect", "NAME", "an effect (repeatable)").Repeatable(),
      Option::Switch("quiet", "no progress lines"),
  }};
  return table;
}

std::string ErrorOf(const OptionTable& table, const std::vector<std::string>& args) {
  try {
    ParseOptions(table, args);
  } catch (const UsageError& e) {
    return e.what();
  }
  return "(no error)";
}
std::string ErrorOf(const std::vector<std::string>& args) {
  return ErrorOf(Table(), args);
}

std::vector<std::string> With(std::vector<std::string> extra) {
  std::vector<std::string> args{"--serial", "/dev/ttyUSB0"};
  args.insert(args.end(), extra.begin(), extra.end());
  return args;
}

}  // namespace

TEST_GROUP(CommandLine) {
  lw::test::TempDirectory dir;
};

TEST(CommandLine, TypedValuesAndDefaults) {
  const ParsedOptions o = ParseOptions(Table(), With({"--baud=115200", "--loss", "0.25", "--seed", "18446744073709551615",
                                                      "--quiet", "--republish_after", "2.5"}));
  CHECK_FALSE(o.help());
  STRCMP_EQUAL("/dev/ttyUSB0", o.Text("serial").c_str());
  LONGS_EQUAL(115200, o.Integer<int>("baud", 9600));
  DOUBLES_EQUAL(0.25, o.Number("loss", 0), 0);
  DOUBLES_EQUAL(2.5, o.Number("republish-after", 30), 0);
  CHECK(o.Integer<uint64_t>("seed", 1) == UINT64_MAX);
  CHECK(o.Switch("quiet"));
  STRCMP_EQUAL("--baud", o.Where("baud").c_str());
  const ParsedOptions d = ParseOptions(Table(), With({}));
  LONGS_EQUAL(9600, d.Integer<int>("baud", 9600));
  DOUBLES_EQUAL(30, d.Number("republish-after", 30), 0);
  CHECK_FALSE(d.Switch("quiet"));
  CHECK_FALSE(d.Has("effect"));
  CHECK(d.Texts("effect").empty());
}

TEST(CommandLine, BadNumbersNameTheFlagTheValueAndTheRange) {
  STRCMP_EQUAL("--baud 'fast' is not a whole number (allowed: [1200, 921600])", ErrorOf(With({"--baud", "fast"})).c_str());
  STRCMP_EQUAL("--baud 12 is out of range (allowed: [1200, 921600])", ErrorOf(With({"--baud=12"})).c_str());
  // The unchecked std::stod this parser replaced took "0.3x" as 0.3 and "nan" as a number.
  STRCMP_EQUAL("--loss '0.3x' is not a number", ErrorOf(With({"--loss", "0.3x"})).c_str());
  STRCMP_EQUAL("--loss 'nan' is not a number", ErrorOf(With({"--loss", "nan"})).c_str());
  STRCMP_EQUAL("--loss '' is not a number", ErrorOf(With({"--loss="})).c_str());
  STRCMP_EQUAL("--loss 1 is out of range (allowed: [0, 1))", ErrorOf(With({"--loss", "1"})).c_str());
  STRCMP_EQUAL("--republish-after 0 is out of range (allowed: (0, inf))", ErrorOf(With({"--republish-after", "0"})).c_str());
  STRCMP_EQUAL("--seed -1 is out of range (allowed: [0, 18446744073709551615])", ErrorOf(With({"--seed", "-1"})).c_str());
  STRCMP_EQUAL("--quiet 'yes' must be true or false", ErrorOf(With({"--quiet=yes"})).c_str());
}

TEST(CommandLine, MissingValueUnknownFlagAndStrayArgumentAreNamed) {
  STRCMP_EQUAL("--baud needs a value", ErrorOf(With({"--baud"})).c_str());
  STRCMP_EQUAL("--config needs a value", ErrorOf(With({"--config"})).c_str());
  STRCMP_EQUAL("unknown option --bogus (see --help)", ErrorOf(With({"--bogus", "1"})).c_str());
  STRCMP_EQUAL("unknown option --bogus (see --help)", ErrorOf(With({"--bogus=1"})).c_str());
  STRCMP_EQUAL("unexpected argument 'extra' (see --help)", ErrorOf(With({"extra"})).c_str());
  STRCMP_EQUAL("--serial is required (see --help)", ErrorOf({"--baud", "9600"}).c_str());
}

TEST(CommandLine, RepeatedFlagIsRefusedUnlessRepeatable) {
  STRCMP_EQUAL("--baud is given twice ('9600' and '19200'); it takes one value",
               ErrorOf(With({"--baud", "9600", "--baud=19200"})).c_str());
  STRCMP_EQUAL("--serial is given twice ('/dev/ttyUSB0' and '/dev/ttyS1'); it takes one value",
               ErrorOf(With({"--serial", "/dev/ttyS1"})).c_str());
  const auto cfg = dir.Write("c.json", "{}");
  CHECK(ErrorOf(With({"--config", cfg.string(), "--config", cfg.string()})).find("--config is given twice") == 0);
  const ParsedOptions o = ParseOptions(Table(), With({"--effect", "a", "--effect=b"}));
  CHECK(o.Texts("effect") == std::vector<std::string>({"a", "b"}));
  STRCMP_EQUAL("b", o.Text("effect").c_str());
}

TEST(CommandLine, HelpWinsAndNothingElseIsChecked) {
  CHECK(ParseOptions(Table(), {"--bogus", "--help"}).help());
  CHECK(ParseOptions(Table(), {"-h"}).help());
}

TEST(CommandLine, ConfigFileUnderTheFlags) {
  const auto file = dir.Write("c.json", R"({"serial": "/dev/ttyS1", "baud": 57600, "republish_after": 1.5, "quiet": true,
                                            "effect": ["x", "y"], "seed": 18446744073709551615})");
  const ParsedOptions o = ParseOptions(Table(), {"--config", file.string(), "--baud=19200", "--effect", "z"});
  STRCMP_EQUAL("/dev/ttyS1", o.Text("serial").c_str());  // required, given by the file
  LONGS_EQUAL(19200, o.Integer<int>("baud", 0));         // the flag overrides the file
  DOUBLES_EQUAL(1.5, o.Number("republish-after", 0), 0);
  CHECK(o.Switch("quiet"));
  CHECK(o.Integer<uint64_t>("seed", 0) == UINT64_MAX);
  CHECK(o.Texts("effect") == std::vector<std::string>({"x", "y", "z"}));  // the file's first
  STRCMP_EQUAL(("config " + file.string() + ", key 'republish-after'").c_str(), o.Where("republish-after").c_str());
  STRCMP_EQUAL("--baud", o.Where("baud").c_str());
  // Numbers may also be written as strings (as the older readers took them).
  dir.Write("c.json", R"({"serial": "s", "baud": "57600"})");
  LONGS_EQUAL(57600, ParseOptions(Table(), {"--config", file.string()}).Integer<int>("baud", 0));
}

TEST(CommandLine, BadConfigFilesNameTheFileAndTheKey) {
  const auto file = dir.Write("bad.json", R"({"serial": "s", "baud": 4294967297})");
  const std::string f = file.string();
  STRCMP_EQUAL(("config " + f + ", key 'baud': --baud 4294967297 is out of range (allowed: [1200, 921600])").c_str(),
               ErrorOf({"--config", f}).c_str());
  dir.Write("bad.json", R"({"serial": "s", "baud": 9600.5})");
  STRCMP_EQUAL(("config " + f + ", key 'baud': must be a whole number").c_str(), ErrorOf({"--config", f}).c_str());
  dir.Write("bad.json", R"({"serial": "s", "loss": "lots"})");
  STRCMP_EQUAL(("config " + f + ", key 'loss': --loss 'lots' is not a number").c_str(), ErrorOf({"--config", f}).c_str());
  dir.Write("bad.json", R"({"serial": ["a"]})");
  STRCMP_EQUAL(("config " + f + ", key 'serial': must be a string").c_str(), ErrorOf({"--config", f}).c_str());
  dir.Write("bad.json", R"({"serial": "s", "quiet": 1})");
  STRCMP_EQUAL(("config " + f + ", key 'quiet': must be true or false").c_str(), ErrorOf({"--config", f}).c_str());
  dir.Write("bad.json", R"({"serial": "s", "colour": "red"})");
  STRCMP_EQUAL(("config " + f + ": unknown key 'colour' (see --help)").c_str(), ErrorOf({"--config", f}).c_str());
  // Every error of the file is a ConfigFileError (programs may report a bad file apart from a bad flag).
  const auto FileErrorOf = [&](const std::string& path) -> std::string {
    try {
      ParseOptions(Table(), {"--config", path});
    } catch (const ConfigFileError& e) {
      return e.what();
    }
    return "(no ConfigFileError)";
  };
  STRCMP_EQUAL(("config " + f + ": unknown key 'colour' (see --help)").c_str(), FileErrorOf(f).c_str());
  dir.Write("bad.json", R"({"days": )");
  CHECK(FileErrorOf(f).find("config " + f + ": invalid JSON: ") == 0);
  dir.Write("bad.json", "[1]");
  STRCMP_EQUAL(("config " + f + ": must be a JSON object of option names to values").c_str(), FileErrorOf(f).c_str());
  STRCMP_EQUAL(("config " + dir.File("none.json") + ": cannot be read").c_str(), FileErrorOf(dir.File("none.json")).c_str());
  // A key given twice: nlohmann kept the last value silently.
  dir.Write("bad.json", R"({"serial": "s", "baud": 9600, "baud": 115200})");
  STRCMP_EQUAL(("config " + f + ": key \"baud\" appears twice in the top level").c_str(), FileErrorOf(f).c_str());
}

// Found by fuzz/ (fuzz_config): a number beyond double range made nlohmann::json throw
// out_of_range (not parse_error), which escaped the parser instead of a UsageError.
TEST(CommandLine, NumberBeyondDoubleRangeInConfigIsAUsageError) {
  const auto file = dir.Write("huge.json", R"({"days": 1.5e3527})");
  const std::string e = ErrorOf({"--config", file.string()});
  CHECK_TEXT(e.find("config " + file.string() + ": invalid JSON") == 0, e.c_str());
}

TEST(CommandLine, PositionalArgumentAndOtherConfigKeys) {
  OptionTable table{{Option::Text("json", "OUT.json", "output")}, "BUNDLE", "bundle", true};
  const auto file = dir.Write("c.json", R"({"bundle": "from-file", "json": "o.json", "scan_day": 40})");
  ParsedOptions o = ParseOptions(table, {"--config", file.string()});
  STRCMP_EQUAL("from-file", o.positional().c_str());
  CHECK(o.other_config() == nlohmann::json({{"scan_day", 40}}));
  o = ParseOptions(table, {"b1", "--config", file.string()});
  STRCMP_EQUAL("b1", o.positional().c_str());  // the command line wins
  STRCMP_EQUAL("unexpected argument 'b2' (one BUNDLE only)", ErrorOf(table, {"b1", "b2"}).c_str());
  table.other_config_keys = false;
  CHECK(ErrorOf(table, {"--config", file.string()}).find("unknown key 'scan_day'") != std::string::npos);
}

TEST(CommandLine, HelpAndSynopsisComeFromTheTable) {
  const std::string help = Table().Help(24);
  CHECK(help.find("  --serial PATH         coordinator serial port\n") != std::string::npos);
  CHECK(help.find("  --loss P              probability that a packet is lost\n"
                  "                        (default 0)\n") != std::string::npos);
  CHECK(help.find("  --republish-after S   seconds\n") != std::string::npos);
  CHECK(Table().Help(12).find("  --serial PATH\n            coordinator serial port\n") !=
        std::string::npos);  // too long: own line
  CHECK(help.find("  --quiet               no progress lines\n") != std::string::npos);
  CHECK(help.find("  --config FILE") != std::string::npos && help.find("  --help") != std::string::npos);
  STRCMP_EQUAL(
      "--serial PATH [--baud N] [--loss P]\n    [--republish-after S] [--seed N] [--effect NAME]\n"
      "    [--quiet] [--config FILE]",
      Table().Synopsis(4, 60).c_str());
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
  STRCMP_EQUAL("--api-mode 0 is out of range (allowed: [1, 2])",
               RangeErrorOf([] { ParseWholeNumber("api-mode", "0", 1, 2); }).c_str());
  STRCMP_EQUAL("--n 99999999999999999999 is out of range (allowed: [0, 10])",
               RangeErrorOf([] { ParseWholeNumber("n", "99999999999999999999", 0, 10); }).c_str());
  for (const char* bad : {"", "1.5", "1e3", "12abc", " 3", "3 ", "0x10", "-", "+", "+-1"}) {
    const std::string e = RangeErrorOf([bad] { ParseWholeNumber("n", bad, 0, 10); });
    CHECK_TEXT(e == std::string("--n '") + bad + "' is not a whole number (allowed: [0, 10])", e.c_str());
  }
  // The typed accessor: a whole range of the type by default, nothing wraps.
  LONGS_EQUAL(65535, ParseInteger<uint16_t>("port", "65535"));
  STRCMP_EQUAL("--port 65536 is out of range (allowed: [0, 65535])",
               RangeErrorOf([] { ParseInteger<uint16_t>("port", "65536"); }).c_str());
  STRCMP_EQUAL("--seed -1 is out of range (allowed: [0, 18446744073709551615])",
               RangeErrorOf([] { ParseInteger<uint64_t>("seed", "-1"); }).c_str());
  CHECK(ParseInteger<uint64_t>("seed", "18446744073709551615") == UINT64_MAX);
  CHECK(ParseInteger<uint64_t>("seed", "9007199254740993") == 9007199254740993ull);  // beyond a double's 53 bits
  STRCMP_EQUAL("--seed 18446744073709551616 is out of range (allowed: [0, 18446744073709551615])",
               RangeErrorOf([] { ParseInteger<uint64_t>("seed", "18446744073709551616"); }).c_str());
  STRCMP_EQUAL("--ms 2147483648 is out of range (allowed: [-2147483648, 2147483647])",
               RangeErrorOf([] { ParseInteger<int>("ms", "2147483648"); }).c_str());
}
