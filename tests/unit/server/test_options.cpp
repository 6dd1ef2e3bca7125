// linerwatch-server's command line (server/src/options.cpp): every integer option is range-checked
// and the error names the option, its value and the allowed range.
#include <string>
#include <vector>

#include "core/cmdline.hpp"
#include "server/server.hpp"

// CppUTest last: its new/delete macros break standard headers included after it.
#include <CppUTest/TestHarness.h>

namespace {
std::vector<std::string> Base() {
  return {"--broker", "tcp://127.0.0.1:1883", "--db", "/tmp/x.db", "--crusher-dir", "/tmp/crushers"};
}
std::string ErrorOf(std::vector<std::string> extra) {
  auto args = Base();
  args.insert(args.end(), extra.begin(), extra.end());
  try {
    lw::server::ParseServerOptions(args);
  } catch (const lw::core::UsageError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST_GROUP(ServerOptions){};

TEST(ServerOptions, IntegerOptionsAreRangeChecked) {
  // Before: any int64 was taken; 9223372036854775807 ms overflowed `last + interval` (undefined
  // behaviour) and an unbounded --batch-max was taken as given.
  STRCMP_EQUAL("--wear-interval-ms 9223372036854775807 is out of range (allowed: [0, 86400000])",
               ErrorOf({"--wear-interval-ms", "9223372036854775807"}).c_str());
  STRCMP_EQUAL("--batch-max 9223372036854775807 is out of range (allowed: [1, 1000000])",
               ErrorOf({"--batch-max", "9223372036854775807"}).c_str());
  STRCMP_EQUAL("--batch-max 0 is out of range (allowed: [1, 1000000])", ErrorOf({"--batch-max", "0"}).c_str());
  STRCMP_EQUAL("--commit-delay-ms 4294967297 is out of range (allowed: [0, 1000])",
               ErrorOf({"--commit-delay-ms", "4294967297"}).c_str());
  STRCMP_EQUAL("--http 65536 is out of range (allowed: [0, 65535])", ErrorOf({"--http", "127.0.0.1:65536"}).c_str());
  STRCMP_EQUAL("--batch-max '10k' is not a whole number (allowed: [1, 1000000])", ErrorOf({"--batch-max", "10k"}).c_str());
  const auto o = lw::server::ParseServerOptions({"--broker", "tcp://h:1883", "--db", "d", "--crusher-dir", "c",
                                                 "--wear-interval-ms", "86400000", "--batch-max", "1000000", "--commit-delay-ms",
                                                 "1000", "--http", "127.0.0.1:65535"});
  CHECK(o.wear_interval_ms == 86400000 && o.batch_max == 1000000 && o.commit_delay_ms == 1000);
}
