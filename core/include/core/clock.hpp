#pragma once
/// Where the host programs get "now" from: the system (wall) clock, or the virtual clock a
/// simulator keeps in a file (`linerwatch-sim run --clock-out FILE`, given to linerwatch-gateway
/// and linerwatch-server as `--clock-file FILE`).
#include <atomic>
#include <cstdint>
#include <string>

namespace lw::core {

/// Unix time in milliseconds from the system clock.
int64_t WallClockMs();

/// "now" in Unix milliseconds: the wall clock, or a clock file.
///
/// A clock file holds the virtual time as Unix milliseconds in ASCII digits, optionally followed
/// by a newline, and is replaced atomically by its writer (rename), so a read sees the old or the
/// new value, never a torn one. It is read on every NowMs().
///
/// Fallback: when the file cannot be read or does not hold a whole number of milliseconds
/// (empty, a sign, letters, more than 18 digits), NowMs() returns the last good value read from
/// it, and the wall clock before the first good value; ok() turns false until a read is good
/// again. Time from a clock file therefore never jumps to the wall clock once the simulation has
/// started.
///
/// NowMs() and ok() may be called from any thread.
class Clock {
 public:
  /// The wall clock.
  Clock() = default;
  /// The clock file at `clock_file`; an empty path is the wall clock.
  explicit Clock(std::string clock_file) : path_(std::move(clock_file)) {}
  Clock(const Clock&) = delete;
  Clock& operator=(const Clock&) = delete;

  int64_t NowMs() const;
  /// Whether the latest read of the clock file was good (always true for the wall clock).
  bool ok() const { return ok_.load(); }
  /// True for a clock file.
  bool is_file() const { return !path_.empty(); }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  mutable std::atomic<int64_t> last_ms_{-1};
  mutable std::atomic<bool> ok_{true};
};

}  // namespace lw::core
