// linerwatch-backup against a running linerwatch-server (docs/deploy.md, *Backup and restore*):
// the server stores readings posted over REST; a backup taken while more are being posted is a
// consistent, checked copy; a backup of the running server restored on a "new machine" (a new
// database path, a copy of the crusher folder, its own broker) serves the same REST answers. And
// the program's own contract: the oldest copies beyond --keep are deleted, bad input is an error
// naming it with a nonzero exit.
#include <atomic>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <map>
#include <thread>

#include <unistd.h>

#include "core/sqlite.hpp"
#include "server/backup.hpp"
#include "server/store.hpp"
#include "support/mosquitto_fixture.hpp"
#include "unit/server/server_fixture.hpp"

#include <httplib.h>  // after Eigen (<resolv.h> defines _res)

#include <CppUTest/TestHarness.h>  // last

using nlohmann::json;
namespace fs = std::filesystem;

namespace {

struct Server {
  lw::test::ChildProcess process;
  std::string log;
  int port = 0;
  void Start(const std::string& broker, const std::string& db, const std::string& crushers, const std::string& log_file) {
    port = lw::test::FreeLoopbackPort();
    log = log_file;
    process.Start({LW_SERVER_BIN, "--broker", broker, "--db", db, "--http", "127.0.0.1:" + std::to_string(port), "--crusher-dir",
                   crushers, "--web-dir", ""},
                  log);
    // Up to 60 s: the map model is built at start-up, slow on a loaded machine.
    for (int i = 0; i < 1200 && !lw::test::PortAccepts(port); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (!lw::test::PortAccepts(port)) FAIL(("server did not come up: " + lw::test::FileTail(log)).c_str());
  }
  /// GET `path`: {status, body}.
  std::pair<int, std::string> Get(const std::string& path) const {
    httplib::Client client("127.0.0.1", port);
    client.set_read_timeout(60, 0);
    const auto res = client.Get(path);
    return res ? std::make_pair(res->status, res->body) : std::make_pair(-1, std::string());
  }
  json GetJson(const std::string& path) const {
    const auto [status, body] = Get(path);
    if (status != 200) FAIL(("GET " + path + ": " + std::to_string(status) + " " + body).c_str());
    return json::parse(body);
  }
  /// POSTs messages [from, to) as one manual-entry request; every one must be stored.
  void Post(const std::string& crusher, const std::vector<lw::server::Incoming>& messages, size_t from, size_t to) const {
    json readings = json::array();
    for (size_t i = from; i < to; ++i) readings.push_back(json::parse(messages[i].payload));
    httplib::Client client("127.0.0.1", port);
    client.set_read_timeout(60, 0);
    const auto res =
        client.Post("/api/v1/crushers/" + crusher + "/readings", json{{"readings", readings}}.dump(), "application/json");
    if (!res || res->status != 200) throw std::runtime_error("POST readings: " + (res ? res->body : std::string("no answer")));
    const json answer = json::parse(res->body);
    if (!answer.contains("stored") || answer.at("stored").get<int64_t>() != static_cast<int64_t>(to - from))
      throw std::runtime_error("POST readings: not all stored: " + res->body);
  }
  /// The wear (404 until the server's first computation).
  json Wear(const std::string& crusher) const {
    const std::string path = "/api/v1/crushers/" + crusher + "/wear";
    for (int i = 0; i < 600; ++i) {
      const auto [status, body] = Get(path);
      if (status == 200) return json::parse(body);
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    FAIL(("no wear from " + path + ": " + lw::test::FileTail(log)).c_str());
    return {};
  }
};

/// Runs linerwatch-backup with `args`; its exit code, its output in `out`.
int Backup(const std::vector<std::string>& args, const std::string& log, std::string* out = nullptr) {
  std::error_code ec;
  fs::remove(log, ec);
  std::vector<std::string> argv{LW_BACKUP_BIN};
  argv.insert(argv.end(), args.begin(), args.end());
  const int rc = lw::test::RunCommand(argv, log);
  if (out) *out = lw::test::FileTail(log);
  return rc;
}

/// The one copy in `dir` (there must be exactly one).
fs::path OnlyBackup(const fs::path& dir) {
  const std::vector<fs::path> all = lw::server::ListBackups(dir);
  LONGS_EQUAL_TEXT(1, all.size(), ("copies in " + dir.string()).c_str());
  return all.front();
}

/// What both servers must answer alike: the crusher list, the sensors, every sensor's readings
/// page by page (the cursor followed to the end), the wear with its faces.
std::map<std::string, json> Answers(const Server& s, const std::string& crusher) {
  std::map<std::string, json> out;
  out["wear"] = s.Wear(crusher);
  out["crushers"] = s.GetJson("/api/v1/crushers");
  const json sensors = s.GetJson("/api/v1/crushers/" + crusher + "/sensors");
  out["sensors"] = sensors;
  for (const json& sensor : sensors["sensors"]) {
    const std::string base = "/api/v1/crushers/" + crusher + "/sensors/" + sensor["id"].get<std::string>() + "/readings?limit=50";
    std::string path = base;
    for (int page = 0; page < 1000; ++page) {
      const json j = s.GetJson(path);
      out[path] = j;
      if (j["next_cursor"].is_null()) break;
      path = base + "&cursor=" + j["next_cursor"].get<std::string>();
    }
  }
  return out;
}

}  // namespace

TEST_GROUP(ServerBackup) {
  lw::test::MosquittoFixture broker;
  lw::test::CrusherFolder folder{30, 5};
  std::vector<lw::server::Incoming> messages = lw::test::Messages(folder.bundle, "site1");
  Server server;
  void setup() override {
    broker.Start();
  }
};

TEST(ServerBackup, ACopyTakenWhileTheServerRunsRestoresToTheSameRestAnswers) {
  const std::string db = folder.dir.File("server.sqlite");
  server.Start(broker.uri(), db, folder.crushers, folder.dir.File("server.log"));
  const std::string crusher = folder.id();
  const size_t half = messages.size() / 2;
  CHECK_TRUE(half > 100);
  for (size_t i = 0; i < half; i += 100) server.Post(crusher, messages, i, std::min(i + 100, half));

  // A backup while the rest is being posted, 10 readings a request.
  const fs::path mid_dir = folder.dir.File("backups-mid");
  fs::create_directories(mid_dir);
  std::atomic<bool> posting_failed{false};
  std::thread poster([&] {
    try {
      for (size_t i = half; i < messages.size(); i += 10) server.Post(crusher, messages, i, std::min(i + 10, messages.size()));
    } catch (const std::exception&) {
      posting_failed = true;
    }
  });
  std::string out;
  const int mid_rc = Backup({"--db", db, "--dir", mid_dir.string(), "--keep", "3"}, folder.dir.File("backup-mid.log"), &out);
  poster.join();
  CHECK_FALSE_TEXT(posting_failed.load(), lw::test::FileTail(server.log).c_str());
  LONGS_EQUAL_TEXT(0, mid_rc, out.c_str());
  CHECK_TRUE_TEXT(out.find("integrity ok") != std::string::npos, out.c_str());
  {
    // One consistent snapshot: the readings stored before it, each exactly as posted.
    const auto copy = lw::server::Store::OpenReadOnly(OnlyBackup(mid_dir));
    const std::vector<lw::server::StoredReading> stored = copy->All(crusher);
    CHECK_TRUE(stored.size() >= half && stored.size() <= messages.size());
    std::map<std::pair<std::string, int64_t>, json> sent;
    for (const auto& m : messages) {
      const json j = json::parse(m.payload);
      sent[{m.sensor, j["seq"].get<int64_t>()}] = j;
    }
    for (const auto& r : stored) {
      const auto it = sent.find({r.sensor, r.seq});
      CHECK_TRUE_TEXT(it != sent.end(), (r.sensor + " seq " + std::to_string(r.seq)).c_str());
      DOUBLES_EQUAL(it->second["thickness_mm"].get<double>(), r.thickness_mm, 1e-9);
    }
  }

  // Everything stored; a backup of the running server, restored on a new machine.
  const fs::path final_dir = folder.dir.File("backups");
  fs::create_directories(final_dir);
  LONGS_EQUAL_TEXT(0, Backup({"--db", db, "--dir", final_dir.string()}, folder.dir.File("backup.log"), &out), out.c_str());
  const std::map<std::string, json> before = Answers(server, crusher);
  LONGS_EQUAL(messages.size(), [&] {
    size_t n = 0;
    for (const json& s : before.at("sensors")["sensors"]) n += s["reading_count"].get<size_t>();
    return n;
  }());

  lw::test::TempDirectory machine("lw-restored");
  const std::string crushers = machine.File("crushers");
  fs::copy(folder.crushers, crushers, fs::copy_options::recursive);
  const std::string restored = machine.File("var/server.sqlite");
  fs::create_directories(machine.File("var"));
  fs::copy_file(OnlyBackup(final_dir), restored);
  lw::test::MosquittoFixture broker2;
  broker2.Start();
  Server second;
  second.Start(broker2.uri(), restored, crushers, machine.File("server.log"));
  // The wear (and the crusher list's minimum) is computed after readings are committed, on each
  // server's own schedule: compared until both have caught up, up to 100 rounds; the last
  // difference is the failure.
  std::string difference;
  for (int round = 0; round < 100; ++round) {
    const std::map<std::string, json> now = Answers(server, crusher);
    const std::map<std::string, json> after = Answers(second, crusher);
    difference.clear();
    if (now.size() != after.size()) difference = "answers: " + std::to_string(now.size()) + " vs " + std::to_string(after.size());
    for (const auto& [what, answer] : now) {
      const auto it = after.find(what);
      if (difference.empty() && (it == after.end() || answer != it->second))
        difference =
            what + ": " + answer.dump().substr(0, 400) + " vs " + (it == after.end() ? "none" : it->second.dump().substr(0, 400));
    }
    if (difference.empty()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  CHECK_TRUE_TEXT(difference.empty(), difference.c_str());
  // And the first server's answers did not change from the backup on: nothing was posted since.
  CHECK_TRUE(before.at("sensors") == Answers(server, crusher).at("sensors"));
}

TEST(ServerBackup, TheOldestCopiesBeyondKeepAreDeletedAndNothingElse) {
  const std::string db = folder.dir.File("server.sqlite");
  { lw::server::Store store(db); }
  const fs::path dir = folder.dir.File("backups");
  fs::create_directories(dir);
  // Older copies (by their names), a stray file and a copy-like name that is not one.
  for (const char* name : {"server-20240101T000000Z.sqlite", "server-20240102T000000Z.sqlite", "server-20240103T000000Z.sqlite"})
    folder.dir.Write("backups/" + std::string(name), "old copy");
  folder.dir.Write("backups/notes.txt", "kept");
  folder.dir.Write("backups/server-2024.sqlite", "kept");
  auto bytes = [](const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
  };
  const std::string live = bytes(db);
  std::string out;
  LONGS_EQUAL_TEXT(0, Backup({"--db", db, "--dir", dir.string(), "--keep", "2"}, folder.dir.File("b.log"), &out), out.c_str());
  CHECK_TRUE_TEXT(bytes(db) == live, "the live database was written");
  const std::vector<fs::path> left = lw::server::ListBackups(dir);
  LONGS_EQUAL(2, left.size());
  STRCMP_EQUAL("server-20240103T000000Z.sqlite", left[0].filename().c_str());
  CHECK_TRUE(left[1].filename().string() > "server-2025");  // the new one, named by today's UTC time
  CHECK_TRUE(fs::exists(dir / "notes.txt"));
  CHECK_TRUE(fs::exists(dir / "server-2024.sqlite"));
  CHECK_TRUE_TEXT(out.find("deleted 2 older") != std::string::npos, out.c_str());
  // --keep 1: the new copy alone.
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));  // a new name: one copy a second at most
  LONGS_EQUAL_TEXT(0, Backup({"--db", db, "--dir", dir.string(), "--keep", "1"}, folder.dir.File("b.log"), &out), out.c_str());
  LONGS_EQUAL(1, lw::server::ListBackups(dir).size());
  CHECK_TRUE(lw::server::ListBackups(dir)[0] != left[1]);
}

TEST(ServerBackup, BadInputIsAnErrorNamingItAndLeavesNothing) {
  const std::string db = folder.dir.File("server.sqlite");
  { lw::server::Store store(db); }
  const fs::path dir = folder.dir.File("backups");
  fs::create_directories(dir);
  const std::string log = folder.dir.File("b.log");
  std::string out;
  auto fails = [&](int code, const std::vector<std::string>& args, const std::string& named) {
    const int rc = Backup(args, log, &out);
    LONGS_EQUAL_TEXT(code, rc, out.c_str());
    CHECK_TRUE_TEXT(out.find(named) != std::string::npos, out.c_str());
  };
  fails(2, {"--db", db, "--dir", dir.string(), "--keep", "0"}, "--keep");
  fails(2, {"--db", db, "--dir", dir.string(), "--keep", "-3"}, "--keep");
  fails(2, {"--db", db}, "--dir");
  fails(1, {"--db", folder.dir.File("missing.sqlite"), "--dir", dir.string()}, "missing.sqlite");
  fails(1, {"--db", db, "--dir", folder.dir.File("no-such-folder")}, "no-such-folder");
  const std::string not_a_db = folder.dir.Write("not-a-db.sqlite", "this is not SQLite\n").string();
  fails(1, {"--db", not_a_db, "--dir", dir.string()}, "not-a-db.sqlite");
  const std::string other = folder.dir.File("other.sqlite");
  {
    lw::core::sqlite::Database<std::runtime_error> o(other, "other");
    o.Exec("CREATE TABLE t(x)");
  }
  fails(1, {"--db", other, "--dir", dir.string()}, "not a linerwatch server database");
  // A folder this user cannot write in (root writes anywhere a mode allows: /proc refuses it).
  fs::path unwritable = folder.dir.File("read-only");
  fs::create_directories(unwritable);
  fs::permissions(unwritable, fs::perms::owner_read | fs::perms::owner_exec);
  if (::geteuid() == 0) unwritable = "/proc/self";
  fails(1, {"--db", db, "--dir", unwritable.string()}, unwritable.string());
  fs::permissions(folder.dir.File("read-only"), fs::perms::owner_all);
  // Nothing was made, and the folder is as it was.
  CHECK_TRUE(fs::is_empty(dir));
}
