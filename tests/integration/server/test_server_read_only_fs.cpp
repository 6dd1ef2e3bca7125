// The real linerwatch-server on a --db whose file system is mounted read-only (a bind mount in a
// mount namespace of the server's own, support/read_only_mount.hpp): it serves what is stored, as on
// a full disk, says why in its log and /healthz naming the file, takes no reading and writes nothing.
// Skips (exit 77) where this machine refuses mount namespaces.
#include <sys/stat.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include "support/mosquitto_fixture.hpp"
#include "support/read_only_mount.hpp"
#include "unit/server/server_fixture.hpp"

#include <httplib.h>  // after Eigen (<resolv.h> defines _res)

#include <CppUTest/TestHarness.h>  // last

namespace {

int64_t NowMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

/// The folder `data` of `folder`, read-only for the children started with it; skips the test
/// program when this machine cannot do that.
lw::test::ReadOnlyMount MountOrSkip(lw::test::CrusherFolder& folder, const std::string& data) {
  ::mkdir(data.c_str(), 0700);
  lw::test::ReadOnlyMount ro(data, folder.dir.File("probe.log"));
  if (!ro.Unavailable().empty()) {
    std::printf("skipped: %s\n", ro.Unavailable().c_str());
    std::exit(lw::test::ReadOnlyMount::kSkip);
  }
  return ro;
}

/// Starts the server on `db` with its folder read-only; returns once /healthz answers.
void StartServer(lw::test::ChildProcess& server, const lw::test::ReadOnlyMount& ro, lw::test::CrusherFolder& folder,
                 const std::string& db, int http_port) {
  const std::string broker = "tcp://127.0.0.1:" + std::to_string(lw::test::FreeLoopbackPort());  // nothing listens
  const std::string log = folder.dir.File("server.log");
  server.Start(ro.Command({LW_SERVER_BIN, "--broker", broker, "--db", db, "--http", "127.0.0.1:" + std::to_string(http_port),
                           "--crusher-dir", folder.crushers, "--web-dir", ""}),
               log);
  httplib::Client http("127.0.0.1", http_port);
  for (const int64_t end = NowMs() + 90'000; NowMs() < end && server.Running();) {
    if (const auto r = http.Get("/healthz"); r) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  FAIL_TEST(("the server did not answer /healthz: " + lw::test::FileTail(log)).c_str());
}

std::string ReadAll(const std::string& path) {
  std::string s;
  if (FILE* f = std::fopen(path.c_str(), "rb")) {
    char buf[65536];
    for (size_t n; (n = std::fread(buf, 1, sizeof buf, f)) > 0;) s.append(buf, n);
    std::fclose(f);
  }
  return s;
}

}  // namespace

TEST_GROUP(ServerReadOnlyFileSystem){};

// Finding (issue 45): a read-only file system gave "unable to open database file" and the server
// exited. Now it serves the stored readings read-only (as on a full disk), names the file and the
// reason in its log and /healthz, refuses REST writes with 503 and changes nothing in the file.
TEST(ServerReadOnlyFileSystem, AStoredDatabaseIsServedReadOnlyWithTheReason) {
  lw::test::CrusherFolder folder{5, 3};
  const std::string data = folder.dir.File("data");
  lw::test::ReadOnlyMount ro = MountOrSkip(folder, data);
  const std::string db = data + "/server.sqlite";
  int64_t stored = 0;
  {
    lw::test::ServerParts parts(folder.crushers, false, "", db);
    stored = static_cast<int64_t>(parts.ingestor->Ingest(lw::test::Messages(folder.bundle)).stored);
    // A measured setting an hour after installation (before any opening): listed and counted read-only too.
    const int64_t installed_s =
        std::chrono::duration_cast<std::chrono::seconds>(folder.bundle.crusher.installed_at.time_since_epoch()).count();
    lw::server::Store s(db);
    CHECK(s.AddSettingCheck({folder.id(), installed_s + 3600, 133.0, 0.0, true, "ops", "gauge", installed_s + 7200}));
  }
  CHECK(stored > 0);
  const std::string before = ReadAll(db);

  lw::test::ChildProcess server;
  const int port = lw::test::FreeLoopbackPort();
  StartServer(server, ro, folder, db, port);
  httplib::Client http("127.0.0.1", port);
  const auto health = http.Get("/healthz");
  CHECK(health);
  LONGS_EQUAL(503, health->status);
  const nlohmann::json h = nlohmann::json::parse(health->body);
  STRCMP_EQUAL("degraded", h.value("status", "").c_str());
  const std::string reason = h.value("reason", "");
  CHECK_TEXT(reason.find("read-only file system") != std::string::npos && reason.find(db) != std::string::npos, reason.c_str());

  const auto crusher = http.Get("/api/v1/crushers/" + folder.id());
  CHECK(crusher);
  LONGS_EQUAL_TEXT(200, crusher->status, crusher->body.c_str());
  LONGS_EQUAL(stored, nlohmann::json::parse(crusher->body)["counters"]["readings_stored"].get<int64_t>());
  const auto checks = http.Get("/api/v1/crushers/" + folder.id() + "/setting/checks");
  CHECK(checks);
  LONGS_EQUAL_TEXT(200, checks->status, checks->body.c_str());
  const nlohmann::json listed = nlohmann::json::parse(checks->body)["checks"];
  LONGS_EQUAL(1, listed.size());
  DOUBLES_EQUAL(133.0, listed[0]["css_mm"].get<double>(), 0);
  const auto wear = http.Get("/api/v1/crushers/" + folder.id() + "/wear?faces=false");
  CHECK(wear);
  LONGS_EQUAL_TEXT(200, wear->status, wear->body.c_str());
  const nlohmann::json checked = nlohmann::json::parse(wear->body)["setting"]["checked"];
  CHECK_TEXT(checked.is_object(), wear->body.substr(0, 2000).c_str());
  DOUBLES_EQUAL(133.0, checked["css_mm"].get<double>(), 0);
  nlohmann::json one = nlohmann::json::parse(lw::test::Messages(folder.bundle).front().payload);
  one["seq"] = 1'000'000;  // a reading not stored yet: it would need a write
  const auto post = http.Post("/api/v1/crushers/" + folder.id() + "/readings",
                              nlohmann::json{{"readings", nlohmann::json::array({one})}}.dump(), "application/json");
  CHECK(post);
  LONGS_EQUAL_TEXT(503, post->status, post->body.c_str());

  LONGS_EQUAL(0, server.Stop(SIGTERM));
  const std::string log = lw::test::FileTail(folder.dir.File("server.log"), 20000);
  CHECK_TEXT(log.find("read-only file system: " + db) != std::string::npos, log.c_str());
  CHECK_TEXT(log.find("serving stored data read-only") != std::string::npos, log.c_str());
  // Nothing written: the same bytes, no -wal or -shm beside it; every reading still there.
  CHECK(before == ReadAll(db));
  struct stat st {};
  CHECK(::stat((db + "-wal").c_str(), &st) != 0 && ::stat((db + "-shm").c_str(), &st) != 0);
  lw::server::Store again(db);
  LONGS_EQUAL(stored, again.CountReadings(folder.id()));
}

// A --db that does not exist yet on a read-only mount: the server says so (file and reason) and
// answers degraded, with nothing stored to serve, instead of exiting on "unable to open".
TEST(ServerReadOnlyFileSystem, ANewDatabaseOnAReadOnlyMountIsNamedWithTheReason) {
  lw::test::CrusherFolder folder{5, 3};
  const std::string data = folder.dir.File("data");
  lw::test::ReadOnlyMount ro = MountOrSkip(folder, data);
  const std::string db = data + "/new.sqlite";
  lw::test::ChildProcess server;
  const int port = lw::test::FreeLoopbackPort();
  StartServer(server, ro, folder, db, port);
  httplib::Client http("127.0.0.1", port);
  const auto health = http.Get("/healthz");
  CHECK(health);
  LONGS_EQUAL(503, health->status);
  const std::string reason = nlohmann::json::parse(health->body).value("reason", "");
  CHECK_TEXT(reason.find("read-only file system: " + db) != std::string::npos, reason.c_str());
  LONGS_EQUAL(0, server.Stop(SIGTERM));
  const std::string log = lw::test::FileTail(folder.dir.File("server.log"), 20000);
  CHECK_TEXT(log.find("read-only file system: " + db) != std::string::npos, log.c_str());
  CHECK_TEXT(log.find("serving no stored data") != std::string::npos, log.c_str());
  struct stat st {};
  CHECK(::stat(db.c_str(), &st) != 0);
}
