#pragma once
/// A virtual clock kept in a file by a simulator (`linerwatch-sim run --clock-out`): the file holds
/// the current virtual time as Unix milliseconds in ASCII and is replaced atomically (rename), so
/// a read sees either the old or the new value, never a torn one.
#include <cstdint>
#include <string>

namespace lw::gateway {

class ClockFile {
 public:
  explicit ClockFile(std::string path) : path_(std::move(path)) {}
  /// The time in the file. When it cannot be read or does not hold a whole number of ms, the last
  /// good value (or `fallback_ms` before the first) is returned and `ok()` turns false.
  int64_t Now(int64_t fallback_ms);
  bool ok() const { return ok_; }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  int64_t last_ms_ = -1;
  bool ok_ = true;
};

}  // namespace lw::gateway
