// lw_bench_firmware_powercut: the firmware power-cut campaign of docs/reliability.md. The real
// firmware App runs on the host HAL through whole liner lives (a ladder worn from 100 loops to 3,
// one step every 1 to 6 virtual hours, the default tunables) and the board loses power at a
// random byte of its flash erases and programs, the interrupted operation torn as on real NOR
// flash (HostFlash::TearAtPowerLoss), over and over, until --cuts cuts happened. After each cut
// the board stays off for a while and boots again. Checked at every boot and at the end of each
// liner:
//   - the flash holds a valid state once any save has completed (never boots blank or corrupt),
//     the one of the interrupted save or the one before it: generation, seq reservation, boot
//     and drop counts never go back, the ladder size is the provisioned one, the saved thickness
//     never rises;
//   - the seq the board resumes at is above every seq the gateway ever received from it, and the
//     gateway never saw one seq carry two different samples (a reused seq would be dropped by the
//     real gateway as a duplicate: a lost reading);
//   - thickness by seq never rises at the gateway, and every worn step reached it.
// Exit status 0 when every check held, 1 otherwise.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>

#include "fakes/fake_gateway.hpp"
#include "firmware/app.hpp"
#include "firmware/persistence.hpp"
#include "hal/host/host_board.hpp"

namespace {

using lw::firmware::App;
using lw::firmware::Config;
using lw::firmware::PersistentState;

constexpr size_t kPageSize = 256;
constexpr size_t kSaveBytes = kPageSize + 24;  // erase one page, program one 24-byte record
constexpr uint8_t kLastLoops = 3;

struct Counts {
  long cuts = 0, cuts_in_erase = 0, cuts_in_program = 0, cuts_during_boot = 0, boots = 0, liners = 0;
  unsigned long long wakes = 0, records = 0;
  long blank_boots = 0;         // a save had completed, yet no valid state
  long state_went_back = 0;     // generation, seq reservation, boots or drops lower than before
  long state_inconsistent = 0;  // ladder size not the provisioned one, or the saved thickness rose
  long seq_reuses = 0;          // resumed at or below a seq the gateway has, or a seq with two samples
  long thickness_rises = 0;     // at the gateway, by seq
  long steps_lost = 0;          // thickness values a powered wake read that never reached the gateway
  long steps = 0;               // thickness values read by wakes that kept their power
  std::string first_failure;
  bool failed() const {
    return blank_boots || state_went_back || state_inconsistent || seq_reuses || thickness_rises || steps_lost;
  }
};

class Liner {
 public:
  Liner(uint32_t sensor_id, std::mt19937& rng, Counts& n, bool tear, long cuts_wanted)
      : cuts_wanted_(cuts_wanted),
        rng_(rng),
        n_(n),
        board_(100, 0x0013A20000000000ull | sensor_id, lw::protocol::ApiMode::kEscaped, kPageSize, 2),
        gateway_(board_.radio, &board_.rtc) {
    config_.sensor_id = sensor_id;
    if (tear) board_.flash.TearAtPowerLoss(static_cast<uint32_t>(rng_()));
    // The wear ahead: one step every 1 to 6 hours from 100 loops down to kLastLoops.
    uint32_t t = 3600;
    for (int loops = 99; loops >= kLastLoops; --loops) {
      t += 3600 + static_cast<uint32_t>(rng_() % (5 * 3600));
      step_at_[loops] = t;
    }
    board_.ladder.SetIntactCount(100);
    Boot(lw::hal::ResetCause::kPowerOn);
  }

  /// Runs the liner's whole life, cutting power until the campaign has its cuts.
  void Run() {
    while (Loops(board_.rtc.now()) > kLastLoops && board_.rtc.now() < 400u * 86400u) {
      if (n_.cuts < cuts_wanted_ && !armed_ && rng_() % 4 == 0) Arm();
      Wake();
      if (board_.flash.power_lost()) PowerCut();
    }
    // Power stays on now: a few more polls see the last step, and the last records drain.
    armed_ = false;
    board_.flash.LosePowerAfter(-1);
    for (int i = 0; i < 96 && (i < 8 || app_->queue().size() > 0); ++i) Wake();
    Finish();
  }

 private:
  uint8_t Loops(uint32_t t) const {
    uint8_t loops = 100;
    for (const auto& [l, at] : step_at_) {
      if (t >= at) loops = std::min<uint8_t>(loops, static_cast<uint8_t>(l));
    }
    return loops;
  }

  void Fail(long* counter, const std::string& what) {
    ++*counter;
    if (n_.first_failure.empty()) n_.first_failure = "sensor " + std::to_string(config_.sensor_id) + ": " + what;
  }

  // The state in flash as the next boot will load it (false: none valid).
  bool Probe(PersistentState* out) {
    lw::firmware::StateStore store(board_.flash, 0);
    return store.Load(out);
  }

  // Power will fail at a random byte of the next one or two saves; the state saved by then is the
  // oldest the next boot may find.
  void Arm() {
    PersistentState now;
    if (Probe(&now)) {
      CheckAgainstLast(now);
      last_ = now;
      saved_once_ = true;
    }
    armed_ = true;
    // Half the cuts fall in the 24 programmed bytes (a torn record), the rest anywhere.
    const long save = static_cast<long>(rng_() % 2) * static_cast<long>(kSaveBytes);
    arm_offset_ = rng_() % 2 ? save + static_cast<long>(kPageSize + rng_() % (kSaveBytes - kPageSize))
                             : static_cast<long>(rng_() % (2 * kSaveBytes));
    board_.flash.LosePowerAfter(arm_offset_);
  }

  // A wake that ends with power still on has queued and sent (the link is up) any new thickness
  // it read: that value must reach the gateway. Steps worn while the board was off, or read in a
  // wake that lost power before its save, were never produced (no seq): not counted.
  void Wake() {
    const uint8_t loops = Loops(board_.rtc.now());
    board_.ladder.SetIntactCount(loops);
    app_->RunOnce();
    ++n_.wakes;
    if (!board_.flash.power_lost()) produced_.insert(loops);
  }

  void Boot(lw::hal::ResetCause cause) {
    PersistentState before;
    const bool had = Probe(&before);
    if (saved_once_ && !had) Fail(&n_.blank_boots, "no valid state in flash after a cut");
    if (had) {
      CheckAgainstLast(before);
      last_ = before;
      saved_once_ = true;
    }
    board_.power.set_reset_cause(cause);
    hal_board_ = std::make_unique<lw::hal::Board>(board_.board());
    app_ = std::make_unique<App>(config_, *hal_board_);
    // Sometimes power fails again during the boot's own save.
    if (!armed_ && n_.cuts < cuts_wanted_ && rng_() % 4 == 0) Arm();
    app_->Init();
    ++n_.boots;
    if (board_.flash.power_lost()) {
      ++n_.cuts_during_boot;
      PowerCut();
      return;
    }
    // The board resumes above every seq that ever left it.
    if (!gateway_.records.empty() && app_->next_seq() <= gateway_.records.rbegin()->first) {
      Fail(&n_.seq_reuses, "resumed at seq " + std::to_string(app_->next_seq()) + " but the gateway has seq " +
                               std::to_string(gateway_.records.rbegin()->first));
    }
    PersistentState after;
    if (Probe(&after)) {
      CheckAgainstLast(after);
      last_ = after;
      saved_once_ = true;
    }
  }

  void CheckAgainstLast(const PersistentState& s) {
    if (s.ladder_loops != 100) Fail(&n_.state_inconsistent, "saved ladder size " + std::to_string(s.ladder_loops));
    if (!saved_once_) return;
    if (s.generation < last_.generation || s.seq_reserved_until < last_.seq_reserved_until || s.boots < last_.boots ||
        s.dropped_total < last_.dropped_total) {
      Fail(&n_.state_went_back, "state went back: generation " + std::to_string(last_.generation) + " -> " +
                                    std::to_string(s.generation) + ", seq reserved " + std::to_string(last_.seq_reserved_until) +
                                    " -> " + std::to_string(s.seq_reserved_until));
    }
    if (last_.reported_loops != 0xFF && s.reported_loops != 0xFF && s.reported_loops > last_.reported_loops) {
      Fail(&n_.state_inconsistent, "saved thickness rose from " + std::to_string(last_.reported_loops) + " to " +
                                       std::to_string(s.reported_loops) + " loops");
    }
  }

  void PowerCut() {
    ++n_.cuts;
    const long offset = arm_offset_ % static_cast<long>(kSaveBytes);
    if (offset < static_cast<long>(kPageSize))
      ++n_.cuts_in_erase;
    else
      ++n_.cuts_in_program;
    armed_ = false;
    board_.flash.PowerRestored();
    board_.rtc.Advance(static_cast<uint32_t>(rng_() % (4 * 3600)));  // off for up to 4 h
    Boot(lw::hal::ResetCause::kBrownout);
  }

  void Finish() {
    ++n_.liners;
    n_.records += gateway_.records.size();
    if (gateway_.seq_conflicts) Fail(&n_.seq_reuses, std::to_string(gateway_.seq_conflicts) + " seqs carried two samples");
    uint8_t prev = 255;
    std::set<uint8_t> seen;
    for (const auto& [seq, r] : gateway_.records) {
      if (r.loops_intact > prev) {
        Fail(&n_.thickness_rises, "seq " + std::to_string(seq) + " reports " + std::to_string(r.loops_intact) + " loops after " +
                                      std::to_string(prev));
      }
      prev = r.loops_intact;
      seen.insert(r.loops_intact);
    }
    for (const uint8_t v : produced_) {
      if (!seen.count(v)) Fail(&n_.steps_lost, "the step to " + std::to_string(v) + " loops never arrived");
    }
    n_.steps += static_cast<long>(produced_.size());
  }

  long cuts_wanted_;
  std::mt19937& rng_;
  Counts& n_;
  Config config_;
  lw::hal::host::HostBoard board_;
  lw::test::FakeGateway gateway_;
  std::unique_ptr<lw::hal::Board> hal_board_;
  std::unique_ptr<App> app_;
  std::map<int, uint32_t> step_at_;
  std::set<uint8_t> produced_;  // thickness values read in wakes that kept their power
  PersistentState last_;
  bool saved_once_ = false;
  bool armed_ = false;
  long arm_offset_ = 0;
};

int Usage(const char* why) {
  std::fprintf(stderr,
               "lw_bench_firmware_powercut: %s\nUsage: lw_bench_firmware_powercut [--cuts N (10000)] [--seed S] [--no-tear]\n",
               why);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  long cuts = 10000;
  unsigned seed = std::random_device{}();
  bool tear = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if ((a == "--cuts" || a == "--seed") && i + 1 < argc) {
      char* end = nullptr;
      const long v = std::strtol(argv[++i], &end, 10);
      if (!end || *end || v < 0) return Usage(("bad value for " + a + ": " + argv[i]).c_str());
      if (a == "--cuts")
        cuts = v;
      else
        seed = static_cast<unsigned>(v);
    } else if (a == "--no-tear") {
      tear = false;
    } else if (a == "--help" || a == "-h") {
      std::printf("lw_bench_firmware_powercut [--cuts N] [--seed S] [--no-tear]: see docs/reliability.md\n");
      return 0;
    } else {
      return Usage(("unknown argument " + a).c_str());
    }
  }
  std::mt19937 rng(seed);
  Counts n;
  for (uint32_t id = 1001; n.cuts < cuts; ++id) {
    Liner liner(id, rng, n, tear, cuts);
    liner.Run();
    if (n.liners % 10 == 0) {
      std::fprintf(stderr, "powercut: %ld liners, %ld cuts, %ld boots, %llu records at the gateway\n", n.liners, n.cuts, n.boots,
                   n.records);
    }
  }
  std::printf(
      "powercut: %ld cuts (%ld in an erase, %ld in a program, %ld of them during a boot's own save; %s), %ld boots, "
      "%ld liners worn 100 -> %d loops, %llu wakes, %llu records at the gateway; blank boots %ld, state went back %ld, "
      "inconsistent state %ld, seq reuses %ld, thickness rises %ld, steps lost %ld of %ld; seed %u\n",
      n.cuts, n.cuts_in_erase, n.cuts_in_program, n.cuts_during_boot, tear ? "torn" : "clean cuts", n.boots, n.liners, kLastLoops,
      n.wakes, n.records, n.blank_boots, n.state_went_back, n.state_inconsistent, n.seq_reuses, n.thickness_rises, n.steps_lost,
      n.steps, seed);
  if (n.failed()) std::printf("powercut: FAILED: %s\n", n.first_failure.c_str());
  return n.failed() ? 1 : 0;
}
