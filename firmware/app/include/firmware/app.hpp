#pragma once
/// The sensor application: one instance per board, all state inside (a simulator runs many).
///
/// Wake cycle (Step): drain the radio (acks that arrived), read the ladder (vote), update the
/// monotonic thickness, save what must survive a reset and only then queue a record (on change
/// or heartbeat), transmit due records (several per frame), drain the radio
/// again, kick the watchdog and arm the RTC alarm for the next poll or retransmission.
/// RunOnce = Step + sleep.
#include <cstdint>

#include "firmware/config.hpp"
#include "firmware/ladder.hpp"
#include "firmware/persistence.hpp"
#include "firmware/report_queue.hpp"
#include "hal/board.hpp"
#include "protocol/frame_decoder.hpp"

namespace lw::firmware {

struct AppStats {
  uint32_t wakes = 0;
  uint32_t records_queued = 0;
  uint32_t frames_sent = 0;
  uint32_t records_acked = 0;
  uint32_t tx_status_failures = 0;
  uint32_t flash_errors = 0;
  uint32_t ladder_faults = 0;
  uint32_t radio_queries = 0;     ///< AT NP / EE queries sent (boot, network join, refused frame)
  uint32_t frames_too_large = 0;  ///< 0x8B data_payload_too_large: frames fall back to the smallest size
  uint32_t np_below_minimum = 0;  ///< NP answers below protocol::kMinRfPayload (frames use the minimum)
};

class App {
 public:
  App(const Config& config, const hal::Board& board);

  /// Boot: starts the watchdog, restores persistent state (seq, last thickness), notes the reset
  /// cause. Call once after reset.
  void Init();
  /// One wake cycle; returns the RTC time of the next wake (also armed as the alarm).
  uint32_t Step();
  /// Step, then sleep until the alarm. What the MCU's main loop calls forever.
  void RunOnce();

  const AppStats& stats() const { return stats_; }
  const ReportQueue& queue() const { return queue_; }
  /// Last reported thickness lower bound in 0.1 mm (0xFFFF before the first valid sample).
  uint16_t reported_thickness_dmm() const;
  uint32_t next_seq() const { return next_seq_; }
  /// The RF payload every frame is sized to now (bytes): the radio's unfragmented limit from its
  /// NP and EE answers, protocol::kMinRfPayload until both came (or after a refused frame).
  size_t rf_payload_limit() const;
  /// Records dropped from the full queue over the board's life (saved in flash across resets);
  /// the payload header carries it, saturated at 65535.
  uint32_t dropped_total() const { return dropped_before_boot_ + queue_.dropped_total(); }

 private:
  void DrainRadio();
  void HandleFrame();
  /// Asks the radio for NP and EE (local AT queries); the answers arrive through DrainRadio.
  void QueryRadio();
  bool HandleRadioAnswer(const uint8_t* data, size_t len);
  void Sample(uint32_t now);
  void Enqueue(uint32_t now, const LadderSample& sample, uint16_t flags, bool heartbeat);
  void Transmit(uint32_t now);
  bool TakeSeq(uint32_t* seq);
  uint16_t DroppedTotal16() const;
  void Persist();
  uint32_t Backoff(uint8_t attempts);

  Config config_;
  hal::Board board_;
  protocol::FrameDecoder decoder_;
  ReportQueue queue_;
  StateStore store_;
  PersistentState state_;
  AppStats stats_;
  uint32_t next_seq_ = 0;
  uint8_t reported_loops_ = 0xFF;  // 0xFF: nothing reported yet
  uint16_t pending_flags_ = 0;     // boot/reset flags for the next record
  uint32_t last_queued_s_ = 0;
  bool have_queued_ = false;
  uint16_t last_fault_flags_ = 0;
  uint8_t frame_id_ = 0;
  uint8_t np_query_id_ = 0;  // frame ids of the outstanding AT queries (0: none)
  uint8_t ee_query_id_ = 0;
  int radio_np_ = -1;  // the radio's answers (-1: not known)
  int radio_ee_ = -1;
  bool force_min_payload_ = false;  // a frame was refused as too large: smallest size until the next join
  bool dirty_ = false;
  uint32_t durable_seq_limit_ = 0;    // seqs below this are covered by a saved reservation
  bool retry_record_ = false;         // a change record could not be queued: queue it next wake
  uint32_t dropped_before_boot_ = 0;  // dropped_total saved by earlier boots
  uint32_t jitter_state_;             // xorshift32 state for the retransmission jitter
};

}  // namespace lw::firmware
