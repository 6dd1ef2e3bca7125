#include "firmware/config.hpp"

#include "firmware/ladder.hpp"

namespace lw::firmware {

ConfigError CheckConfig(const Config& c) {
  if (c.ladder_loops == 0 || c.ladder_loops > protocol::kMaxLadderLoops) return ConfigError::kLadderLoops;
  if (c.loop_pitch_dmm == 0) return ConfigError::kLoopPitch;
  if (static_cast<uint32_t>(c.base_offset_dmm) + static_cast<uint32_t>(c.ladder_loops) * c.loop_pitch_dmm > 0xFFFFu) {
    return ConfigError::kThicknessRange;
  }
  if (c.votes_per_poll == 0 || c.votes_per_poll > kMaxVotes) return ConfigError::kVotes;
  if (c.poll_period_s == 0) return ConfigError::kPollPeriod;
  if (c.heartbeat_period_s < c.poll_period_s) return ConfigError::kHeartbeat;
  if (c.backoff_min_s == 0 || c.backoff_min_s > c.backoff_max_s) return ConfigError::kBackoff;
  if (c.watchdog_timeout_s <= c.poll_period_s) return ConfigError::kWatchdog;
  if (c.seq_reserve_block == 0) return ConfigError::kSeqBlock;
  return ConfigError::kOk;
}

const char* ConfigErrorText(ConfigError error) {
  switch (error) {
    case ConfigError::kOk:
      return "ok";
    case ConfigError::kLadderLoops:
      return "ladder_loops must be 1..128";
    case ConfigError::kLoopPitch:
      return "loop_pitch_dmm must be at least 1";
    case ConfigError::kThicknessRange:
      return "base_offset_dmm + ladder_loops x loop_pitch_dmm must not exceed 65535";
    case ConfigError::kVotes:
      return "votes_per_poll must be 1..9";
    case ConfigError::kPollPeriod:
      return "poll_period_s must be at least 1";
    case ConfigError::kHeartbeat:
      return "heartbeat_period_s must be at least poll_period_s";
    case ConfigError::kBackoff:
      return "backoff_min_s must be 1..backoff_max_s";
    case ConfigError::kWatchdog:
      return "watchdog_timeout_s must be longer than poll_period_s (the longest sleep)";
    case ConfigError::kSeqBlock:
      return "seq_reserve_block must be at least 1";
  }
  return "unknown config error";
}

}  // namespace lw::firmware
