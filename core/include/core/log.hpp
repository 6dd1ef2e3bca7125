#pragma once
/// One log line mechanism for the host programs (gateway and server): every line is made safe for
/// a one-line log (fields from the radio, the broker or a REST body cannot forge or garble a
/// line), and a kind of message an outsider can repeat at will is rate-limited, so that a flood
/// of bad input cannot grow the log without bound.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <ostream>
#include <string>
#include <string_view>

namespace lw::core {

/// `text` made safe for a one-line log: control characters (newline, ESC, ...), DEL, bytes above
/// 0x7E and backslash as `\xNN` / `\\`; longer than `max_bytes`: cut, with the length noted.
std::string SanitizeForLog(std::string_view text, size_t max_bytes = 2048);

/// Counts messages per kind: the first kFirst of a kind are written, then every kEvery-th with
/// the count so far ("(12000 so far)"). Safe to share between threads.
class LogLimiter {
 public:
  static constexpr uint64_t kFirst = 10;
  static constexpr uint64_t kEvery = 1000;
  /// The line to write for this occurrence of `kind` (with the count once past kFirst), or
  /// nullopt when this one is not written.
  std::optional<std::string> Admit(const std::string& kind, const std::string& line);

 private:
  std::mutex mutex_;
  std::map<std::string, uint64_t> counts_;
};

/// A program's log: each line sanitised, prefixed and written whole to `out` (one line at a time
/// between threads). `stamp`, when set, gives a time prefix for each line.
class Logger {
 public:
  Logger(std::ostream& out, std::string program, std::function<std::string()> stamp = {})
      : out_(out), program_(std::move(program)), stamp_(std::move(stamp)) {}
  /// Writes `line`.
  void operator()(const std::string& line);
  /// Writes `line` as a message of `kind` (LogLimiter's rule): for what outsiders can repeat.
  void Limited(const std::string& kind, const std::string& line);

 private:
  void Write(const std::string& safe);  // a sanitised line

  std::ostream& out_;
  std::string program_;
  std::function<std::string()> stamp_;
  std::mutex mutex_;
  LogLimiter limiter_;
};

}  // namespace lw::core
