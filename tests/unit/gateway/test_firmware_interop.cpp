// The real sensor firmware (firmware/app on the host HAL) against the real gateway logic: each
// transmission of the sensor becomes a coordinator 0x90 frame fed to Gateway::OnBytes, and each
// 0x10 ack the gateway writes is handed back to the sensor's radio. Shows that the two sides agree
// on the wire and that the no-loss chain holds across a gateway outage.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>
#include <map>
#include <memory>
#include <set>

#include <nlohmann/json.hpp>

#include "firmware/app.hpp"
#include "gateway/gateway.hpp"
#include "gateway/spool.hpp"
#include "hal/host/host_board.hpp"
#include "unit/gateway/gateway_test_support.hpp"

// CppUTest last: its new/delete macros break standard headers included after it.
#include <CppUTest/TestHarness.h>

namespace gw = lw::gateway;
namespace pr = lw::protocol;
using nlohmann::json;

namespace {

constexpr uint32_t kDay = 86400;
constexpr uint64_t kSensorAddress = 0x0013A20000001001ull;

// The coordinator radio between the two: the gateway's serial port on one side, the air on the
// other. `down` models the gateway being off: frames from the sensor are lost, no acks come back.
// It answers the gateway's AT NP / EE queries with `np` / `ee` (answers wait in `answers` for the
// test to feed back) and refuses an ack above the payload limit they imply, as a link without
// fragmentation would lose it.
class Coordinator : public gw::ByteSink {
 public:
  explicit Coordinator(lw::hal::host::HostRadio& sensor_radio) : sensor_radio_(sensor_radio) {}
  bool down = false;       // gateway off: the sensor's frames are lost
  bool acks_lost = false;  // the gateway's acks are lost on the way back (the sensor retransmits)
  size_t frames_lost = 0;
  size_t acks_delivered = 0;
  uint8_t np = pr::kNpFragmentedMaximum;
  uint8_t ee = 0;
  size_t acks_too_large = 0;
  size_t largest_ack = 0;
  std::vector<uint8_t> answers;

  bool Write(const uint8_t* data, size_t len) override {
    for (size_t i = 0; i < len; ++i) {
      if (decoder_.Feed(data[i]) != pr::DecodeEvent::kFrame) continue;
      pr::AtCommand cmd;
      if (pr::ParseAtCommand(decoder_.frame_data(), decoder_.frame_length(), &cmd) == pr::Status::kOk) {
        Answer(cmd);
        continue;
      }
      pr::TransmitRequest req;
      if (pr::ParseTransmitRequest(decoder_.frame_data(), decoder_.frame_length(), &req) != pr::Status::kOk) continue;
      largest_ack = std::max(largest_ack, req.payload_len);
      if (req.payload_len > pr::RfPayloadLimit(np, ee)) {
        ++acks_too_large;
        continue;
      }
      if (req.dest64 != sensor_radio_.address64() || acks_lost) continue;
      sensor_radio_.Inject(req.payload, req.payload_len);
      ++acks_delivered;
    }
    return true;
  }

 private:
  void Answer(const pr::AtCommand& cmd) {
    const bool is_np = cmd.command[0] == 'N' && cmd.command[1] == 'P';
    const uint8_t value[2] = {0, is_np ? np : ee};
    pr::AtCommandResponse rsp;
    rsp.frame_id = cmd.frame_id;
    rsp.command[0] = cmd.command[0];
    rsp.command[1] = cmd.command[1];
    rsp.data = is_np ? value : value + 1;
    rsp.data_len = is_np ? 2 : 1;
    uint8_t frame[16], wire[40];
    size_t n = 0;
    CHECK(pr::BuildAtCommandResponse(rsp, frame, sizeof frame, &n) == pr::Status::kOk);
    const size_t w = pr::EncodeFrame(pr::ApiMode::kEscaped, frame, n, wire, sizeof wire);
    answers.insert(answers.end(), wire, wire + w);
  }
  lw::hal::host::HostRadio& sensor_radio_;
  pr::FrameDecoder decoder_{pr::ApiMode::kEscaped};
};

}  // namespace

TEST_GROUP(FirmwareInterop) {
  lw::test::TempDirectory dir;
};

TEST(FirmwareInterop, EveryWearStepOfTheRealFirmwareReachesTheSpoolAcrossAGatewayOutage) {
  lw::firmware::Config config;
  lw::hal::host::HostBoard board(config.ladder_loops, kSensorAddress, config.api_mode);
  board.ladder.SetIntactCount(config.ladder_loops);
  lw::hal::Board hal_board = board.board();
  lw::firmware::App app(config, hal_board);
  app.Init();

  gw::Spool spool(dir.File("spool.db"), 100'000);
  lw::test::FakePublisher publisher;
  Coordinator coordinator(board.radio);
  gw::GatewayOptions options;
  options.site = "s1";
  options.crusher = "c1";
  options.api_mode = pr::ApiMode::kEscaped;
  options.log = [](const std::string&) {};
  gw::Gateway gateway(options, spool, publisher, coordinator);

  // The air: the sensor's transmissions arrive at the coordinator as 0x90 frames.
  board.radio.set_on_deliver([&](uint64_t src64, const uint8_t* payload, size_t len) {
    if (coordinator.down) {
      ++coordinator.frames_lost;
      return;
    }
    uint8_t wire[pr::kMaxWireFrame];
    const size_t n = pr::EncodeReceivePacket(pr::ApiMode::kEscaped, {src64, 0x4001, 0x01, payload, len}, wire, sizeof wire);
    CHECK(n > 0);
    gateway.OnBytes(wire, n, static_cast<int64_t>(board.rtc.now()) * 1000);
  });

  // 12 days, 100 -> 89 loops (one loop a day); the gateway is off from day 4 to day 6, and its
  // acks are lost from day 8 to day 9.
  const auto loops_at = [](uint32_t t) { return static_cast<uint8_t>(100 - std::min<uint32_t>(12, t / kDay)); };
  while (board.rtc.now() < 12 * kDay) {
    const uint32_t t = board.rtc.now();
    coordinator.down = t >= 4 * kDay && t < 6 * kDay;
    coordinator.acks_lost = t >= 8 * kDay && t < 9 * kDay;
    board.ladder.SetIntactCount(loops_at(t));
    app.RunOnce();
  }
  // Drain: let the firmware retransmit what the outage held back.
  while (board.rtc.now() < 13 * kDay) app.RunOnce();

  LONGS_EQUAL(0, app.queue().size());
  std::set<uint32_t> seqs;
  std::set<int> loops_reported;
  for (const gw::SpoolRecord& r : spool.Heads(100'000)) {
    const json j = json::parse(r.payload);
    STRCMP_EQUAL("1001", j["sensor"].get<std::string>().c_str());
    STRCMP_EQUAL("0013A20000001001", j["address"].get<std::string>().c_str());
    seqs.insert(r.seq);
    loops_reported.insert(j["loops_intact"].get<int>());
  }
  // Every record the firmware queued is spooled exactly once, with no gap in its seqs.
  LONGS_EQUAL(app.stats().records_queued, seqs.size());
  LONGS_EQUAL(*seqs.rbegin() - *seqs.begin() + 1, seqs.size());
  for (int v = 89; v <= 100; ++v) CHECK_TEXT(loops_reported.count(v) == 1, std::to_string(v).c_str());
  CHECK(coordinator.frames_lost > 0);
  CHECK(gateway.counters().records_duplicate > 0);  // retransmissions after lost acks, stored once
  LONGS_EQUAL(seqs.size(), gateway.counters().records_spooled);
  LONGS_EQUAL(0, gateway.counters().bad_payloads);
  LONGS_EQUAL(0, gateway.decoder_counters().checksum_errors);
  LONGS_EQUAL(app.stats().records_acked, seqs.size());
}

// The radio as it is: the sensor's radio and the coordinator answer NP 84 (EE=0), 66 (EE=1) and
// 49 (APS security), and each refuses a frame above it (no fragmentation). The sensor's backlog
// after a 1-day gateway outage go out in frames sized to the limit, the gateway's acks (one
// list per sensor and read) are sized to it too, and every record the firmware queued is spooled
// exactly once.
TEST(FirmwareInterop, EveryRecordArrivesOnceWhateverTheRadiosPayloadLimit) {
  struct Case {
    uint8_t np, ee;
  };
  for (const Case c : {Case{0x54, 0}, Case{0x42, 1}, Case{49, 1}}) {
    const size_t limit = pr::RfPayloadLimit(c.np, c.ee);
    const std::string what = "NP " + std::to_string(c.np);
    lw::test::TempDirectory case_dir;
    lw::firmware::Config config;
    config.ladder_loops = 16;  // 18-byte records: 4 fit 84 bytes, 3 fit 66, 2 fit 49
    lw::hal::host::HostBoard board(config.ladder_loops, kSensorAddress, config.api_mode);
    board.radio.set_np(c.np);
    board.radio.set_ee(c.ee);
    board.ladder.SetIntactCount(config.ladder_loops);
    lw::hal::Board hal_board = board.board();
    lw::firmware::App app(config, hal_board);

    gw::Spool spool(case_dir.File("spool.db"), 100'000);
    lw::test::FakePublisher publisher;
    Coordinator coordinator(board.radio);
    coordinator.np = c.np;
    coordinator.ee = c.ee;
    gw::GatewayOptions options;
    options.site = "s1";
    options.crusher = "c1";
    options.api_mode = pr::ApiMode::kEscaped;
    options.log = [](const std::string&) {};
    gw::Gateway gateway(options, spool, publisher, coordinator);
    gateway.OnRadioOpened(0);
    gateway.OnBytes(coordinator.answers.data(), coordinator.answers.size(), 0);
    LONGS_EQUAL_TEXT(limit, gateway.rf_payload_limit(), what.c_str());

    // The sensor's whole wake arrives at the coordinator as one read of the serial port.
    std::vector<uint8_t> air;
    board.radio.set_on_deliver([&](uint64_t src64, const uint8_t* payload, size_t len) {
      if (coordinator.down) {
        ++coordinator.frames_lost;
        return;
      }
      uint8_t wire[pr::kMaxWireFrame];
      const size_t n = pr::EncodeReceivePacket(pr::ApiMode::kEscaped, {src64, 0x4001, 0x01, payload, len}, wire, sizeof wire);
      air.insert(air.end(), wire, wire + n);
    });
    app.Init();
    // The board wakes every 3 hours, so that a backlog falls due together.
    for (uint32_t t = 0; t < 4 * kDay; t += 3 * 3600) {
      board.rtc.Set(t);
      coordinator.down = t >= kDay && t < 2 * kDay;
      board.ladder.SetIntactCount(static_cast<uint8_t>(16 - t / (kDay / 2) % 16));
      app.Step();
      if (!air.empty()) gateway.OnBytes(air.data(), air.size(), static_cast<int64_t>(t) * 1000);
      air.clear();
      app.Step();  // takes the acks
    }
    LONGS_EQUAL_TEXT(0, board.radio.refused_too_large(), what.c_str());
    LONGS_EQUAL_TEXT(0, coordinator.acks_too_large, what.c_str());
    CHECK_TEXT(board.radio.largest_payload() <= limit, what.c_str());
    CHECK_TEXT(coordinator.largest_ack <= limit, what.c_str());
    // The backlog went out in frames as full as the limit allows.
    LONGS_EQUAL_TEXT(pr::kReadingsHeaderSize + pr::kCrcSize + pr::MaxRecordsPerPayload(16, limit) * 18,
                     board.radio.largest_payload(), what.c_str());
    CHECK_TEXT(coordinator.frames_lost > 0, what.c_str());
    LONGS_EQUAL_TEXT(0, app.queue().size(), what.c_str());
    LONGS_EQUAL_TEXT(0, app.queue().dropped_total(), what.c_str());
    std::set<uint32_t> seqs;
    for (const gw::SpoolRecord& r : spool.Heads(100'000)) CHECK_TEXT(seqs.insert(r.seq).second, what.c_str());
    LONGS_EQUAL_TEXT(app.stats().records_queued, seqs.size(), what.c_str());
    LONGS_EQUAL_TEXT(*seqs.rbegin() - *seqs.begin() + 1, seqs.size(), what.c_str());
    LONGS_EQUAL_TEXT(seqs.size(), gateway.counters().records_spooled, what.c_str());
    LONGS_EQUAL_TEXT(0, gateway.counters().oversize_frames, what.c_str());
  }
}
