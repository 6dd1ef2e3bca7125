// The linerwatch-gateway program's command-line contract (docs/gateway.md): --help, a non-zero exit
// with one line naming what was wrong, and no spool file left behind on bad input.
#include <algorithm>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>

#include <cstdio>
#include <fstream>
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
  std::vector<std::string> argv{LW_GATEWAY_BIN};
  argv.reserve(args.size() + 1);
  for (const std::string& a : args) argv.push_back(a);
  const std::string log = dir.File("out.log");
  std::remove(log.c_str());
  const int rc = lw::test::RunCommand(argv, log);
  return {rc, lw::test::FileTail(log, 100000)};
}

size_t Lines(const std::string& s) {
  size_t n = 0;
  for (char c : s) n += c == '\n';
  return n;
}

}  // namespace

TEST_GROUP(GatewayCommandLine) {
  lw::test::TempDirectory dir{"lw-gateway-cli"};
  std::vector<std::string> Valid() {
    return {"--serial", "/dev/null", "--broker", "tcp://127.0.0.1:1", "--site",
            "s",        "--crusher", "c",        "--spool",           dir.File("spool.db")};
  }
};

TEST(GatewayCommandLine, HelpExitsZeroAndListsTheContractFlags) {
  const Result r = Run(dir, {"--help"});
  LONGS_EQUAL(0, r.exit_code);
  for (const char* flag : {"--serial", "--baud", "--api-mode", "--broker", "--site", "--crusher", "--spool", "--username",
                           "--password", "--config", "--tls-ca", "--gateway-id"}) {
    CHECK_TEXT(r.output.find(flag) != std::string::npos, flag);
  }
}

TEST(GatewayCommandLine, BadInputExitsNonZeroWithOneLineAndNoSpool) {
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--serial", "/dev/null"}, "--broker is required"},
      {{"--api-mode", "3"}, "--api-mode"},
      {{"--baud", "1000"}, "--baud"},
      {{"--broker", "127.0.0.1:1883"}, "--broker"},
      {{"--serial", dir.File("no-such-tty")}, "does not exist"},
      {{"--config", dir.File("missing.json")}, "cannot be read"},
      {{"--frobnicate", "1"}, "unknown option --frobnicate"},
      {{"--window", "2", "--window", "3"}, "--window is given twice ('2' and '3')"},
  };
  for (const auto& [change, expected] : cases) {
    std::vector<std::string> args = Valid();
    if (change.size() == 2 && change[0] == "--serial" && change[1] == "/dev/null") {
      args = {"--serial", "/dev/null", "--site", "s", "--crusher", "c", "--spool", dir.File("spool.db")};
    } else {
      // The changed flag replaces its valid value (a flag given twice is refused on its own).
      const auto it = std::find(args.begin(), args.end(), change[0]);
      if (change.size() == 2 && it != args.end())
        *(it + 1) = change[1];
      else
        args.insert(args.end(), change.begin(), change.end());
    }
    const Result r = Run(dir, args);
    CHECK_TEXT(r.exit_code != 0, expected.c_str());
    CHECK_TEXT(r.output.find(expected) != std::string::npos, (expected + " not in: " + r.output).c_str());
    LONGS_EQUAL_TEXT(1, Lines(r.output), r.output.c_str());
    CHECK_TEXT(access(dir.File("spool.db").c_str(), F_OK) != 0, "spool file created on bad input");
  }
}

TEST(GatewayCommandLine, JsonConfigErrorsNameFileAndKey) {
  const std::string file = dir.File("gw.json");
  std::ofstream(file) << R"({"serial": "/dev/null", "broker": "tcp://127.0.0.1:1", "site": "s", "crusher": "c",
                            "spool": ")"
                      << dir.File("spool.db") << R"(", "baud": "fast"})";
  const Result r = Run(dir, {"--config", file});
  CHECK(r.exit_code == 2);
  CHECK_TEXT(r.output.find(file) != std::string::npos && r.output.find("'baud'") != std::string::npos, r.output.c_str());
}

TEST(GatewayCommandLine, SecondGatewayOnTheSameSpoolIsRefused) {
  lw::test::ChildProcess first;
  std::vector<std::string> argv{LW_GATEWAY_BIN};
  for (const std::string& a : Valid()) argv.push_back(a);
  first.Start(argv, dir.File("first.log"));
  // Wait until the first one has its spool (it logs the spool depth once the spool is open): up to
  // 60 s, since a start on a loaded machine can take seconds and a second gateway started before
  // the first holds the spool would take it itself.
  const auto has_spool = [&] { return lw::test::FileTail(dir.File("first.log")).find("records waiting") != std::string::npos; };
  for (int i = 0; i < 6000 && !has_spool() && first.Running(); ++i) usleep(10'000);
  CHECK_TEXT(has_spool(), ("the first gateway did not open its spool: " + lw::test::FileTail(dir.File("first.log"))).c_str());
  CHECK_TRUE(first.Running());
  const Result second = Run(dir, Valid());
  LONGS_EQUAL(1, second.exit_code);
  CHECK_TEXT(second.output.find("in use") != std::string::npos, second.output.c_str());
  CHECK_TRUE(first.Running());
  first.Stop(SIGTERM);
  CHECK(WIFEXITED(first.status()) && WEXITSTATUS(first.status()) == 0);
}
