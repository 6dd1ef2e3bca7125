#include <vector>

#include "hal/host/host_board.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw::hal;
using namespace lw::hal::host;

TEST_GROUP(HostBoard){};

TEST(HostBoard, LadderServesLoopsAsShiftRegisterBytesThenSignature) {
  HostLadder ladder(12);
  ladder.SetIntactCount(9);
  Spi& spi = ladder;
  uint8_t rx[3] = {};
  CHECK(spi.Transfer(nullptr, rx, 3));
  LONGS_EQUAL(0xFF, rx[0]);
  LONGS_EQUAL(0x01, rx[1]);  // loop 8 intact, 9..11 broken, 12..15 do not exist
  LONGS_EQUAL(kLadderSignature, rx[2]);
  ladder.SetStuckByte(0x00);
  CHECK(spi.Transfer(nullptr, rx, 3));
  LONGS_EQUAL(0x00, rx[2]);
  ladder.SetStuckByte(-1);
  ladder.SetTransferFails(true);
  CHECK_FALSE(spi.Transfer(nullptr, rx, 3));
}

TEST(HostBoard, FlickerLoopTogglesBetweenReads) {
  HostLadder ladder(8);
  ladder.SetIntactCount(4);
  ladder.SetFlickerLoop(4);
  uint8_t a[2], b[2];
  static_cast<Spi&>(ladder).Transfer(nullptr, a, 2);
  static_cast<Spi&>(ladder).Transfer(nullptr, b, 2);
  CHECK((a[0] ^ b[0]) == 0x10);
}

TEST(HostBoard, SleepJumpsVirtualTimeToTheAlarm) {
  HostRtc rtc(100);
  HostPower power(rtc);
  static_cast<Rtc&>(rtc).SetAlarm(1000);
  static_cast<Power&>(power).Sleep();
  LONGS_EQUAL(1000, rtc.now());
}

TEST(HostBoard, WatchdogExpiresWithoutKicks) {
  HostRtc rtc(0);
  HostWatchdog wd(rtc);
  static_cast<Watchdog&>(wd).Start(60);
  rtc.Advance(59);
  CHECK_FALSE(wd.Expired());
  static_cast<Watchdog&>(wd).Kick();
  rtc.Advance(61);
  CHECK(wd.Expired());
}

TEST(HostBoard, FlashIsNorAndLosesPowerAtTheChosenByte) {
  HostFlash flash(16, 2);
  FlashPages& f = flash;
  const uint8_t data[4] = {0x0F, 0xF0, 0x00, 0xAA};
  CHECK(f.Program(0, 0, data, 4));
  const uint8_t more[1] = {0xF0};
  CHECK(f.Program(0, 0, more, 1));  // programming only clears bits
  uint8_t out[4];
  CHECK(f.Read(0, 0, out, 4));
  LONGS_EQUAL(0x00, out[0]);
  flash.LosePowerAfter(5);  // erase of 16 bytes stops after 5
  CHECK_FALSE(f.Erase(0));
  CHECK(flash.power_lost());
  CHECK(f.Read(0, 0, out, 4));
  LONGS_EQUAL(0xFF, out[0]);
  LONGS_EQUAL(0xFF, out[3]);
  CHECK_FALSE(f.Program(1, 0, data, 1));  // everything fails until power returns
  flash.PowerRestored();
  CHECK(f.Program(1, 0, data, 1));
  CHECK_FALSE(f.Program(2, 0, data, 1));
  CHECK_FALSE(f.Program(0, 15, data, 2));
}

// Torn operations: the programmed byte at the cut has only some of its bits programmed, and an
// interrupted erase leaves every byte of the page part-way (old bits, some set), as on real NOR.
TEST(HostBoard, FlashTearsTheByteAndThePageThatPowerLossInterrupts) {
  const uint8_t zeros[16] = {};
  int torn_bytes = 0, half_erased_pages = 0;
  for (uint32_t seed = 1; seed <= 64; ++seed) {
    HostFlash flash(16, 1);
    FlashPages& f = flash;
    flash.TearAtPowerLoss(seed);
    flash.LosePowerAfter(3);  // bytes 0..2 programmed, byte 3 torn, 4.. untouched
    CHECK_FALSE(f.Program(0, 0, zeros, 16));
    uint8_t out[16];
    CHECK(f.Read(0, 0, out, 16));
    LONGS_EQUAL(0x00, out[2]);
    LONGS_EQUAL(0xFF, out[4]);
    if (out[3] != 0x00 && out[3] != 0xFF) ++torn_bytes;
    flash.PowerRestored();
    CHECK(f.Program(0, 0, zeros, 16));  // all zeros now
    flash.LosePowerAfter(8);            // the erase stops half way
    CHECK_FALSE(f.Erase(0));
    CHECK(f.Read(0, 0, out, 16));
    int partial = 0;  // of the bytes the erase had not reached: neither kept (0x00) nor erased
    for (int i = 8; i < 16; ++i) partial += (out[i] != 0x00 && out[i] != 0xFF) ? 1 : 0;
    for (int i = 0; i < 8; ++i) LONGS_EQUAL(0xFF, out[i]);
    if (partial >= 5) ++half_erased_pages;
  }
  CHECK(torn_bytes > 40);         // most seeds leave a part-programmed byte
  CHECK(half_erased_pages > 40);  // and a page of part-erased bytes
  // Without tearing the cut is clean (the existing model).
  HostFlash clean(16, 1);
  FlashPages& c = clean;
  clean.LosePowerAfter(3);
  CHECK_FALSE(c.Program(0, 0, zeros, 16));
  uint8_t out[16];
  CHECK(c.Read(0, 0, out, 16));
  LONGS_EQUAL(0xFF, out[3]);
}

TEST(HostBoard, RadioDeliversTransmitRequestsAndAnswersWithStatus) {
  HostRadio radio(0x0013A20000000001ull, lw::protocol::ApiMode::kEscaped);
  std::vector<uint8_t> got;
  radio.set_on_deliver([&](uint64_t src, const uint8_t* p, size_t n) {
    CHECK(src == 0x0013A20000000001ull);
    got.assign(p, p + n);
  });
  const uint8_t payload[3] = {0x7E, 0x11, 0x42};
  lw::protocol::TransmitRequest req;
  req.frame_id = 7;
  req.payload = payload;
  req.payload_len = 3;
  uint8_t frame[64], wire[160];
  size_t fl = 0;
  CHECK(lw::protocol::BuildTransmitRequest(req, frame, sizeof frame, &fl) == lw::protocol::Status::kOk);
  const size_t wl = lw::protocol::EncodeFrame(lw::protocol::ApiMode::kEscaped, frame, fl, wire, sizeof wire);
  static_cast<Uart&>(radio).Write(wire, wl);
  LONGS_EQUAL(3, got.size());
  LONGS_EQUAL(0x7E, got[0]);
  // The status frame comes back on the MCU side.
  uint8_t rx[64];
  const size_t n = static_cast<Uart&>(radio).Read(rx, sizeof rx);
  lw::protocol::FrameDecoder dec(lw::protocol::ApiMode::kEscaped);
  bool seen = false;
  for (size_t i = 0; i < n; ++i) {
    if (dec.Feed(rx[i]) == lw::protocol::DecodeEvent::kFrame) {
      lw::protocol::TransmitStatus st;
      CHECK(lw::protocol::ParseTransmitStatus(dec.frame_data(), dec.frame_length(), &st) == lw::protocol::Status::kOk);
      LONGS_EQUAL(7, st.frame_id);
      LONGS_EQUAL(0, st.delivery_status);
      seen = true;
    }
  }
  CHECK(seen);
  radio.set_link_up(false);
  got.clear();
  static_cast<Uart&>(radio).Write(wire, wl);
  CHECK(got.empty());
  LONGS_EQUAL(1, radio.delivered());
}

TEST(HostBoard, FlashPowerLossBrownsOutTheWholeBoard) {
  HostBoard hb(16, 0x0013A20000000002ull, lw::protocol::ApiMode::kEscaped);
  uint32_t delivered = 0;
  hb.radio.set_on_deliver([&](uint64_t, const uint8_t*, size_t) { ++delivered; });
  const uint8_t payload[2] = {0x01, 0x02};
  lw::protocol::TransmitRequest req;
  req.payload = payload;
  req.payload_len = 2;
  uint8_t frame[64], wire[160];
  size_t fl = 0;
  CHECK(lw::protocol::BuildTransmitRequest(req, frame, sizeof frame, &fl) == lw::protocol::Status::kOk);
  const size_t wl = lw::protocol::EncodeFrame(lw::protocol::ApiMode::kEscaped, frame, fl, wire, sizeof wire);
  Board b = hb.board();
  b.radio.Write(wire, wl);
  LONGS_EQUAL(1, delivered);
  hb.flash.LosePowerAfter(0);
  CHECK_FALSE(b.flash.Erase(0));
  b.radio.Write(wire, wl);  // the MCU is dead: nothing reaches the radio
  LONGS_EQUAL(1, delivered);
  LONGS_EQUAL(wl, hb.radio.bytes_lost_to_brownout());
  hb.flash.PowerRestored();
  b.radio.Write(wire, wl);
  LONGS_EQUAL(2, delivered);
}

// The virtual radio as Digi's modules are: it answers the local AT queries NP and EE, and a
// transmission above the unfragmented payload they imply is refused (0x74), never delivered.
TEST(HostBoard, RadioAnswersNpAndEeAndRefusesAFrameAboveItsPayloadLimit) {
  namespace pr = lw::protocol;
  HostRadio radio(0x0013A20000000001ull, pr::ApiMode::kEscaped);
  radio.set_np(0xFF);
  radio.set_ee(1);
  size_t delivered = 0;
  radio.set_on_deliver([&](uint64_t, const uint8_t*, size_t) { ++delivered; });
  pr::FrameDecoder dec(pr::ApiMode::kEscaped);
  const auto answers = [&] {
    std::vector<std::vector<uint8_t>> frames;
    uint8_t rx[256];
    const size_t n = static_cast<Uart&>(radio).Read(rx, sizeof rx);
    dec.Feed(rx, n, [&](pr::DecodeEvent ev) {
      if (ev == pr::DecodeEvent::kFrame) frames.emplace_back(dec.frame_data(), dec.frame_data() + dec.frame_length());
    });
    return frames;
  };
  for (const char* name : {"NP", "EE", "ZZ"}) {
    pr::AtCommand cmd;
    cmd.frame_id = 3;
    cmd.command[0] = name[0];
    cmd.command[1] = name[1];
    uint8_t wire[16];
    static_cast<Uart&>(radio).Write(wire, pr::EncodeAtCommand(pr::ApiMode::kEscaped, cmd, wire, sizeof wire));
    const auto frames = answers();
    LONGS_EQUAL(1, frames.size());
    pr::AtCommandResponse rsp;
    CHECK(pr::ParseAtCommandResponse(frames[0].data(), frames[0].size(), &rsp) == pr::Status::kOk);
    LONGS_EQUAL(3, rsp.frame_id);
    uint64_t v = 0;
    if (name[0] == 'Z') {
      LONGS_EQUAL(static_cast<int>(pr::AtStatus::kInvalidCommand), rsp.status);
      continue;
    }
    CHECK(rsp.Value(&v));
    LONGS_EQUAL(name[0] == 'N' ? 0xFF : 1, v);
  }
  LONGS_EQUAL(66, radio.rf_payload_limit());
  for (const size_t len : {size_t{66}, size_t{67}}) {
    uint8_t payload[pr::kMaxRfPayload] = {};
    pr::TransmitRequest req;
    req.frame_id = 9;
    req.payload = payload;
    req.payload_len = len;
    uint8_t wire[pr::kMaxWireFrame];
    static_cast<Uart&>(radio).Write(wire, pr::EncodeTransmitRequest(pr::ApiMode::kEscaped, req, wire, sizeof wire));
    const auto frames = answers();
    LONGS_EQUAL(1, frames.size());
    pr::TransmitStatus st;
    CHECK(pr::ParseTransmitStatus(frames[0].data(), frames[0].size(), &st) == pr::Status::kOk);
    LONGS_EQUAL(len == 66 ? 0x00 : 0x74, st.delivery_status);
  }
  LONGS_EQUAL(1, delivered);
  LONGS_EQUAL(1, radio.refused_too_large());
  LONGS_EQUAL(67, radio.largest_payload());
}
