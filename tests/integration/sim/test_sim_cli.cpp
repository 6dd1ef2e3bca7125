// linerwatch-sim's command line: integer options are range-checked, never wrapped or rounded; the
// error names the option, its value and the allowed range (exit status 2, nothing written).
#include <unistd.h>

#include <string>
#include <vector>

#include "support/mosquitto_fixture.hpp"

// CppUTest last: its new/delete macros break standard headers included after it.
#include <CppUTest/TestHarness.h>

namespace {
struct Result {
  int exit_code;
  std::string output;
};
Result Run(lw::test::TempDirectory& dir, const std::vector<std::string>& args) {
  std::vector<std::string> argv{LW_SIM_BIN};
  argv.reserve(args.size() + 1);
  for (const std::string& a : args) argv.push_back(a);
  const std::string log = dir.File("out.log");
  ::unlink(log.c_str());
  const int rc = lw::test::RunCommand(argv, log);
  return {rc, lw::test::FileTail(log, 100000)};
}
bool Contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}
}  // namespace

TEST_GROUP(SimCommandLine) {
  lw::test::TempDirectory dir{"lw-sim-cli"};
};

// Before: `campaign --seed -1` went through std::stoull and ran with seed 18446744073709551615;
// `campaign --seed 12abc` ran with seed 12.
TEST(SimCommandLine, CampaignSeedIsAnUnsigned64BitNumber) {
  Result r = Run(dir, {"campaign", "--out", dir.File("b1"), "--seed", "-1"});
  LONGS_EQUAL(2, r.exit_code);
  CHECK_TEXT(Contains(r.output, "--seed -1 is out of range (allowed: [0, 18446744073709551615])"), r.output.c_str());
  r = Run(dir, {"campaign", "--out", dir.File("b2"), "--seed", "12abc"});
  LONGS_EQUAL(2, r.exit_code);
  CHECK_TEXT(Contains(r.output, "--seed '12abc' is not a whole number"), r.output.c_str());
  CHECK(::access(dir.File("b1").c_str(), F_OK) != 0 && ::access(dir.File("b2").c_str(), F_OK) != 0);
}

// Before: `run --seed` went through a double: 2^64 was cast to uint64_t (undefined behaviour) and
// accepted, and seeds beyond 2^53 were silently rounded to another seed.
TEST(SimCommandLine, RunSeedBeyond64BitsIsRefusedByName) {
  const Result r =
      Run(dir, {"run", "--crusher-dir", dir.File("c"), "--serial-out", dir.File("tty"), "--seed", "18446744073709551616"});
  LONGS_EQUAL(2, r.exit_code);
  CHECK_TEXT(Contains(r.output, "--seed 18446744073709551616 is out of range (allowed: [0, 18446744073709551615])"),
             r.output.c_str());
}
