#include "gateway/serial_port.hpp"

#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

namespace lw::gateway {
namespace {

speed_t ToSpeed(int baud) {
  switch (baud) {
    case 1200:
      return B1200;
    case 2400:
      return B2400;
    case 4800:
      return B4800;
    case 9600:
      return B9600;
    case 19200:
      return B19200;
    case 38400:
      return B38400;
    case 57600:
      return B57600;
    case 115200:
      return B115200;
    case 230400:
      return B230400;
    case 460800:
      return B460800;
    case 921600:
      return B921600;
    default:
      return B0;
  }
}

}  // namespace

std::string OpenErrorText(const std::string& path, int err) {
  std::string text = "serial " + path + ": cannot open: " + std::strerror(err);
  if (err == EPERM) {
    text +=
        " (a device policy refuses it: under systemd the unit's DevicePolicy=closed allows only the "
        "DeviceAllow= groups; add `DeviceAllow=char-NAME rw` for this device's group in /proc/devices "
        "with `systemctl edit linerwatch-gateway`, docs/gateway.md, *Serial devices the unit allows*)";
  } else if (err == EACCES) {
    text +=
        " (file permissions: the gateway's user must be in the device's group, usually dialout: "
        "`ls -l` the device, `adduser linerwatch-gateway dialout`, docs/gateway.md, *Serial devices the unit allows*)";
  }
  return text;
}

bool SerialPort::Open(std::string* error) {
  Close();
  fd_ = ::open(path_.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) {
    *error = OpenErrorText(path_, errno);
    return false;
  }
  is_tty_ = isatty(fd_) != 0;
  if (!is_tty_) return true;  // FIFO or file: nothing to configure
  termios tio{};
  if (tcgetattr(fd_, &tio) != 0) {
    *error = "serial " + path_ + ": tcgetattr: " + std::strerror(errno);
    Close();
    return false;
  }
  cfmakeraw(&tio);  // 8 data bits, no parity, no echo, no line editing
  tio.c_cflag &= ~static_cast<tcflag_t>(CSTOPB | PARENB | CRTSCTS);
  tio.c_cflag |= CLOCAL | CREAD | CS8;
  tio.c_iflag &= ~static_cast<tcflag_t>(IXON | IXOFF | IXANY);
  // VMIN=1 with O_NONBLOCK: an empty port reads EAGAIN, so a read of 0 bytes means hang-up.
  tio.c_cc[VMIN] = 1;
  tio.c_cc[VTIME] = 0;
  const speed_t speed = ToSpeed(baud_);
  if (speed == B0 || cfsetispeed(&tio, speed) != 0 || cfsetospeed(&tio, speed) != 0) {
    *error = "serial " + path_ + ": unsupported baud rate " + std::to_string(baud_);
    Close();
    return false;
  }
  if (tcsetattr(fd_, TCSANOW, &tio) != 0) {
    *error = "serial " + path_ + ": tcsetattr: " + std::strerror(errno);
    Close();
    return false;
  }
  return true;
}

void SerialPort::Close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

long SerialPort::Read(uint8_t* buffer, size_t cap) {
  if (fd_ < 0) return -1;
  const ssize_t n = ::read(fd_, buffer, cap);
  if (n > 0) return static_cast<long>(n);
  if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) return 0;
  if (n == 0 && !is_tty_) return 0;  // regular file or FIFO without writer: wait for more
  return -1;
}

long SerialPort::ReadWaiting(uint8_t* buffer, size_t cap) {
  size_t got = 0;
  while (got < cap) {
    const long n = Read(buffer + got, cap - got);
    if (n <= 0) {
      if (got == 0) return n;
      break;
    }
    got += static_cast<size_t>(n);
  }
  return static_cast<long>(got);
}

bool SerialPort::Write(const uint8_t* data, size_t len) {
  if (fd_ < 0) return false;
  size_t done = 0;
  int waited_ms = 0;
  while (done < len) {
    const ssize_t n = ::write(fd_, data + done, len - done);
    if (n > 0) {
      done += static_cast<size_t>(n);
      continue;
    }
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) return false;
    if (waited_ms >= 1000) return false;
    pollfd p{fd_, POLLOUT, 0};
    ::poll(&p, 1, 50);
    waited_ms += 50;
  }
  return true;
}

}  // namespace lw::gateway
