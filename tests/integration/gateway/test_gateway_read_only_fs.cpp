// The real linerwatch-gateway with its --spool on a read-only mount (a bind mount in a mount
// namespace of the gateway's own, support/read_only_mount.hpp): it stops at once with a message
// naming the spool and the reason, and the records already spooled stay there, readable, for the
// gateway started once the file system is writable. Skips (exit 77) where namespaces are refused.
#include <sys/stat.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "gateway/spool.hpp"
#include "support/mosquitto_fixture.hpp"
#include "support/read_only_mount.hpp"

#include <CppUTest/TestHarness.h>  // last

namespace {

struct Outcome {
  int exit_code;
  std::string said;
};

/// Runs the gateway on `spool` with `data` read-only for it (skips the test program when this
/// machine cannot do that).
Outcome RunOnReadOnlySpool(lw::test::TempDirectory& dir, const std::string& data, const std::string& spool) {
  lw::test::ReadOnlyMount ro(data, dir.File("probe.log"));
  if (!ro.Unavailable().empty()) {
    std::printf("skipped: %s\n", ro.Unavailable().c_str());
    std::exit(lw::test::ReadOnlyMount::kSkip);
  }
  const std::string log = dir.File("gateway.log");
  std::remove(log.c_str());
  const int rc = lw::test::RunCommand(ro.Command({LW_GATEWAY_BIN, "--serial", "/dev/null", "--broker", "tcp://127.0.0.1:1",
                                                  "--site", "s", "--crusher", "c", "--spool", spool}),
                                      log);
  return {rc, lw::test::FileTail(log, 20000)};
}

}  // namespace

TEST_GROUP(GatewayReadOnlyFileSystem) {
  lw::test::TempDirectory dir{"lw-gateway-ro"};
  std::string data;
  void setup() override {
    data = dir.File("data");
    ::mkdir(data.c_str(), 0700);
  }
};

// Finding (issue 45): a read-only file system gave "unable to open database file" without the
// file's reason. The gateway stores every reading before it acks the sensor, so with no writable
// spool it must not run: it exits naming the spool and the reason, and acks nothing.
TEST(GatewayReadOnlyFileSystem, ASpoolOnAReadOnlyMountStopsTheGatewayAndKeepsItsRecords) {
  const std::string spool = data + "/spool.db";
  {
    lw::gateway::Spool s(spool, 1000);
    std::vector<lw::gateway::SpoolRecord> records;
    for (uint32_t seq = 1; seq <= 5; ++seq)
      records.push_back({"1001", seq, 1000 + seq, false, "{\"seq\":" + std::to_string(seq) + "}"});
    s.Insert(records);
    LONGS_EQUAL(5, s.depth());
  }
  const Outcome o = RunOnReadOnlySpool(dir, data, spool);
  CHECK_TEXT(o.exit_code != 0, o.said.c_str());
  CHECK_TEXT(o.said.find("spool " + spool) != std::string::npos, o.said.c_str());
  CHECK_TEXT(o.said.find("Read-only file system") != std::string::npos, o.said.c_str());
  // Every record is still there for the gateway started on a writable file system.
  lw::gateway::Spool again(spool, 1000);
  LONGS_EQUAL(5, again.depth());
  LONGS_EQUAL(5, again.Heads(10).size());
}

// A spool that does not exist yet on a read-only mount: the same, and no file is left behind.
TEST(GatewayReadOnlyFileSystem, ANewSpoolOnAReadOnlyMountIsNamedWithTheReason) {
  const std::string spool = data + "/new-spool.db";
  const Outcome o = RunOnReadOnlySpool(dir, data, spool);
  CHECK_TEXT(o.exit_code != 0, o.said.c_str());
  CHECK_TEXT(o.said.find("spool " + spool) != std::string::npos, o.said.c_str());
  CHECK_TEXT(o.said.find("Read-only file system") != std::string::npos, o.said.c_str());
  struct stat st {};
  CHECK(::stat(spool.c_str(), &st) != 0);
}
