#pragma once
/// One running instance per file: an exclusive advisory lock (flock) held for an object's
/// lifetime. flock does not interfere with SQLite's POSIX locks. The descriptor stays open until
/// the lock is destroyed: destroy it after the file's SQLite connections (closing any other
/// descriptor of a SQLite file would drop SQLite's own locks).
#include <string>

namespace lw::core {

class ExclusiveFileLock {
 public:
  /// Opens `path` (`create`: creating it with mode 0600 when missing; otherwise it must exist)
  /// and takes the lock without waiting. Throws std::runtime_error naming the path when it cannot
  /// be opened, or, naming `holder`, when another process holds the lock.
  ExclusiveFileLock(const std::string& path, bool create, const std::string& holder);
  ~ExclusiveFileLock();
  ExclusiveFileLock(const ExclusiveFileLock&) = delete;
  ExclusiveFileLock& operator=(const ExclusiveFileLock&) = delete;

 private:
  int fd_ = -1;
};

}  // namespace lw::core
