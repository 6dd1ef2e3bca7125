#pragma once
/// Host port of the HAL: every peripheral is a fake whose behaviour a test or the simulator
/// controls. Host-only (uses the standard library freely). One HostBoard per virtual sensor board;
/// nothing is global, so a simulator can run many boards in one process.
#include <cstdint>
#include <deque>
#include <functional>
#include <vector>

#include "hal/board.hpp"
#include "protocol/frame_decoder.hpp"
#include "protocol/xbee_api.hpp"

namespace lw::hal::host {

/// Signature byte of the last (hard-wired) shift register in the ladder chain: a stuck bus reads
/// 0x00 or 0xFF there instead. The MCU firmware checks it after every read.
inline constexpr uint8_t kLadderSignature = 0xA5;

/// The wear ladder behind daisy-chained parallel-in shift registers: byte i carries loops
/// 8i..8i+7 (bit = 1: loop intact), then the signature byte.
class HostLadder final : public Spi {
 public:
  explicit HostLadder(uint8_t loops);
  uint8_t loops() const { return loops_; }
  /// Loops 0..n-1 intact (loop 0 nearest the base), the rest broken: a clean wear state.
  void SetIntactCount(uint8_t n);
  void SetLoop(uint8_t index, bool intact);
  bool Loop(uint8_t index) const;
  /// The loop toggles on every read (being cut at the wear face); -1 = none.
  void SetFlickerLoop(int index) { flicker_loop_ = index; }
  /// Every read returns this byte on the whole bus (stuck MISO); -1 = normal.
  void SetStuckByte(int value) { stuck_byte_ = value; }
  /// Every transfer fails (returns false) until cleared: no response from the chain.
  void SetTransferFails(bool fails) { transfer_fails_ = fails; }
  /// Only the next `n` transfers fail (a glitch inside one poll's votes).
  void FailNextTransfers(uint32_t n) { fail_next_ = n; }
  uint32_t transfers() const { return transfers_; }

 private:
  bool DoTransfer(const uint8_t* tx, uint8_t* rx, size_t len) override;
  uint8_t loops_;
  std::vector<bool> intact_;
  int flicker_loop_ = -1;
  bool flicker_phase_ = false;
  int stuck_byte_ = -1;
  bool transfer_fails_ = false;
  uint32_t fail_next_ = 0;
  uint32_t transfers_ = 0;
};

class HostPin final : public DigitalOut {
 public:
  bool high() const { return high_; }
  uint32_t rising_edges() const { return rising_edges_; }

 private:
  void DoSet(bool high) override {
    if (high && !high_) ++rising_edges_;
    high_ = high;
  }
  bool high_ = false;
  uint32_t rising_edges_ = 0;
};

class HostAdc final : public Adc {
 public:
  void set_battery_mv(int32_t mv) { battery_mv_ = mv; }
  void set_temperature_c(int32_t c) { temperature_c_ = c; }

 private:
  bool DoRead(AdcChannel channel, int32_t* value) override;
  int32_t battery_mv_ = 3600;
  int32_t temperature_c_ = 25;
};

/// Virtual time. The simulator advances it; Sleep() jumps to the alarm.
class HostRtc final : public Rtc {
 public:
  explicit HostRtc(uint32_t start = 0) : now_(start) {}
  void Advance(uint32_t seconds) { now_ += seconds; }
  void Set(uint32_t now) { now_ = now; }
  uint32_t alarm() const { return alarm_; }
  bool alarm_armed() const { return armed_; }
  uint32_t now() const { return now_; }

 private:
  uint32_t DoNowSeconds() override { return now_; }
  void DoSetAlarm(uint32_t at) override {
    alarm_ = at;
    armed_ = true;
  }
  uint32_t now_;
  uint32_t alarm_ = 0;
  bool armed_ = false;
};

class HostPower final : public Power {
 public:
  explicit HostPower(HostRtc& rtc) : rtc_(rtc) {}
  void set_reset_cause(ResetCause cause) { cause_ = cause; }
  uint32_t sleeps() const { return sleeps_; }

 private:
  void DoSleep() override;
  ResetCause DoLastResetCause() override { return cause_; }
  HostRtc& rtc_;
  ResetCause cause_ = ResetCause::kPowerOn;
  uint32_t sleeps_ = 0;
};

class HostWatchdog final : public Watchdog {
 public:
  explicit HostWatchdog(HostRtc& rtc) : rtc_(rtc) {}
  bool started() const { return started_; }
  uint32_t kicks() const { return kicks_; }
  uint32_t timeout_s() const { return timeout_s_; }
  /// True when the watchdog would have reset the MCU by now.
  bool Expired() const { return started_ && rtc_.now() - last_kick_ > timeout_s_; }

 private:
  void DoStart(uint32_t timeout_s) override {
    started_ = true;
    timeout_s_ = timeout_s;
    last_kick_ = rtc_.now();
  }
  void DoKick() override {
    ++kicks_;
    last_kick_ = rtc_.now();
  }
  HostRtc& rtc_;
  bool started_ = false;
  uint32_t timeout_s_ = 0;
  uint32_t last_kick_ = 0;
  uint32_t kicks_ = 0;
};

/// NOR flash: erase sets 0xFF, program clears bits. Power loss can be injected at any byte of
/// erase or program work: that byte and everything after it in the operation does not happen
/// (an erase proceeds byte by byte), and every later call fails until PowerRestored().
/// With TearAtPowerLoss(seed) the interruption is as ragged as on real NOR flash: the byte being
/// programmed keeps a pseudo-random part of its bits programmed, and an interrupted erase (a
/// sector erase works on every cell at once) leaves every byte of the page half erased (its old
/// value with pseudo-random bits set).
class HostFlash final : public FlashPages {
 public:
  HostFlash(size_t page_size, size_t page_count);
  /// After `bytes` more bytes of erase/program work, power is lost. -1 disables.
  void LosePowerAfter(long bytes) { budget_ = bytes; }
  /// Tear the operation that power loss interrupts (see the class comment); the bits come from a
  /// xorshift32 seeded with `seed` (0 is taken as 1), so a seed gives the same damage.
  void TearAtPowerLoss(uint32_t seed) {
    tear_ = true;
    tear_state_ = seed ? seed : 1;
  }
  bool power_lost() const { return power_lost_; }
  void PowerRestored() {
    power_lost_ = false;
    budget_ = -1;
  }
  /// Bytes of erase/program work done so far (to size an injection sweep).
  uint64_t work_bytes() const { return work_bytes_; }
  uint32_t erases() const { return erases_; }

 private:
  size_t DoPageSize() override { return page_size_; }
  size_t DoPageCount() override { return pages_.size(); }
  bool DoErase(size_t page) override;
  bool DoProgram(size_t page, size_t offset, const uint8_t* data, size_t len) override;
  bool DoRead(size_t page, size_t offset, uint8_t* data, size_t len) override;
  bool Spend();  // one byte of work; false when power is lost at it
  uint8_t TearBits();
  size_t page_size_;
  std::vector<std::vector<uint8_t>> pages_;
  long budget_ = -1;
  bool power_lost_ = false;
  uint64_t work_bytes_ = 0;
  uint32_t erases_ = 0;
  bool tear_ = false;
  uint32_t tear_state_ = 1;
};

/// The XBee module as seen from the MCU's UART, plus the radio link beyond it. It decodes the
/// firmware's API frames; a 0x10 Transmit Request is delivered to `on_deliver` when the link
/// accepts it and answered with a 0x8B Transmit Status either way. Frames for the firmware
/// (0x90 from the coordinator) are queued with Inject(). It answers the local AT queries NP and
/// EE (0x08 -> 0x88) with its settings, and refuses a transmission whose payload exceeds what one
/// unfragmented packet carries (protocol::RfPayloadLimit of them) with delivery status 0x74
/// data_payload_too_large, not delivered: a frame sized for a bigger link fails loudly here.
class HostRadio final : public Uart {
 public:
  using DeliverFn = std::function<void(uint64_t src64, const uint8_t* payload, size_t len)>;
  HostRadio(uint64_t address64, protocol::ApiMode mode);
  void set_on_deliver(DeliverFn fn) { on_deliver_ = std::move(fn); }
  /// false: every transmission fails with 0x21 network ACK failure (link down).
  void set_link_up(bool up) { link_up_ = up; }
  /// When set, asked once per transmission whether the link carries it (instead of set_link_up):
  /// a simulator's lossy air. Local AT commands never ask it.
  void set_link_check(std::function<bool()> fn) { link_check_ = std::move(fn); }
  /// The module's NP answer (default 0xFF, an XBee 3 in API mode) and EE setting (default 0).
  void set_np(uint8_t np) { np_ = np; }
  void set_ee(uint8_t ee) { ee_ = ee; }
  /// false: AT commands get no answer (a module in transparent mode, or a cut TX line).
  void set_answers_at(bool answers) { answers_at_ = answers; }
  /// The largest payload it delivers: protocol::RfPayloadLimit(np, ee).
  size_t rf_payload_limit() const;
  /// Transmissions refused as too large (0x74), and the largest payload the MCU asked to send.
  uint32_t refused_too_large() const { return refused_too_large_; }
  size_t largest_payload() const { return largest_payload_; }
  uint32_t at_queries() const { return at_queries_; }
  /// Supply check: while it returns false the board is browned out and whatever the MCU writes
  /// never reaches the radio (HostBoard ties it to the flash's injected power loss).
  void set_power_good(std::function<bool()> fn) { power_good_ = std::move(fn); }
  /// Bytes the MCU wrote while the supply was down (they went nowhere).
  uint64_t bytes_lost_to_brownout() const { return bytes_lost_to_brownout_; }
  /// Queues a 0x90 Receive Packet from the coordinator carrying `payload`.
  void Inject(const uint8_t* payload, size_t len);
  uint64_t address64() const { return address64_; }
  uint32_t transmit_requests() const { return transmit_requests_; }
  uint32_t delivered() const { return delivered_; }
  const protocol::DecoderCounters& counters() const { return decoder_.counters(); }

 private:
  size_t DoWrite(const uint8_t* data, size_t len) override;
  size_t DoRead(uint8_t* out, size_t cap) override;
  void QueueFrame(const uint8_t* frame_data, size_t len);
  void Transmit(const protocol::TransmitRequest& req);
  void AnswerAt(const protocol::AtCommand& cmd);
  uint64_t address64_;
  protocol::ApiMode mode_;
  protocol::FrameDecoder decoder_;
  DeliverFn on_deliver_;
  std::function<bool()> power_good_;
  std::function<bool()> link_check_;
  uint64_t bytes_lost_to_brownout_ = 0;
  bool link_up_ = true;
  std::deque<uint8_t> to_mcu_;
  uint32_t transmit_requests_ = 0;
  uint32_t delivered_ = 0;
  uint8_t np_ = protocol::kNpFragmentedMaximum;
  uint8_t ee_ = 0;
  bool answers_at_ = true;
  uint32_t refused_too_large_ = 0;
  size_t largest_payload_ = 0;
  uint32_t at_queries_ = 0;
};

/// All host peripherals of one board, wired into a hal::Board. A power loss injected with
/// `flash.LosePowerAfter()` browns out the whole board: from that byte on, the radio transmits
/// nothing until `flash.PowerRestored()` (the test then reboots the App, as the MCU would).
/// Peripherals refer to each other, so a HostBoard is built in place and never copied or moved.
struct HostBoard {
  HostBoard(uint8_t ladder_loops, uint64_t radio_address64, protocol::ApiMode mode, size_t flash_page_size = 256,
            size_t flash_pages = 2);
  HostBoard(const HostBoard&) = delete;
  HostBoard& operator=(const HostBoard&) = delete;
  HostLadder ladder;
  HostPin ladder_power;
  HostRadio radio;
  HostAdc adc;
  HostRtc rtc;
  HostPower power;
  HostWatchdog watchdog;
  HostFlash flash;
  Board board();
};

}  // namespace lw::hal::host
