#pragma once
/// Every tunable of the sensor firmware, in one place. Units are in the names.
#include <cstdint>

#include "protocol/sensor_payload.hpp"
#include "protocol/xbee_api.hpp"

namespace lw::firmware {

struct Config {
  uint32_t sensor_id = 1001;                                 ///< reported in every payload; provisioned per board
  uint8_t ladder_loops = 100;                                ///< loops on the ladder (<= protocol::kMaxLadderLoops)
  uint16_t loop_pitch_dmm = 10;                              ///< distance between loops, 0.1 mm (1 mm ladder)
  uint16_t base_offset_dmm = 0;                              ///< liner thickness below loop 0's lower bound, 0.1 mm
  uint8_t votes_per_poll = 5;                                ///< ladder reads per poll, majority vote per loop
  uint32_t poll_period_s = 900;                              ///< wake and read the ladder every 15 min
  uint32_t heartbeat_period_s = 6 * 3600;                    ///< send a record at least this often without change
  uint32_t backoff_min_s = 900;                              ///< first retransmission delay
  uint32_t backoff_max_s = 6 * 3600;                         ///< retransmission delay cap
  uint16_t low_battery_mv = 3300;                            ///< below: kFlagLowBattery
  uint32_t watchdog_timeout_s = 2 * 900 + 60;                ///< longer than the longest sleep
  uint32_t seq_reserve_block = 64;                           ///< seqs reserved in flash per write (never reused)
  protocol::ApiMode api_mode = protocol::ApiMode::kEscaped;  ///< must match the radio's AP
  uint64_t coordinator_address64 = protocol::kCoordinatorAddress64;
};

/// Capacity of the unacknowledged-record queue (compile time: it sizes a static buffer). Sized for
/// a 20-day radio outage without losing a thickness step (docs/firmware.md, "Queue"): the
/// fastest-wearing row of a campaign (90 mm in 95 days, accelerating to ~1.33 mm/day at the end)
/// makes at most 27 one-millimetre steps in any 20 days; with two new-fault records and the
/// newest heartbeats (liveness, battery) that is 32. Heartbeats go first when it is full. (A reset
/// empties the queue: it is RAM; its boot record starts a new one.)
inline constexpr uint16_t kQueueCapacity = 32;

/// The first rule a Config breaks (kOk: none). An App must only be built from a Config that
/// passes; provisioning tools and the simulator check with CheckConfig and print ConfigErrorText.
enum class ConfigError : uint8_t {
  kOk = 0,
  kLadderLoops,     ///< ladder_loops outside 1..protocol::kMaxLadderLoops
  kLoopPitch,       ///< loop_pitch_dmm is 0
  kThicknessRange,  ///< base_offset_dmm + ladder_loops x loop_pitch_dmm exceeds 65535
  kVotes,           ///< votes_per_poll outside 1..kMaxVotes (9)
  kPollPeriod,      ///< poll_period_s is 0
  kHeartbeat,       ///< heartbeat_period_s shorter than poll_period_s
  kBackoff,         ///< backoff_min_s is 0 or above backoff_max_s
  kWatchdog,        ///< watchdog_timeout_s not longer than poll_period_s (the longest sleep)
  kSeqBlock,        ///< seq_reserve_block is 0
};

/// Checks every field of `config`; pure, no I/O. Returns the first broken rule.
ConfigError CheckConfig(const Config& config);
/// One line naming the field and its rule, e.g. "votes_per_poll must be 1..9". Never null.
const char* ConfigErrorText(ConfigError error);

}  // namespace lw::firmware
