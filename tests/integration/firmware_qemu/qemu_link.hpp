#pragma once
// Shared by the QEMU firmware tests: opening a QEMU pty raw, the ladder test-path frame, and
// finding the ptys QEMU reports ("char device redirected to /dev/pts/N (label serialK)").
#include <fcntl.h>
#include <regex>
#include <string>
#include <termios.h>
#include <unistd.h>

namespace lw::test {

/// Opens a pty non-blocking in raw mode; -1 when it cannot.
inline int OpenRawPty(const std::string& path) {
  if (path.empty()) return -1;
  const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK);
  if (fd < 0) return -1;
  termios t{};
  ::tcgetattr(fd, &t);
  ::cfmakeraw(&t);
  ::tcsetattr(fd, TCSANOW, &t);
  return fd;
}

/// Fills `serial0`/`serial1` from QEMU's log text when it names them.
inline void FindQemuPtys(const std::string& log_text, std::string* serial0, std::string* serial1) {
  static const std::regex re(R"((/dev/pts/\d+) \(label serial(\d)\))");
  for (std::sregex_iterator it(log_text.begin(), log_text.end(), re), end; it != end; ++it) {
    (((*it)[2] == "0") ? *serial0 : *serial1) = (*it)[1];
  }
}

/// Ladder test-path frame for UART1: loops 0..intact-1 of a 100-loop ladder intact.
/// Returns the number of bytes written to `out` (15).
inline size_t LadderFrame(int intact, unsigned char out[15]) {
  for (int i = 0; i < 15; ++i) out[i] = 0;
  out[0] = 0x55;
  out[1] = 13;
  for (int i = 0; i < intact; ++i) out[2 + i / 8] = static_cast<unsigned char>(out[2 + i / 8] | (1u << (i % 8)));
  return 15;
}

}  // namespace lw::test
