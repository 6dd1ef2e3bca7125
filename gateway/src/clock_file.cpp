#include "gateway/clock_file.hpp"

#include <fcntl.h>
#include <stdint.h>
#include <unistd.h>

namespace lw::gateway {

int64_t ClockFile::Now(int64_t fallback_ms) {
  char buf[32];
  ssize_t n = -1;
  const int fd = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd >= 0) {
    n = ::read(fd, buf, sizeof buf - 1);
    ::close(fd);
  }
  int64_t value = 0;
  bool digits = false;
  bool good = n > 0;
  for (ssize_t i = 0; good && i < n; ++i) {
    const char c = buf[i];
    if (c >= '0' && c <= '9' && value < INT64_MAX / 10 - 10) {
      value = value * 10 + (c - '0');
      digits = true;
    } else if ((c == '\n' || c == '\r' || c == ' ') && digits) {
      break;
    } else {
      good = false;
    }
  }
  ok_ = good && digits;
  if (ok_) last_ms_ = value;
  return last_ms_ >= 0 ? last_ms_ : fallback_ms;
}

}  // namespace lw::gateway
