#include <cmath>
#include <memory>
#include <set>
#include <string>

#include "fakes/fake_gateway.hpp"
#include "firmware/app.hpp"
#include "hal/host/host_board.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw;
using firmware::App;
using firmware::Config;

namespace {

constexpr uint32_t kDay = 86400;

struct Rig {
  explicit Rig(Config c = Config{})
      : config(c), board(c.ladder_loops, 0x0013A20000001001ull, c.api_mode), gateway(board.radio, &board.rtc) {
    CHECK(firmware::CheckConfig(c) == firmware::ConfigError::kOk);
    board.ladder.SetIntactCount(c.ladder_loops);
    Boot();
  }
  // A reset: RAM is lost, flash and the RTC survive.
  void Boot(hal::ResetCause cause = hal::ResetCause::kPowerOn) {
    board.power.set_reset_cause(cause);
    hal_board = std::make_unique<hal::Board>(board.board());
    app = std::make_unique<App>(config, *hal_board);
    app->Init();
  }
  // Runs wake cycles until virtual time reaches `until`, applying `wear(t)` before each wake.
  template <typename F>
  void RunUntil(uint32_t until, F wear) {
    while (board.rtc.now() < until) {
      wear(board.rtc.now());
      app->RunOnce();
      CHECK_FALSE(board.watchdog.Expired());
    }
  }
  void RunUntil(uint32_t until) {
    RunUntil(until, [](uint32_t) {});
  }
  // Like RunUntil, but stops after the wake in which the board lost power.
  template <typename F>
  void RunUntilPowerLoss(uint32_t until, F wear) {
    while (board.rtc.now() < until && !board.flash.power_lost()) {
      wear(board.rtc.now());
      app->RunOnce();
    }
  }
  // Thickness as the gateway sees it, in seq order, never goes up.
  void CheckMonotonicAtGateway() const {
    uint8_t prev = 255;
    for (const auto& [seq, r] : gateway.records) {
      CHECK(r.loops_intact <= prev);
      prev = r.loops_intact;
    }
  }
  std::vector<protocol::SensorRecord> Received() const {
    std::vector<protocol::SensorRecord> v;
    for (const auto& [seq, r] : gateway.records) v.push_back(r);
    return v;
  }
  Config config;
  hal::host::HostBoard board;
  test::FakeGateway gateway;
  std::unique_ptr<hal::Board> hal_board;
  std::unique_ptr<App> app;
};

// Accelerating wear over 95 days from 100 loops to 12.
uint8_t TrueLoops(uint32_t t) {
  const double f = std::min(1.0, t / (95.0 * kDay));
  return static_cast<uint8_t>(std::floor(100.0 - 88.0 * std::pow(f, 1.4) + 1e-9));
}

}  // namespace

TEST_GROUP(FirmwareApp){};

TEST(FirmwareApp, MonotonicWearOverAWholeCampaignReportsEveryStep) {
  Rig rig;
  rig.RunUntil(95 * kDay + 3600, [&](uint32_t t) { rig.board.ladder.SetIntactCount(TrueLoops(t)); });
  const auto recs = rig.Received();
  CHECK(recs.size() > 88);
  std::set<uint8_t> values;
  uint8_t prev = 255;
  for (const auto& r : recs) {  // in seq order
    CHECK(r.loops_intact <= prev);
    prev = r.loops_intact;
    values.insert(r.loops_intact);
    LONGS_EQUAL(r.loops_intact * 10, r.thickness_dmm);
  }
  // Every mm of wear was reported (each value from 100 down to 12).
  for (int v = 12; v <= 100; ++v) CHECK(values.count(static_cast<uint8_t>(v)) == 1);
  LONGS_EQUAL(12, prev);
  LONGS_EQUAL(0, rig.app->queue().size());
  LONGS_EQUAL(0, rig.gateway.bad_payloads);
  // Heartbeats kept flowing: at least one record every 6 h on average.
  CHECK(recs.size() >= 95 * 4);
  CHECK(rig.app->stats().wakes >= 95 * 96);
}

TEST(FirmwareApp, FlickerAtTheWearFaceNeverReportsThicknessGoingUp) {
  Rig rig;
  rig.board.ladder.SetIntactCount(50);
  rig.board.ladder.SetFlickerLoop(50);
  rig.RunUntil(2 * kDay);
  bool flicker_flagged = false;
  for (const auto& r : rig.Received()) {
    CHECK(r.loops_intact <= 51);
    if (r.flags & protocol::kFlagFlicker) flicker_flagged = true;
  }
  CHECK(flicker_flagged);
  const uint16_t first = rig.app->reported_thickness_dmm();
  rig.board.ladder.SetFlickerLoop(-1);  // loop 50 finally cut
  rig.RunUntil(3 * kDay);
  LONGS_EQUAL(500, rig.app->reported_thickness_dmm());
  CHECK(first >= 500);
}

TEST(FirmwareApp, CrackCuttingALoopEarlyIsFlaggedNotReportedAsWear) {
  Rig rig;
  rig.board.ladder.SetIntactCount(80);
  rig.RunUntil(kDay);
  rig.board.ladder.SetLoop(30, false);
  rig.RunUntil(2 * kDay);
  LONGS_EQUAL(800, rig.app->reported_thickness_dmm());
  bool flagged = false;
  for (const auto& r : rig.Received()) flagged |= (r.flags & protocol::kFlagNonContiguous) != 0;
  CHECK(flagged);
}

TEST(FirmwareApp, ALoopThatHealsIsFlaggedAndThicknessStaysDown) {
  Rig rig;
  rig.board.ladder.SetIntactCount(40);
  rig.RunUntil(kDay);
  rig.board.ladder.SetIntactCount(42);  // moisture bridges two broken loops
  rig.RunUntil(2 * kDay);
  LONGS_EQUAL(400, rig.app->reported_thickness_dmm());
  bool healed = false;
  for (const auto& r : rig.Received()) {
    CHECK(r.loops_intact <= 40 || r.seq < 2);
    healed |= (r.flags & protocol::kFlagLoopHealed) != 0;
  }
  CHECK(healed);
}

// Day 1 to 21 without a radio link while the ladder wears by `wear(t)`, then two days with it:
// heartbeats were dropped, no step; every value from 100 down to `lowest` arrived.
template <typename F>
void OutageLosesNoStep(Rig& rig, F wear, int lowest) {
  rig.RunUntil(kDay);
  rig.board.radio.set_link_up(false);
  rig.RunUntil(21 * kDay, wear);
  CHECK(rig.app->queue().dropped_heartbeats() > 0);
  LONGS_EQUAL(0, rig.app->queue().dropped_steps());
  rig.board.radio.set_link_up(true);
  rig.RunUntil(23 * kDay);
  LONGS_EQUAL(0, rig.app->queue().size());
  std::set<uint8_t> values;
  for (const auto& r : rig.Received()) values.insert(r.loops_intact);
  for (int v = lowest; v <= 100; ++v) CHECK_TEXT(values.count(static_cast<uint8_t>(v)) == 1, std::to_string(v).c_str());
}

TEST(FirmwareApp, RadioDownForDaysThenBackLosesNoThicknessStep) {
  Rig rig;
  // 20 days down: 20 steps of wear and ~80 heartbeats, more than the queue holds.
  OutageLosesNoStep(
      rig, [&](uint32_t t) { rig.board.ladder.SetIntactCount(static_cast<uint8_t>(100 - (t - kDay) / kDay)); }, 81);
  // The drops are reported to the gateway.
  LONGS_EQUAL(rig.app->queue().dropped_total(), rig.gateway.last_dropped_total);
  bool flagged = false;
  for (const auto& r : rig.Received()) flagged |= (r.flags & protocol::kFlagDropped) != 0;
  CHECK(flagged);
  // Retransmission backed off while the link was down: far fewer frames than wakes.
  CHECK(rig.board.radio.transmit_requests() < rig.app->stats().wakes);
}

// The queue's size (kQueueCapacity, docs/firmware.md): 20 days without a radio link at the fastest
// row's end-of-campaign wear rate (4 mm in 3 days, 1.33 mm/day: 26 steps and ~80 heartbeats)
// loses no thickness step; only heartbeats are given up.
TEST(FirmwareApp, TwentyDaysDownAtThePeakWearRateLosesNoStep) {
  Rig rig;
  OutageLosesNoStep(
      rig, [&](uint32_t t) { rig.board.ladder.SetIntactCount(static_cast<uint8_t>(100 - (t - kDay) * 4 / (3 * kDay))); }, 74);
  CHECK(rig.app->queue().dropped_heartbeats() > 40);  // the queue was full for most of the outage
}

TEST(FirmwareApp, UnackedRecordsAreRetransmittedUntilAcknowledged) {
  Rig rig;
  rig.gateway.set_acking(false);  // gateway receives but its acks are lost
  rig.board.ladder.SetIntactCount(90);
  rig.RunUntil(kDay);
  const size_t arrivals = rig.gateway.arrival_order.size();
  CHECK(arrivals > rig.gateway.records.size());  // duplicates: retransmissions
  CHECK(rig.app->queue().size() > 0);
  rig.gateway.set_acking(true);
  rig.RunUntil(2 * kDay);
  LONGS_EQUAL(0, rig.app->queue().size());
}

TEST(FirmwareApp, ResetNeverReusesASequenceNumberAndKeepsThickness) {
  Rig rig;
  rig.RunUntil(3 * kDay, [&](uint32_t t) { rig.board.ladder.SetIntactCount(static_cast<uint8_t>(100 - t / kDay)); });
  const uint32_t max_seq = rig.gateway.records.rbegin()->first;
  rig.board.ladder.SetIntactCount(99);  // a glitch after reset must not raise thickness
  rig.Boot();
  rig.RunUntil(4 * kDay);
  LONGS_EQUAL(980, rig.app->reported_thickness_dmm());
  bool boot_seen = false;
  for (const auto& [seq, r] : rig.gateway.records) {
    if (r.flags & protocol::kFlagBoot && seq > max_seq) boot_seen = true;
  }
  CHECK(boot_seen);
  CHECK(rig.app->next_seq() > max_seq);
}

TEST(FirmwareApp, PowerLossDuringEveryFlashWriteOfABootNeverReusesASeq) {
  // Sweep the power cut over every byte of the boot-time state write.
  for (long cut = 0; cut < 300; cut += 7) {
    Rig rig;
    rig.RunUntil(kDay, [&](uint32_t t) { rig.board.ladder.SetIntactCount(static_cast<uint8_t>(100 - t / 20000)); });
    const uint32_t max_seq = rig.gateway.records.rbegin()->first;
    rig.board.flash.LosePowerAfter(cut);
    rig.Boot();  // the boot's save is cut
    rig.board.flash.PowerRestored();
    rig.Boot();  // power back: a clean boot
    rig.RunUntil(2 * kDay);
    CHECK(rig.app->next_seq() > max_seq + 1);
    for (const auto& [seq, r] : rig.gateway.records) {
      if (seq > max_seq) CHECK(r.loops_intact <= 96);
    }
  }
}

TEST(FirmwareApp, WatchdogIsKickedEveryWakeAndAResetIsReported) {
  Rig rig;
  rig.RunUntil(kDay);
  CHECK(rig.board.watchdog.started());
  CHECK(rig.board.watchdog.kicks() >= rig.app->stats().wakes);
  CHECK(rig.board.watchdog.timeout_s() > rig.config.poll_period_s);
  // The firmware hangs: no wake for longer than the timeout -> the watchdog fires.
  rig.board.rtc.Advance(rig.config.watchdog_timeout_s + 1);
  CHECK(rig.board.watchdog.Expired());
  const uint32_t max_seq = rig.gateway.records.rbegin()->first;
  rig.Boot(hal::ResetCause::kWatchdog);
  rig.RunUntil(rig.board.rtc.now() + 3600);
  bool reported = false;
  for (const auto& [seq, r] : rig.gateway.records) {
    if (seq > max_seq && (r.flags & protocol::kFlagWatchdogReset)) reported = true;
  }
  CHECK(reported);
}

TEST(FirmwareApp, StuckSpiBusAndAllOpenAreFaultsNotWear) {
  Rig rig;
  rig.board.ladder.SetIntactCount(70);
  rig.RunUntil(kDay);
  rig.board.ladder.SetStuckByte(0x00);
  rig.RunUntil(2 * kDay);
  LONGS_EQUAL(700, rig.app->reported_thickness_dmm());
  rig.board.ladder.SetStuckByte(-1);
  rig.board.ladder.SetIntactCount(0);  // cable cut: every loop reads open
  rig.RunUntil(3 * kDay);
  LONGS_EQUAL(700, rig.app->reported_thickness_dmm());  // 70 loops cannot all break at once
  rig.board.ladder.SetIntactCount(69);                  // cable repaired; wear went on meanwhile
  rig.RunUntil(4 * kDay);
  LONGS_EQUAL(690, rig.app->reported_thickness_dmm());
  rig.CheckMonotonicAtGateway();
  bool stuck = false, all_open = false;
  for (const auto& r : rig.Received()) {
    stuck |= (r.flags & protocol::kFlagSpiStuck) != 0;
    all_open |= (r.flags & protocol::kFlagAllOpen) != 0;
  }
  CHECK(stuck);
  CHECK(all_open);
}

TEST(FirmwareApp, LowBatteryIsFlagged) {
  Rig rig;
  rig.board.adc.set_battery_mv(3100);
  rig.RunUntil(kDay);
  const auto recs = rig.Received();
  CHECK(recs.back().flags & protocol::kFlagLowBattery);
  LONGS_EQUAL(3100, recs.back().battery_mv);
}

TEST(FirmwareApp, NoRecordBeforeTheFirstValidLadderRead) {
  Rig rig;
  rig.board.ladder.SetTransferFails(true);  // ladder cable not yet connected at boot
  rig.RunUntil(3600);
  LONGS_EQUAL(0, rig.gateway.records.size());
  rig.board.ladder.SetTransferFails(false);
  rig.board.ladder.SetIntactCount(88);
  rig.RunUntil(7200);
  CHECK(!rig.gateway.records.empty());
  const auto& first = rig.gateway.records.begin()->second;
  LONGS_EQUAL(88, first.loops_intact);
  CHECK(first.flags & protocol::kFlagBoot);
  CHECK(first.flags & protocol::kFlagSpiStuck);  // the early failures are reported, not lost
}

namespace {
// One wear step every 3 h and a seq block of 2: thickness saves and seq-block saves interleave.
Config PowerLossConfig() {
  Config c;
  c.seq_reserve_block = 2;
  return c;
}
uint8_t StepEvery3h(uint32_t t) {
  return static_cast<uint8_t>(100 - t / (3 * 3600));
}
}  // namespace

// The board browns out at every byte of every flash erase/program during a day of wear (both
// kinds of save: a new thickness and a new seq block), reboots at once, and runs on. The first
// read after the reboot catches the loop being cut still closed (flicker at the face), the case
// where restoring an older thickness would report wear going up.
TEST(FirmwareApp, PowerLossAtEveryByteOfEveryFlashWriteRecovers) {
  uint64_t work = 0;
  {
    Rig probe(PowerLossConfig());
    const uint64_t boot_work = probe.board.flash.work_bytes();
    probe.RunUntil(kDay, [&](uint32_t t) { probe.board.ladder.SetIntactCount(StepEvery3h(t)); });
    work = probe.board.flash.work_bytes() - boot_work;
  }
  CHECK(work > 5 * 256);  // several saves in the window
  for (long cut = 0; cut < static_cast<long>(work); ++cut) {
    Rig rig(PowerLossConfig());
    auto wear = [&](uint32_t t) { rig.board.ladder.SetIntactCount(StepEvery3h(t)); };
    rig.board.flash.LosePowerAfter(cut);
    rig.RunUntilPowerLoss(kDay, wear);
    CHECK(rig.board.flash.power_lost());
    rig.board.flash.PowerRestored();
    const uint32_t t_loss = rig.board.rtc.now();
    rig.board.ladder.SetIntactCount(static_cast<uint8_t>(StepEvery3h(t_loss) + 1));  // flicker
    rig.Boot(hal::ResetCause::kBrownout);
    rig.app->RunOnce();
    rig.RunUntil(t_loss + kDay / 2, wear);
    LONGS_EQUAL(0, rig.gateway.seq_conflicts);
    rig.CheckMonotonicAtGateway();
    LONGS_EQUAL(StepEvery3h(rig.board.rtc.now() - 1) * 10, rig.app->reported_thickness_dmm());
    LONGS_EQUAL(0, rig.app->queue().size());
    // Every step of wear reached the gateway despite the power loss.
    std::set<uint8_t> values;
    for (const auto& [seq, r] : rig.gateway.records) values.insert(r.loops_intact);
    for (uint8_t v = StepEvery3h(rig.board.rtc.now() - 1); v <= 100; ++v) CHECK(values.count(v) == 1);
  }
}

// The flash fails (e.g. worn out) while the MCU keeps running and the radio works: the firmware
// must not send records whose seq reservation or thickness is not saved, or the next reset would
// reuse seqs. It resumes once the flash works again.
TEST(FirmwareApp, FlashFailureWithoutResetNeverLeadsToReusedSeqs) {
  Rig rig(PowerLossConfig());
  rig.board.radio.set_power_good(nullptr);  // the MCU keeps running: no brownout
  auto wear = [&](uint32_t t) { rig.board.ladder.SetIntactCount(StepEvery3h(t)); };
  rig.RunUntil(kDay / 2, wear);
  const size_t before = rig.gateway.records.size();
  rig.board.flash.LosePowerAfter(0);  // every erase/program fails from now on
  rig.RunUntil(kDay, wear);
  CHECK(rig.app->stats().flash_errors > 0);
  LONGS_EQUAL(before, rig.gateway.records.size());  // nothing new without a durable state
  rig.board.flash.PowerRestored();
  rig.Boot();
  rig.RunUntil(2 * kDay, wear);
  LONGS_EQUAL(0, rig.gateway.seq_conflicts);
  rig.CheckMonotonicAtGateway();
  LONGS_EQUAL(StepEvery3h(rig.board.rtc.now() - 1) * 10, rig.app->reported_thickness_dmm());
}

// Drops are counted over the board's life: a reset does not zero the count the gateway sees.
TEST(FirmwareApp, DroppedCountSurvivesAReset) {
  Rig rig;
  rig.board.radio.set_link_up(false);
  rig.RunUntil(20 * kDay);  // ~80 heartbeats into 48 slots
  const uint32_t dropped = rig.app->dropped_total();
  CHECK(dropped > 0);
  rig.Boot();
  LONGS_EQUAL(dropped, rig.app->dropped_total());
  rig.board.radio.set_link_up(true);
  rig.RunUntil(21 * kDay);
  CHECK(!rig.gateway.records.empty());
  LONGS_EQUAL(dropped, rig.gateway.last_dropped_total);
  CHECK(rig.gateway.records.rbegin()->second.flags & protocol::kFlagDropped);
}

// Retransmissions back off exponentially between backoff_min_s and backoff_max_s, less a
// per-board jitter of up to a quarter, so boards that lost the link together spread out.
TEST(FirmwareApp, RetransmissionsBackOffWithPerBoardJitter) {
  std::vector<std::vector<uint32_t>> tries;
  for (uint32_t id : {1001u, 1002u}) {
    Config c;
    c.sensor_id = id;
    c.heartbeat_period_s = 10 * kDay;  // no heartbeats: a single record is retried
    Rig rig(c);
    rig.board.radio.set_link_up(false);
    rig.board.ladder.SetIntactCount(90);  // one record, never acked
    std::vector<uint32_t> times;
    uint32_t last_requests = rig.board.radio.transmit_requests();
    while (rig.board.rtc.now() < 3 * kDay) {
      rig.app->RunOnce();
      if (rig.board.radio.transmit_requests() != last_requests && rig.app->queue().size() == 1) {
        times.push_back(rig.board.rtc.now());
      }
      last_requests = rig.board.radio.transmit_requests();
    }
    CHECK(times.size() >= 6);
    uint32_t nominal = c.backoff_min_s;
    for (size_t i = 1; i < times.size(); ++i) {
      const uint32_t gap = times[i] - times[i - 1];
      // The wake happens at the retry alarm or the next poll, whichever is first.
      CHECK(gap <= nominal);
      CHECK(gap >= std::min(nominal - nominal / 4, c.poll_period_s));
      nominal = std::min(nominal * 2, c.backoff_max_s);
    }
    tries.push_back(times);
  }
  CHECK(tries[0] != tries[1]);  // the two boards do not retry in lockstep
}

// Re-provisioning the board for another ladder length forgets the thickness, not the seqs.
TEST(FirmwareApp, ReprovisionedLadderKeepsSequenceNumbersAndForgetsThickness) {
  Rig rig;
  rig.board.ladder.SetIntactCount(70);
  rig.RunUntil(kDay);
  const uint32_t max_seq = rig.gateway.records.rbegin()->first;
  rig.config.ladder_loops = 64;
  rig.Boot();
  CHECK(rig.app->next_seq() > max_seq);
  LONGS_EQUAL(0xFFFF, rig.app->reported_thickness_dmm());
}

// The last loop breaking is wear: the sensor is consumed and reports 0 loops with all_open.
TEST(FirmwareApp, LastLoopBreakingReportsTheSensorConsumed) {
  Rig rig;
  rig.board.ladder.SetIntactCount(1);
  rig.RunUntil(kDay);
  LONGS_EQUAL(10, rig.app->reported_thickness_dmm());
  rig.board.ladder.SetIntactCount(0);
  rig.RunUntil(2 * kDay);
  LONGS_EQUAL(0, rig.app->reported_thickness_dmm());
  const auto& last = rig.gateway.records.rbegin()->second;
  LONGS_EQUAL(0, last.loops_intact);
  CHECK(last.flags & protocol::kFlagAllOpen);
}

// A board whose ladder reads all open from the first poll (cable cut before installation) sends
// nothing rather than 0 mm, like a board whose bus is stuck.
TEST(FirmwareApp, AllOpenBeforeAnyValidReadSendsNoThickness) {
  Rig rig;
  rig.board.ladder.SetIntactCount(0);
  rig.Boot();
  rig.RunUntil(kDay);
  LONGS_EQUAL(0, rig.gateway.records.size());
  rig.board.ladder.SetIntactCount(95);
  rig.RunUntil(kDay + 3600);
  const auto& first = rig.gateway.records.begin()->second;
  LONGS_EQUAL(95, first.loops_intact);
  CHECK(first.flags & protocol::kFlagAllOpen);  // the earlier fault rides on the first record
}

// Frames are sized to what the radio says one unfragmented packet carries (its NP and EE answers),
// never more: the host radio refuses (0x74 data_payload_too_large) anything larger, as a link
// without fragmentation would lose it. The board wakes every 3 hours (so that records fall due
// together), a backlog after a 2-day outage goes out in frames as full as the limit allows, and
// every record arrives.
TEST(FirmwareApp, FramesNeverExceedTheRadiosPayloadLimit) {
  struct Case {
    uint8_t np, ee;
    bool answers;
    size_t limit, largest;  // expected payload limit and largest frame (100-loop ladder: 41 per record, 70 for two)
  };
  const Case cases[] = {
      {0x54, 0, true, 84, 70},                        // S2C, EE=0: NP is the single-packet limit
      {0xFF, 0, true, 84, 70},                        // XBee 3 in API mode: NP 0xFF, the EE table decides
      {0x42, 1, true, 66, 41},                        // network encryption
      {0xFF, 1, true, 66, 41},                        // XBee 3 with EE=1
      {49, 1, true, 49, 41},                          // APS encryption and a secure session: smaller still
      {0xFF, 0, false, protocol::kMinRfPayload, 41},  // no answer: the smallest supported size
  };
  for (const Case& c : cases) {
    const std::string what = "NP " + std::to_string(c.np) + " EE " + std::to_string(c.ee) + (c.answers ? "" : " (no answer)");
    Config config;
    hal::host::HostBoard board(config.ladder_loops, 0x0013A20000001001ull, config.api_mode);
    board.radio.set_np(c.np);
    board.radio.set_ee(c.ee);
    board.radio.set_answers_at(c.answers);
    board.ladder.SetIntactCount(config.ladder_loops);
    test::FakeGateway gateway(board.radio, &board.rtc);
    hal::Board hal_board = board.board();
    App app(config, hal_board);
    app.Init();
    for (uint32_t t = 0; t < 8 * kDay; t += 3 * 3600) {
      board.rtc.Set(t);
      board.radio.set_link_up(t < kDay || t >= 3 * kDay);
      board.ladder.SetIntactCount(static_cast<uint8_t>(100 - t / kDay));
      app.Step();
    }
    LONGS_EQUAL_TEXT(c.limit, app.rf_payload_limit(), what.c_str());
    LONGS_EQUAL_TEXT(0, board.radio.refused_too_large(), what.c_str());
    CHECK_TEXT(board.radio.largest_payload() <= c.limit, what.c_str());
    LONGS_EQUAL_TEXT(c.largest, board.radio.largest_payload(), what.c_str());
    LONGS_EQUAL_TEXT(0, app.queue().size(), what.c_str());
    LONGS_EQUAL_TEXT(app.stats().records_queued, gateway.records.size(), what.c_str());
    CHECK_TEXT(board.radio.at_queries() >= 2, what.c_str());
  }
}

// A radio that refuses a frame as too large (a source route or APS security the NP answer does
// not show) turns the firmware to the smallest frames until the next join; nothing is lost.
TEST(FirmwareApp, AFrameRefusedAsTooLargeFallsBackToTheSmallestSize) {
  Config config;
  config.ladder_loops = 8;  // 17-byte records: 4 in an 84-byte frame (80 bytes), 1 in a 44-byte one
  hal::host::HostBoard board(config.ladder_loops, 0x0013A20000001001ull, config.api_mode);
  board.radio.set_np(0x54);  // says 84
  board.ladder.SetIntactCount(config.ladder_loops);
  test::FakeGateway gateway(board.radio, &board.rtc);
  hal::Board hal_board = board.board();
  App app(config, hal_board);
  app.Init();
  app.Step();  // NP answered: 84
  LONGS_EQUAL(84, app.rf_payload_limit());
  board.radio.set_np(45);                              // the link now carries less than the firmware was told
  for (uint32_t t = 0; t < 3 * kDay; t += 3 * 3600) {  // wakes every 3 h: records fall due together
    board.rtc.Set(t);
    board.ladder.SetIntactCount(static_cast<uint8_t>(8 - t / kDay));
    board.radio.set_link_up(t >= kDay / 2);
    app.Step();
  }
  CHECK(app.stats().frames_too_large > 0);
  LONGS_EQUAL(protocol::kMinRfPayload, app.rf_payload_limit());
  LONGS_EQUAL(0, app.queue().size());
  LONGS_EQUAL(app.stats().records_queued, gateway.records.size());
}
