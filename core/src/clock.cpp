#include "core/clock.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <chrono>
#include <optional>

namespace lw::core {
namespace {

/// The whole number of ms in the file: digits, then optionally '\n', '\r' or ' ' and anything.
std::optional<int64_t> ReadClockFile(const std::string& path) {
  char buf[32];
  ssize_t n = -1;
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd >= 0) {
    n = ::read(fd, buf, sizeof buf - 1);
    ::close(fd);
  }
  if (n <= 0) return std::nullopt;
  int64_t value = 0;
  int digits = 0;
  for (ssize_t i = 0; i < n; ++i) {
    const char c = buf[i];
    if (c >= '0' && c <= '9' && digits < 18) {
      value = value * 10 + (c - '0');
      ++digits;
    } else if ((c == '\n' || c == '\r' || c == ' ') && digits > 0) {
      break;
    } else {
      return std::nullopt;
    }
  }
  if (digits == 0) return std::nullopt;
  return value;
}

}  // namespace

int64_t WallClockMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

int64_t Clock::NowMs() const {
  if (path_.empty()) return WallClockMs();
  const std::optional<int64_t> read = ReadClockFile(path_);
  ok_.store(read.has_value());
  if (read) {
    last_ms_.store(*read);
    return *read;
  }
  const int64_t last = last_ms_.load();
  return last >= 0 ? last : WallClockMs();
}

}  // namespace lw::core
