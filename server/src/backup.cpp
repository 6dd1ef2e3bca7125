#include "server/backup.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <regex>

#include "core/atomic_file.hpp"
#include "core/sqlite.hpp"

namespace lw::server {
namespace fs = std::filesystem;
namespace {

using Db = core::sqlite::Database<BackupError>;
using Stmt = core::sqlite::Statement<BackupError>;
using core::Option;

constexpr int64_t kMaxKeep = 100'000;
// A backup step meets SQLITE_BUSY only while the server holds a lock the copy must wait for
// (WAL recovery, a checkpoint restarting the log): 100 ms apart, for up to a minute.
constexpr int kBusyRetries = 600;

const core::OptionTable& Table() {
  static const core::OptionTable table{{
      Option::Text("db", "FILE", "the server database to copy (opened read-only; the server may be running)").Required(),
      Option::Text("dir", "DIR", "folder the copies go to, server-YYYYMMDDTHHMMSSZ.sqlite (must exist)").Required(),
      Option::Whole("keep", "N", 1, kMaxKeep, "copies kept in DIR, the new one included; older ones are deleted (default 14)"),
  }};
  return table;
}

void CheckInputs(const BackupOptions& o) {
  if (o.keep < 1) throw BackupError("keep must be 1 or more, not " + std::to_string(o.keep));
  std::error_code ec;
  const fs::file_status db = fs::status(o.db, ec);
  if (!fs::exists(db)) throw BackupError("database '" + o.db + "' does not exist");
  if (!fs::is_regular_file(db)) throw BackupError("database '" + o.db + "' is not a file");
  const fs::file_status dir = fs::status(o.dir, ec);
  // Not made here: a backup disk that is not mounted must not fill the system disk instead.
  if (!fs::exists(dir)) throw BackupError("backup folder '" + o.dir + "' does not exist (make it, or mount the backup disk)");
  if (!fs::is_directory(dir)) throw BackupError("backup folder '" + o.dir + "' is not a folder");
}

/// Opens the live database read-only and checks that it is a server database: a wrong --db is
/// named here, not copied.
void CheckSource(const Db& src) {
  Stmt readings(src, "SELECT COUNT(*) FROM sqlite_master WHERE type='table' AND name='readings'");
  readings.Step();
  if (readings.Int(0) != 1)
    throw BackupError("database " + src.path() + ": not a linerwatch server database (no readings table)");
}

/// The whole database in one step: one read transaction, so the copy is one consistent snapshot
/// while the server goes on committing (WAL: the reader does not block the writer).
void CopyPages(const Db& src, const Db& dest) {
  sqlite3_backup* backup = sqlite3_backup_init(dest.get(), "main", src.get(), "main");
  if (!backup) dest.Fail("backup");
  int rc = SQLITE_OK;
  for (int tries = 0;; ++tries) {
    rc = sqlite3_backup_step(backup, -1);
    if ((rc == SQLITE_BUSY || rc == SQLITE_LOCKED) && tries < kBusyRetries) {
      sqlite3_sleep(100);
      continue;
    }
    break;
  }
  const int finished = sqlite3_backup_finish(backup);
  if (rc != SQLITE_DONE) throw BackupError("backup " + dest.path() + ": copy from " + src.path() + ": " + sqlite3_errstr(rc));
  if (finished != SQLITE_OK) dest.Fail("copy from " + src.path());
}

/// The copy's own check: SQLite reads every page, index and constraint back.
void CheckCopy(const Db& dest) {
  Stmt check(dest, "PRAGMA integrity_check");
  std::string first;
  int rows = 0;
  while (check.Step()) {
    if (rows++ == 0) first = check.Text(0);
  }
  if (rows != 1 || first != "ok") throw BackupError("backup " + dest.path() + ": integrity_check: " + first);
}

/// Writes the copy at `tmp` (created here, owner-only: it holds every reading).
void WriteCopy(const Db& src, const fs::path& tmp, const std::string& dir) {
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) throw BackupError("backup folder '" + dir + "': cannot create a file in it: " + std::strerror(errno));
  ::close(fd);
  Db dest(tmp.string(), "backup", SQLITE_OPEN_READWRITE);
  CopyPages(src, dest);
  // The copy is one self-contained file (a rollback journal, not WAL): nothing beside it to lose
  // when it is moved. The server switches a restored copy back to WAL when it opens it.
  dest.Exec("PRAGMA journal_mode=DELETE");
  CheckCopy(dest);
}

/// Deletes the oldest copies in `dir` so that `keep` remain, never `made` itself (a clock set back
/// makes the new copy sort first).
std::vector<fs::path> Prune(const fs::path& dir, const fs::path& made, int keep) {
  std::vector<fs::path> others = ListBackups(dir);
  others.erase(std::remove(others.begin(), others.end(), made), others.end());
  std::vector<fs::path> removed;
  const size_t keep_others = static_cast<size_t>(keep - 1);
  for (size_t i = 0; i + keep_others < others.size(); ++i) {
    std::error_code ec;
    fs::remove(others[i], ec);
    if (ec) {
      throw BackupError("backup " + made.string() + " is made, but the old copy " + others[i].string() +
                        " cannot be deleted: " + ec.message());
    }
    removed.push_back(others[i]);
  }
  return removed;
}

}  // namespace

std::string BackupHelp() {
  return "linerwatch-backup: an online, checked copy of the linerwatch-server database, the oldest copies beyond N deleted.\n\n"
         "Usage: linerwatch-backup " +
         Table().Synopsis(25, 100) + "\n\n" + Table().Help(24) +
         "\nExit status: 0 the copy is made and checked, 1 it could not be (the reason on stderr), 2 a bad command line.\n";
}

BackupOptions ParseBackupOptions(const std::vector<std::string>& args) {
  BackupOptions o;
  const core::ParsedOptions p = core::ParseOptions(Table(), args);
  if (p.help()) {
    o.help = true;
    return o;
  }
  o.db = p.Text("db");
  o.dir = p.Text("dir");
  o.keep = p.Integer<int>("keep", o.keep);
  if (o.db.empty()) throw core::UsageError("--db must not be empty");
  if (o.dir.empty()) throw core::UsageError("--dir must not be empty");
  return o;
}

std::string BackupFileName(core::TimePoint at) {
  std::string iso = core::FormatIsoTime(at);  // 2026-03-14T02:15:00Z
  iso.erase(std::remove_if(iso.begin(), iso.end(), [](char c) { return c == '-' || c == ':'; }), iso.end());
  return "server-" + iso + ".sqlite";
}

std::vector<fs::path> ListBackups(const fs::path& dir) {
  static const std::regex kName(R"(server-[0-9]{8}T[0-9]{6}Z\.sqlite)");
  std::vector<fs::path> out;
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(dir, ec)) {
    if (e.is_regular_file(ec) && std::regex_match(e.path().filename().string(), kName)) out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

BackupResult TakeBackup(const BackupOptions& options, core::TimePoint at) {
  CheckInputs(options);
  const Db src(options.db, "database", SQLITE_OPEN_READONLY);
  CheckSource(src);
  BackupResult result;
  result.file = fs::path(options.dir) / BackupFileName(at);
  if (fs::exists(result.file)) {
    throw BackupError("backup " + result.file.string() + " exists already (one backup a second at most)");
  }
  core::MakeFileAtomically(result.file, [&](const fs::path& tmp) { WriteCopy(src, tmp, options.dir); });
  std::error_code ec;
  result.bytes = static_cast<int64_t>(fs::file_size(result.file, ec));
  result.removed = Prune(options.dir, result.file, options.keep);
  return result;
}

}  // namespace lw::server
