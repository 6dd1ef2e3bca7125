// Boots the real firmware image under qemu-system-arm -M mps2-an386. UART0 (the radio) and UART1
// (the test path standing in for the SPI ladder) are ptys. The test sets the ladder's loop image,
// decodes the XBee frames the firmware sends with the shared protocol library, and acks them.
#include <chrono>
#include <csignal>
#include <fcntl.h>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <sys/wait.h>
#include <termios.h>
#include <thread>
#include <unistd.h>
#include <vector>

#include "protocol/frame_decoder.hpp"
#include "protocol/sensor_payload.hpp"
#include "integration/firmware_qemu/qemu_link.hpp"
#include "protocol/xbee_api.hpp"

#include <CppUTest/TestHarness.h>

// The machine the image is built for: mps2-an386 (hal/mps2) or netduinoplus2 (hal/stm32, STM32F405).
#ifndef LW_QEMU_MACHINE
#define LW_QEMU_MACHINE "mps2-an386"
#endif

using namespace lw::protocol;
using Clock = std::chrono::steady_clock;
using lw::test::FindQemuPtys;
using lw::test::LadderFrame;
using lw::test::OpenRawPty;

namespace {

class Qemu {
 public:
  Qemu() {
    char tmpl[] = "/tmp/lw-qemu-XXXXXX";
    dir_ = ::mkdtemp(tmpl);
    log_ = dir_ + "/qemu.log";
    pid_ = ::fork();
    if (pid_ == 0) {
      const int fd = ::open(log_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      ::dup2(fd, 1);
      ::dup2(fd, 2);
      ::execlp("qemu-system-arm", "qemu-system-arm", "-M", LW_QEMU_MACHINE, "-nographic", "-monitor", "none", "-kernel",
               LW_FIRMWARE_ELF, "-serial", "pty", "-serial", "pty", static_cast<char*>(nullptr));
      ::_exit(127);
    }
    // QEMU names its ptys once it has started: seconds on a loaded machine.
    for (int i = 0; i < 1200 && (radio_path_.empty() || ladder_path_.empty()); ++i) {
      std::ifstream in(log_);
      std::stringstream ss;
      ss << in.rdbuf();
      FindQemuPtys(ss.str(), &radio_path_, &ladder_path_);
      std::this_thread::sleep_for(std::chrono::milliseconds(25));
    }
    radio_ = OpenRawPty(radio_path_);
    ladder_ = OpenRawPty(ladder_path_);
  }
  ~Qemu() {
    if (radio_ >= 0) ::close(radio_);
    if (ladder_ >= 0) ::close(ladder_);
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
    std::remove(log_.c_str());
    ::rmdir(dir_.c_str());
  }
  bool ok() const { return radio_ >= 0 && ladder_ >= 0; }
  int radio() const { return radio_; }
  // Loops 0..intact-1 intact of a 100-loop ladder.
  void SetLadder(int intact) {
    unsigned char frame[15];
    const size_t n = LadderFrame(intact, frame);
    CHECK(::write(ladder_, frame, n) == static_cast<ssize_t>(n));
  }

 private:
  std::string dir_, log_, radio_path_, ladder_path_;
  pid_t pid_ = -1;
  int radio_ = -1, ladder_ = -1;
};

struct Received {
  uint32_t sensor_id = 0;
  SensorRecord record;
  Clock::time_point at;  // when the test read it
};

// Reads the radio for `seconds`, decoding readings; acks them when `ack` is set, noting in
// `acked_at` (when given) the time each seq was first acked.
std::vector<Received> Listen(Qemu& q, FrameDecoder& dec, double seconds, bool ack,
                             std::map<uint32_t, Clock::time_point>* acked_at = nullptr) {
  std::vector<Received> out;
  const auto end = Clock::now() + std::chrono::milliseconds(static_cast<int>(seconds * 1000));
  uint8_t buf[512];
  while (Clock::now() < end) {
    const ssize_t n = ::read(q.radio(), buf, sizeof buf);
    if (n <= 0) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      continue;
    }
    for (ssize_t i = 0; i < n; ++i) {
      if (dec.Feed(buf[i]) != DecodeEvent::kFrame) continue;
      TransmitRequest req;
      if (ParseTransmitRequest(dec.frame_data(), dec.frame_length(), &req) != Status::kOk) continue;
      ReadingsHeader h;
      SensorRecord recs[4];
      size_t count = 0;
      if (DecodeReadings(req.payload, req.payload_len, &h, recs, 4, &count) != PayloadStatus::kOk) continue;
      Ack a;
      a.sensor_id = h.sensor_id;
      for (size_t k = 0; k < count; ++k) {
        out.push_back({h.sensor_id, recs[k], Clock::now()});
        a.seqs[a.count++] = recs[k].seq;
      }
      if (!ack) continue;
      uint8_t payload[kMaxRfPayload], wire[kMaxWireFrame];
      size_t plen = 0;
      EncodeAck(a, payload, sizeof payload, &plen);
      const ReceivePacket rx{kCoordinatorAddress64, 0, 0, payload, plen};
      const size_t wlen = EncodeReceivePacket(ApiMode::kEscaped, rx, wire, sizeof wire);
      CHECK(::write(q.radio(), wire, wlen) == static_cast<ssize_t>(wlen));
      if (acked_at) {
        for (uint8_t k = 0; k < a.count; ++k) acked_at->emplace(a.seqs[k], Clock::now());
      }
    }
  }
  return out;
}

}  // namespace

TEST_GROUP(FirmwareOnQemu){};

TEST(FirmwareOnQemu, BootsReportsWearAndStopsRetransmittingWhenAcked) {
  Qemu q;
  CHECK_TEXT(q.ok(), "QEMU did not start with two ptys");
  FrameDecoder dec(ApiMode::kEscaped);
  q.SetLadder(84);
  // Wait for the first frame (an emulated boot on a loaded machine can take many seconds; up to
  // 120 s), then listen on without acks until a record is sent again (the firmware resends after
  // 1 s, then 2 s on; a starved emulator later), at most 60 s: a firmware that never resends
  // still fails.
  // The image is sent again every 5 s until a frame comes: QEMU's STM32 USART drops bytes that
  // arrive before the firmware has enabled it (netduinoplus2), and a frame only follows a valid read.
  auto first = Listen(q, dec, 0.5, false);
  for (int i = 0; i < 240 && first.empty(); ++i) {
    if (i % 10 == 9) q.SetLadder(84);
    first = Listen(q, dec, 0.5, false);
  }
  CHECK_TEXT(!first.empty(), "no frame from the firmware within 120 s of starting QEMU");
  const auto retransmitted = [&first] {
    std::map<uint32_t, int> copies;
    for (const auto& r : first) ++copies[r.record.seq];
    for (const auto& [seq, n] : copies) {
      if (n > 1) return true;
    }
    return false;
  };
  for (int i = 0; i < 120 && !retransmitted(); ++i) {
    for (const auto& r : Listen(q, dec, 0.5, false)) first.push_back(r);
  }
  LONGS_EQUAL(1001, first.front().sensor_id);
  CHECK(first.front().record.flags & kFlagBoot);
  CHECK_TEXT(retransmitted(), "unacknowledged records must be sent again");

  // Wear proceeds: every step is reported, thickness never goes up, acks stop retransmission.
  // Each step is held until its reading arrives (the firmware polls every second; an emulator
  // starved by a loaded host can take longer than any fixed window), at most 60 s: a step that
  // is never reported still fails below.
  std::vector<Received> all;
  std::map<uint32_t, Clock::time_point> acked_at;  // seq -> its first ack written to the firmware
  for (int loops = 83; loops >= 80; --loops) {
    q.SetLadder(loops);
    bool reported = false;
    for (int i = 0; i < 240 && !reported; ++i) {
      for (const auto& r : Listen(q, dec, 0.25, true, &acked_at)) {
        all.push_back(r);
        reported |= r.record.loops_intact == loops;
      }
    }
  }
  std::map<int, bool> seen;
  uint32_t last_seq = 0;
  int last_loops = 200;
  for (const auto& r : all) {
    seen[r.record.loops_intact] = true;
    if (r.record.seq > last_seq) {
      CHECK(r.record.loops_intact <= last_loops);
      last_loops = r.record.loops_intact;
      last_seq = r.record.seq;
    }
    LONGS_EQUAL(r.record.loops_intact * 10, r.record.thickness_dmm);
  }
  for (int loops = 80; loops <= 83; ++loops) CHECK_TEXT(seen[loops], "a thickness step was not reported");
  // Acks stop retransmission, judged by what the firmware sends rather than by a count of records
  // in a fixed window or a time since each ack (a starved emulator may legitimately resend, even
  // seconds later, before it has read an ack): the test goes on acking what it reads until no
  // acked seq has been sent again for kQuiet, longer than the firmware's longest resend interval
  // (backoff capped at 8 s, board config), so a firmware whose acks do not stop its resends never
  // gets there; at most 120 s.
  constexpr auto kQuiet = std::chrono::seconds(12);
  auto last_resend = Clock::now();  // of an acked seq
  std::map<uint32_t, int> resends;  // acked seq -> copies seen after its ack
  for (const auto until = Clock::now() + std::chrono::seconds(120);
       Clock::now() - last_resend < kQuiet && Clock::now() < until;) {
    for (const auto& r : Listen(q, dec, 0.5, true, &acked_at)) {
      const auto it = acked_at.find(r.record.seq);
      if (it == acked_at.end() || r.at <= it->second) continue;  // first seen now, acked after
      ++resends[r.record.seq];
      last_resend = r.at;
    }
  }
  std::string resent;
  for (const auto& [seq, n] : resends) resent += "seq " + std::to_string(seq) + ": " + std::to_string(n) + " copies\n";
  CHECK_TEXT(Clock::now() - last_resend >= kQuiet,
             ("the firmware kept resending acked records (resends after the ack):\n" + resent).c_str());
}
