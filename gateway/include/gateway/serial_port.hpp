#pragma once
/// The coordinator's serial port (or a pty, FIFO or any path). A tty is set to raw 8N1 at the
/// given baud rate without flow control; other files are read as they are. Not thread-safe.
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>

#include "gateway/byte_sink.hpp"

namespace lw::gateway {

/// The line logged when `path` cannot be opened with `err` (an errno value). EPERM (a systemd
/// DevicePolicy / DeviceAllow refusal: the device cgroup) and EACCES (file permissions) name the
/// setting to change; docs/gateway.md, *Serial devices the unit allows*.
std::string OpenErrorText(const std::string& path, int err);

class SerialPort : public ByteSink {
 public:
  SerialPort(std::string path, int baud) : path_(std::move(path)), baud_(baud) {}
  ~SerialPort() override { Close(); }
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;

  /// Opens (non-blocking) and configures the port. Returns false and sets `*error` on failure.
  bool Open(std::string* error);
  void Close();
  bool is_open() const { return fd_ >= 0; }
  /// File descriptor for poll(), -1 when closed.
  int fd() const { return fd_; }
  const std::string& path() const { return path_; }

  /// Reads what is available without blocking. Returns the byte count (0: nothing now), or -1
  /// when the port is gone (EOF, hang-up, I/O error): Close() and Open() again later.
  long Read(uint8_t* buffer, size_t cap);
  /// Reads everything waiting, up to `cap` bytes, in as many reads as that takes (a tty or pty
  /// hands out at most ~4 KiB per read), without blocking: the frames that arrived together are
  /// then spooled together, under one fsync. Returns the byte count (0: nothing now), or -1 when
  /// the port is gone and nothing was read; bytes read before a hang-up are returned first (the
  /// next call reports the hang-up).
  long ReadWaiting(uint8_t* buffer, size_t cap);

  /// Writes all bytes, waiting up to 1 s in total for the port to drain. False on failure.
  bool Write(const uint8_t* data, size_t len) override;

 private:
  std::string path_;
  int baud_;
  int fd_ = -1;
  bool is_tty_ = false;  // a tty reading 0 bytes has hung up; a file or FIFO just has no data yet
};

}  // namespace lw::gateway
