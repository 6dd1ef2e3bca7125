#pragma once
/// linerwatch-backup: an online, consistent copy of the server database (docs/deploy.md, *Backup
/// and restore*). The copy is taken with SQLite's backup API over a read-only connection, so the
/// running server keeps committing and the live database is never written; the copy is checked
/// with `PRAGMA integrity_check`, made whole or not at all (core::MakeFileAtomically), named by
/// its UTC time, and the oldest copies beyond `keep` are deleted.
#include <chrono>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/cmdline.hpp"
#include "core/time.hpp"

namespace lw::server {

/// A backup that cannot be taken: what() is one line naming the file or folder and the reason.
class BackupError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct BackupOptions {
  bool help = false;
  std::string db;   ///< the live database (opened read-only)
  std::string dir;  ///< the folder the copies go to (must exist: a backup disk that is not mounted is an error)
  int keep = 14;    ///< copies kept, the new one included (>= 1)
};

/// --help text of linerwatch-backup.
std::string BackupHelp();
/// Parses linerwatch-backup's command line (and --config FILE). Throws core::UsageError.
BackupOptions ParseBackupOptions(const std::vector<std::string>& args);

/// "server-20260314T021500Z.sqlite": names sort in time order, so the oldest come first.
std::string BackupFileName(core::TimePoint at);
/// The copies in `dir` (names of BackupFileName's form, nothing else), oldest first.
std::vector<std::filesystem::path> ListBackups(const std::filesystem::path& dir);

struct BackupResult {
  std::filesystem::path file;                  ///< the new copy
  int64_t bytes = 0;                           ///< its size
  std::vector<std::filesystem::path> removed;  ///< older copies deleted (beyond keep)
};

/// Takes the backup at time `at` (its name). Throws BackupError (nothing is left behind: no new
/// file, no copy deleted).
BackupResult TakeBackup(const BackupOptions& options, core::TimePoint at);

}  // namespace lw::server
