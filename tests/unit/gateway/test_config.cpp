// Command line and JSON configuration: required flags, validation messages, file + flag merge.
#include <fstream>

#include "gateway/config.hpp"
#include "unit/gateway/gateway_test_support.hpp"

// CppUTest last: its new/delete macros break standard headers included after it.
#include <CppUTest/TestHarness.h>

using lw::gateway::Config;
using lw::gateway::ConfigError;
using lw::gateway::ParseCommandLine;
using lw::gateway::ParseResult;

namespace {
std::vector<std::string> Base() {
  return {"linerwatch-gateway", "--serial", "/dev/ttyUSB0", "--broker", "tcp://127.0.0.1:1883", "--site", "s1",
          "--crusher",          "c1",       "--spool",      "/tmp/x.db"};
}
std::string ErrorOf(const std::vector<std::string>& args) {
  Config c;
  try {
    ParseCommandLine(args, &c);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}
bool Contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}
}  // namespace

TEST_GROUP(Config) {
  lw::test::TempDirectory dir;
};

TEST(Config, MinimalFlagsGiveDefaults) {
  Config c;
  CHECK(ParseCommandLine(Base(), &c) == ParseResult::kRun);
  STRCMP_EQUAL("/dev/ttyUSB0", c.serial.c_str());
  LONGS_EQUAL(9600, c.baud);
  LONGS_EQUAL(2, c.api_mode);
  LONGS_EQUAL(1, c.window);
  CHECK(c.gateway_id.rfind("gw-", 0) == 0);
}

TEST(Config, HelpWins) {
  Config c;
  CHECK(ParseCommandLine({"linerwatch-gateway", "--help"}, &c) == ParseResult::kHelp);
  CHECK(Contains(lw::gateway::UsageText(), "--api-mode"));
}

TEST(Config, EveryRequiredFlagIsNamedWhenMissing) {
  for (const char* flag : {"serial", "broker", "site", "crusher", "spool"}) {
    std::vector<std::string> args{"linerwatch-gateway"};
    const auto base = Base();
    for (size_t i = 1; i < base.size(); i += 2) {
      if (base[i] != std::string("--") + flag) {
        args.push_back(base[i]);
        args.push_back(base[i + 1]);
      }
    }
    STRCMP_EQUAL((std::string("--") + flag + " is required (see --help)").c_str(), ErrorOf(args).c_str());
  }
}

TEST(Config, BadValuesAreNamed) {
  auto a = Base();
  a.insert(a.end(), {"--baud", "12345"});
  CHECK(Contains(ErrorOf(a), "--baud: 12345"));
  a = Base();
  a.insert(a.end(), {"--api-mode", "3"});
  STRCMP_EQUAL("--api-mode 3 is out of range (allowed: [1, 2])", ErrorOf(a).c_str());
  a = Base();
  a.insert(a.end(), {"--baud", "fast"});
  STRCMP_EQUAL("--baud 'fast' is not a whole number (allowed: [1200, 921600])", ErrorOf(a).c_str());
  a = Base();
  a[4] = "localhost:1883";
  CHECK(Contains(ErrorOf(a), "--broker"));
  a = Base();
  a[6] = "a/b";
  CHECK(Contains(ErrorOf(a), "--site"));
  a = Base();
  a.insert(a.end(), {"--password", "p"});
  CHECK(Contains(ErrorOf(a), "--password given without --username"));
  a = Base();
  a.push_back("--bogus");
  a.push_back("1");
  CHECK(Contains(ErrorOf(a), "unknown option --bogus"));
  a = Base();
  a.push_back("--window");
  CHECK(Contains(ErrorOf(a), "--window needs a value"));
}

// The gateway's site and crusher become topic levels the server matches against crusher.json,
// which allows only crusher.json's identifiers: a name only the gateway accepted (a space, an
// escape, a non-ASCII letter, 65 characters) would have every reading quarantined at the server.
TEST(Config, SiteAndCrusherKeepCrusherJsonsIdentifierRule) {
  const char* refused[] = {"mine a", "cr\x1b[31m", "m\xc3\xa9", "a+b", "a#"};
  for (int field : {6, 8}) {
    for (const char* name : refused) {
      auto a = Base();
      a[field] = name;
      const std::string error = ErrorOf(a);
      CHECK_TEXT(Contains(error, field == 6 ? "--site: '" : "--crusher: '"), (std::string(name) + ": " + error).c_str());
      CHECK_TEXT(Contains(error, "1-64 letters, digits, '.', '_' or '-'"), error.c_str());
    }
    auto a = Base();
    a[field] = std::string(65, 'x');
    CHECK(Contains(ErrorOf(a), "must be 1-64"));
    a[field] = std::string(64, 'x');
    STRCMP_EQUAL("", ErrorOf(a).c_str());
    a[field] = "Mine-A.2_b";
    STRCMP_EQUAL("", ErrorOf(a).c_str());
  }
}

// Integer options were parsed as long long and then static_cast: `--api-mode 4294967297` ran in API
// mode 1 and `--baud 4294976896` (9600 + 2^32) at 9600 baud. Each is now refused, naming the option,
// its value and the allowed range, on the command line and in a --config file.
TEST(Config, IntegerOptionsAreRangeCheckedNotTruncated) {
  const std::pair<const char*, const char*> cases[] = {
      {"--api-mode=4294967297", "--api-mode 4294967297 is out of range (allowed: [1, 2])"},
      {"--baud=4294976896", "--baud 4294976896 is out of range (allowed: [1200, 921600])"},
      {"--window=4294967297", "--window 4294967297 is out of range (allowed: [1, 10000])"},
      {"--max-devices=18446744073709551617", "--max-devices 18446744073709551617 is out of range (allowed: [1, 1000000])"},
      {"--spool-max-records=0", "--spool-max-records 0 is out of range (allowed: [1, 1000000000])"},
      {"--spool-max-records=-1", "--spool-max-records -1 is out of range (allowed: [1, 1000000000])"},
  };
  for (const auto& [flag, expected] : cases) {
    auto a = Base();
    a.push_back(flag);
    STRCMP_EQUAL(expected, ErrorOf(a).c_str());
  }
  const std::string file = dir.File("wide.json");
  std::ofstream(file) << R"({"api_mode": 4294967297})";
  auto a = Base();
  a.insert(a.end(), {"--config", file});
  STRCMP_EQUAL(("config " + file + ", key 'api-mode': --api-mode 4294967297 is out of range (allowed: [1, 2])").c_str(),
               ErrorOf(a).c_str());
  // The limits themselves are accepted.
  a = Base();
  a.insert(a.end(), {"--api-mode", "1", "--baud", "921600", "--window", "10000"});
  Config c;
  CHECK(ParseCommandLine(a, &c) == ParseResult::kRun);
  LONGS_EQUAL(1, c.api_mode);
  LONGS_EQUAL(921600, c.baud);
  LONGS_EQUAL(10000, c.window);
}

TEST(Config, JsonFileWithFlagOverride) {
  const std::string file = dir.File("gw.json");
  std::ofstream(file) << R"({"serial": "/dev/ttyS1", "baud": 115200, "api_mode": 1, "broker": "tcp://b:1883",
                            "site": "mine", "crusher": "cr2", "spool": "/var/lib/x.db", "gateway-id": "gw-9",
                            "republish-after": 2.5})";
  Config c;
  ParseCommandLine({"linerwatch-gateway", "--config", file, "--baud", "57600"}, &c);
  STRCMP_EQUAL("/dev/ttyS1", c.serial.c_str());
  LONGS_EQUAL(57600, c.baud);
  LONGS_EQUAL(1, c.api_mode);
  STRCMP_EQUAL("gw-9", c.gateway_id.c_str());
  DOUBLES_EQUAL(2.5, c.republish_after_s, 1e-12);
}

TEST(Config, BadJsonFilesAreNamed) {
  const std::string file = dir.File("bad.json");
  std::ofstream(file) << R"({"serial": "/dev/ttyS1", "colour": "red"})";
  const std::string e1 = ErrorOf({"linerwatch-gateway", "--config", file});
  CHECK(Contains(e1, file) && Contains(e1, "unknown key 'colour'"));
  std::ofstream(file) << R"({"baud": "fast"})";
  CHECK(Contains(ErrorOf({"linerwatch-gateway", "--config", file}), "key 'baud': --baud 'fast' is not a whole number"));
  std::ofstream(file) << R"({"baud": )";
  CHECK(Contains(ErrorOf({"linerwatch-gateway", "--config", file}), "invalid JSON"));
  CHECK(Contains(ErrorOf({"linerwatch-gateway", "--config", dir.File("none.json")}), "cannot be read"));
}

// Found by fuzz/ (fuzz_config): a number beyond double range made nlohmann::json throw
// out_of_range (not parse_error), which escaped as an unnamed exception instead of a ConfigError.
TEST(Config, NumberBeyondDoubleRangeInJsonFileIsNamed) {
  const std::string file = dir.File("huge.json");
  std::ofstream(file) << R"({"serial": "/dev/ttyS1", "republish-after": 1e999})";
  const std::string e = ErrorOf({"linerwatch-gateway", "--config", file});
  CHECK_TEXT(Contains(e, file) && Contains(e, "invalid JSON"), e.c_str());
}
