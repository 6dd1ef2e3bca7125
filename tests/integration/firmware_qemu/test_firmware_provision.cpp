// The netduinoplus2 image (STM32F405 under qemu-system-arm) given a provisioning record it must
// refuse, placed by QEMU's loader where scripts/flash writes it (sector 4, 0x08010000): a record
// made for the l431 board, and a record of its own board with a corrupted byte. The board must stop
// in lw::board::HaltUnprovisioned (its program counter is read through QEMU's monitor) without
// sending one radio frame. The accepted record (the readings carry its sensor id) is
// test_integration_firmware_gateway_netduinoplus2_provisioned.
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "integration/firmware_qemu/qemu_link.hpp"
#include "support/mosquitto_fixture.hpp"

#include <CppUTest/TestHarness.h>

using Clock = std::chrono::steady_clock;

namespace {

// [start, end) of a function of the image, from arm-none-eabi-nm -C -S (0, 0 when absent).
std::pair<unsigned long, unsigned long> SymbolRange(lw::test::TempDirectory& dir, const std::string& demangled) {
  const std::string log = dir.File("nm.txt");
  if (lw::test::RunCommand({"arm-none-eabi-nm", "-C", "-S", LW_FIRMWARE_ELF}, log) != 0) return {0, 0};
  std::ifstream in(log);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::string addr, size, type, name;
    ls >> addr >> size >> type;
    std::getline(ls, name);
    if (name == " " + demangled) {
      const unsigned long start = std::stoul(addr, nullptr, 16) & ~1ul;
      return {start, start + std::stoul(size, nullptr, 16)};
    }
  }
  return {0, 0};
}

// One HMP command over QEMU's monitor socket; what it printed ("" when the monitor does not answer).
std::string Monitor(const std::string& socket_path, const std::string& command) {
  const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", socket_path.c_str());
  std::string out;
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0) {
    const std::string line = command + "\n";
    if (::write(fd, line.data(), line.size()) == static_cast<ssize_t>(line.size())) {
      // The answer ends with the next prompt after the command's own output.
      timeval tv{1, 0};
      ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
      char buf[4096];
      for (int i = 0; i < 30; ++i) {
        const ssize_t n = ::read(fd, buf, sizeof buf);
        if (n <= 0) break;
        out.append(buf, static_cast<size_t>(n));
        if (out.find("R15=") != std::string::npos && out.rfind("(qemu)") > out.find("R15=")) break;
      }
    }
  }
  ::close(fd);
  return out;
}

struct Outcome {
  bool halted = false;     // the program counter was seen inside HaltUnprovisioned
  std::string last_pc;     // the last one read
  size_t radio_bytes = 0;  // what the firmware sent on its radio UART
  std::string qemu_log;
};

// Boots the image with `record` at 0x08010000 and watches it for up to 120 s (returning as soon
// as the program counter is in [halt.first, halt.second), then reads the radio once more).
Outcome Boot(lw::test::TempDirectory& dir, const std::string& record, std::pair<unsigned long, unsigned long> halt) {
  const std::string monitor = dir.File("monitor.sock");
  lw::test::ChildProcess qemu;
  qemu.Start(
      {"qemu-system-arm", "-M", "netduinoplus2", "-nographic", "-monitor", "unix:" + monitor + ",server=on,wait=off", "-kernel",
       LW_FIRMWARE_ELF, "-serial", "pty", "-serial", "pty", "-device", "loader,file=" + record + ",addr=0x08010000"},
      dir.File("qemu.log"));
  std::string radio_path, ladder_path;
  for (int i = 0; i < 1200 && (radio_path.empty() || ladder_path.empty()); ++i) {
    lw::test::FindQemuPtys(lw::test::FileTail(dir.File("qemu.log"), 4000), &radio_path, &ladder_path);
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  Outcome o;
  const int radio = lw::test::OpenRawPty(radio_path);
  const auto drain = [&] {
    char buf[256];
    for (ssize_t n; radio >= 0 && (n = ::read(radio, buf, sizeof buf)) > 0;) o.radio_bytes += static_cast<size_t>(n);
  };
  static const std::regex pc_re(R"(R15=([0-9a-f]{8}))");
  for (const auto until = Clock::now() + std::chrono::seconds(120); !o.halted && Clock::now() < until;) {
    drain();
    std::smatch m;
    const std::string regs = Monitor(monitor, "info registers");
    if (std::regex_search(regs, m, pc_re)) {
      o.last_pc = m[1];
      const unsigned long pc = std::stoul(o.last_pc, nullptr, 16);
      o.halted = pc >= halt.first && pc < halt.second;
    }
    if (!o.halted) std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  drain();
  if (radio >= 0) ::close(radio);
  o.qemu_log = lw::test::FileTail(dir.File("qemu.log"));
  return o;
}

}  // namespace

TEST_GROUP(FirmwareProvision) {
  lw::test::TempDirectory dir{"lw-fw-provision"};
  std::pair<unsigned long, unsigned long> halt;
  void setup() override {
    halt = SymbolRange(dir, "lw::board::HaltUnprovisioned()");
    CHECK_TEXT(halt.second > halt.first, "the image has no lw::board::HaltUnprovisioned() (arm-none-eabi-nm -C -S)");
  }
  std::string Record(const std::string& board, const std::string& sensor) {
    const std::string out = dir.File("record-" + board + ".bin");
    const int rc = lw::test::RunCommand({LW_PROVISION_BIN, "record", "--board", board, "--sensor-id", sensor, "--out", out},
                                        dir.File("provision.log"));
    LONGS_EQUAL_TEXT(0, rc, lw::test::FileTail(dir.File("provision.log")).c_str());
    return out;
  }
  void ExpectHalted(const Outcome& o) {
    CHECK_TEXT(o.halted,
               ("the board did not stop in HaltUnprovisioned (last PC 0x" + o.last_pc + "); QEMU log:\n" + o.qemu_log).c_str());
    LONGS_EQUAL_TEXT(0, o.radio_bytes, "a refused board sent on its radio");
  }
};

TEST(FirmwareProvision, ARecordForTheOtherBoardStopsTheBoardBeforeItsRadioTalks) {
  ExpectHalted(Boot(dir, Record("l431", "4242"), halt));
}

TEST(FirmwareProvision, ACorruptedRecordStopsTheBoard) {
  const std::string path = Record("netduinoplus2", "4242");
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  f.seekp(8);  // the sensor id's low byte: the CRC no longer matches
  f.put(static_cast<char>(0x93));
  f.close();
  ExpectHalted(Boot(dir, path, halt));
}
