#pragma once
// A pty in raw mode standing in for a serial line in integration tests: the program under test
// opens slave_name(); the test writes and reads master() (non-blocking). Both ends are held open
// until destruction, so a killed program does not hang the pty up.
#include <fcntl.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <stdexcept>
#include <string>

namespace lw::test {

class RawPty {
 public:
  RawPty() {
    char name[128];
    if (openpty(&master_, &slave_, name, nullptr, nullptr) != 0) throw std::runtime_error("openpty failed");
    slave_name_ = name;
    termios tio{};
    tcgetattr(slave_, &tio);
    cfmakeraw(&tio);
    tcsetattr(slave_, TCSANOW, &tio);
    fcntl(master_, F_SETFL, fcntl(master_, F_GETFL) | O_NONBLOCK);
  }
  ~RawPty() {
    close(master_);
    close(slave_);
  }
  RawPty(const RawPty&) = delete;
  RawPty& operator=(const RawPty&) = delete;
  int master() const { return master_; }
  const std::string& slave_name() const { return slave_name_; }

 private:
  int master_ = -1;
  int slave_ = -1;
  std::string slave_name_;
};

}  // namespace lw::test
