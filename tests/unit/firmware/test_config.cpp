#include <cstring>

#include "firmware/config.hpp"
#include "firmware/ladder.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw::firmware;

TEST_GROUP(Config){};

TEST(Config, DefaultsPass) {
  CHECK(CheckConfig(Config{}) == ConfigError::kOk);
}

TEST(Config, EachBrokenRuleIsNamed) {
  struct Case {
    void (*breaks)(Config&);
    ConfigError expected;
    const char* field;
  };
  const Case cases[] = {
      {[](Config& c) { c.ladder_loops = 0; }, ConfigError::kLadderLoops, "ladder_loops"},
      {[](Config& c) { c.ladder_loops = lw::protocol::kMaxLadderLoops + 1; }, ConfigError::kLadderLoops, "ladder_loops"},
      {[](Config& c) { c.loop_pitch_dmm = 0; }, ConfigError::kLoopPitch, "loop_pitch_dmm"},
      {[](Config& c) { c.loop_pitch_dmm = 1000; }, ConfigError::kThicknessRange, "loop_pitch_dmm"},
      {[](Config& c) { c.votes_per_poll = 0; }, ConfigError::kVotes, "votes_per_poll"},
      {[](Config& c) { c.votes_per_poll = kMaxVotes + 1; }, ConfigError::kVotes, "votes_per_poll"},
      {[](Config& c) { c.poll_period_s = 0; }, ConfigError::kPollPeriod, "poll_period_s"},
      {[](Config& c) { c.heartbeat_period_s = c.poll_period_s - 1; }, ConfigError::kHeartbeat, "heartbeat_period_s"},
      {[](Config& c) { c.backoff_min_s = 0; }, ConfigError::kBackoff, "backoff_min_s"},
      {[](Config& c) { c.backoff_min_s = c.backoff_max_s + 1; }, ConfigError::kBackoff, "backoff_min_s"},
      {[](Config& c) { c.watchdog_timeout_s = c.poll_period_s; }, ConfigError::kWatchdog, "watchdog_timeout_s"},
      {[](Config& c) { c.seq_reserve_block = 0; }, ConfigError::kSeqBlock, "seq_reserve_block"},
  };
  for (const Case& k : cases) {
    Config c;
    k.breaks(c);
    const ConfigError got = CheckConfig(c);
    CHECK(got == k.expected);
    STRCMP_CONTAINS(k.field, ConfigErrorText(got));
  }
}
