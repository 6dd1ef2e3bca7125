// SerialPort on a real pty: raw bytes both ways, reopen after hang-up.
#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <string>
#include <vector>

#include "gateway/serial_port.hpp"

// CppUTest last: its new/delete macros break standard headers included after it.
#include <CppUTest/TestHarness.h>

TEST_GROUP(SerialPort) {
  int master = -1;
  int slave = -1;
  std::string name;
  void setup() override {
    char buf[128];
    CHECK(openpty(&master, &slave, buf, nullptr, nullptr) == 0);
    name = buf;
  }
  void teardown() override {
    if (master >= 0) close(master);
    if (slave >= 0) close(slave);
  }
  std::vector<uint8_t> ReadMaster(size_t want) {
    std::vector<uint8_t> out;
    for (int tries = 0; tries < 100 && out.size() < want; ++tries) {
      pollfd p{master, POLLIN, 0};
      if (poll(&p, 1, 50) <= 0) continue;
      uint8_t b[256];
      const ssize_t n = read(master, b, sizeof b);
      if (n > 0) out.insert(out.end(), b, b + n);
    }
    return out;
  }
};

TEST(SerialPort, BinaryBytesPassUnchangedBothWays) {
  lw::gateway::SerialPort port(name, 115200);
  std::string error;
  CHECK_TRUE_TEXT(port.Open(&error), error.c_str());
  // Bytes a cooked tty would eat or translate: CR, NL, XON/XOFF, ^C, ^D, DEL.
  const std::vector<uint8_t> bytes{0x7E, 0x0D, 0x0A, 0x11, 0x13, 0x03, 0x04, 0x7F, 0x00, 0xFF};
  CHECK(write(master, bytes.data(), bytes.size()) == static_cast<ssize_t>(bytes.size()));
  std::vector<uint8_t> got;
  for (int tries = 0; tries < 100 && got.size() < bytes.size(); ++tries) {
    pollfd p{port.fd(), POLLIN, 0};
    poll(&p, 1, 50);
    uint8_t b[64];
    const long n = port.Read(b, sizeof b);
    CHECK(n >= 0);
    if (n > 0) got.insert(got.end(), b, b + n);
  }
  CHECK(got == bytes);
  CHECK_TRUE(port.Write(bytes.data(), bytes.size()));
  CHECK(ReadMaster(bytes.size()) == bytes);
}

TEST(SerialPort, EverythingWaitingIsReadInOneCallUpToTheBuffer) {
  // A pty (like a tty) hands out at most ~4 KiB per read(); ReadWaiting takes all that waits, so
  // that the frames that arrived together are spooled together (one fsync), and stops at `cap`.
  lw::gateway::SerialPort port(name, 115200);
  std::string error;
  CHECK_TRUE_TEXT(port.Open(&error), error.c_str());
  // As much as the pty holds (~20 KiB on Linux 6), written without blocking: several reads' worth.
  CHECK(fcntl(master, F_SETFL, fcntl(master, F_GETFL) | O_NONBLOCK) == 0);
  std::vector<uint8_t> bytes(64 * 1024);
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<uint8_t>(i * 7 + i / 256);
  size_t written = 0;
  for (int tries = 0; tries < 20; ++tries) {
    const ssize_t n = write(master, bytes.data() + written, bytes.size() - written);
    if (n > 0) written += static_cast<size_t>(n);
    poll(nullptr, 0, 5);
  }
  CHECK_TEXT(written > 12000, std::to_string(written).c_str());
  bytes.resize(written);
  pollfd p{port.fd(), POLLIN, 0};
  CHECK(poll(&p, 1, 2000) == 1);
  std::vector<uint8_t> got(bytes.size() + 1000);
  const long first = port.ReadWaiting(got.data(), 10000);
  LONGS_EQUAL(10000, first);
  const long rest = port.ReadWaiting(got.data() + first, got.size() - static_cast<size_t>(first));
  LONGS_EQUAL(written - 10000, rest);
  got.resize(bytes.size());
  CHECK(got == bytes);
  LONGS_EQUAL(0, port.ReadWaiting(got.data(), got.size()));  // nothing waits: no blocking, 0
}

TEST(SerialPort, MissingDeviceIsReportedWithItsPath) {
  lw::gateway::SerialPort port("/dev/does-not-exist-lw", 9600);
  std::string error;
  CHECK_FALSE(port.Open(&error));
  CHECK(error.find("/dev/does-not-exist-lw") != std::string::npos);
}

TEST(SerialPort, HangUpIsReportedSoTheCallerReopens) {
  lw::gateway::SerialPort port(name, 9600);
  std::string error;
  CHECK_TRUE(port.Open(&error));
  close(slave);
  slave = -1;
  close(master);
  master = -1;
  uint8_t b[16];
  LONGS_EQUAL(-1, port.Read(b, sizeof b));
  LONGS_EQUAL(-1, port.ReadWaiting(b, sizeof b));
}

// A device the unit's DevicePolicy refuses (EPERM from the device cgroup) or that the user may not
// open (EACCES) is reported with the setting to change, not just strerror.
TEST(SerialPort, APolicyOrPermissionRefusalNamesTheSettingToChange) {
  const std::string eperm = lw::gateway::OpenErrorText("/dev/ttyAMA0", EPERM);
  CHECK(eperm.find("/dev/ttyAMA0") != std::string::npos);
  CHECK(eperm.find("DeviceAllow=char-NAME rw") != std::string::npos);
  CHECK(eperm.find("systemctl edit linerwatch-gateway") != std::string::npos);
  const std::string eacces = lw::gateway::OpenErrorText("/dev/ttyUSB0", EACCES);
  CHECK(eacces.find("dialout") != std::string::npos);
  const std::string enoent = lw::gateway::OpenErrorText("/dev/ttyUSB9", ENOENT);
  CHECK(enoent.find("DeviceAllow") == std::string::npos);
  CHECK(enoent.find("No such file") != std::string::npos);
}
