#pragma once
/// The virtual site of `linerwatch-sim run`, without I/O: one board per sensor running the real
/// firmware (lw::firmware::App on the host HAL) whose ladder breaks as the truth model says, the
/// virtual XBee network, and the coordinator radio whose serial side speaks XBee API frames
/// (lw::protocol): 0x90 Receive Packets out for every packet that arrives, 0x10 Transmit Requests
/// in (the gateway's acks), each answered with a 0x8B Transmit Status. Times are virtual Unix
/// seconds; the caller decides how fast they pass and carries the serial bytes.
#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "core/bundle.hpp"
#include "firmware/config.hpp"
#include "protocol/frame_decoder.hpp"
#include "protocol/xbee_api.hpp"
#include "sim/network.hpp"
#include "sim/truth.hpp"

namespace lw::sim {

/// One reading a virtual sensor produced (queued in its firmware): what must end up stored once.
struct LedgerEntry {
  std::string sensor_id;
  uint32_t seq = 0;
  int64_t time_s = 0;  ///< virtual Unix seconds of the sample
  double thickness_mm = 0;
};

struct FleetOptions {
  NetworkParams network;
  protocol::ApiMode serial_mode = protocol::ApiMode::kUnescaped;  ///< coordinator AP setting (1)
  /// Firmware tunables for every board (sensor_id, ladder and api_mode are set per board).
  firmware::Config firmware;
  /// Boards boot spread over this many seconds after installed_at (0: all at once).
  double boot_spread_s = 0;
  /// What every radio (the boards' and the coordinator) answers to AT NP and AT EE. A radio
  /// refuses a transmission above protocol::RfPayloadLimit(np, ee) with 0x74
  /// data_payload_too_large, so an oversize frame from either side is lost, never fragmented.
  uint8_t radio_np = protocol::kNpFragmentedMaximum;
  uint8_t radio_ee = 0;
};

struct FleetCounters {
  uint64_t readings_produced = 0;  ///< records the boards queued
  uint64_t readings_acked = 0;     ///< records the boards saw acked (released from their queues)
  uint64_t frames_to_gateway = 0;  ///< 0x90 frames written to the serial side
  uint64_t acks_from_gateway = 0;  ///< 0x10 frames read from the serial side
  uint64_t acks_lost = 0;          ///< of those, lost on the air
  uint64_t serial_bad_frames = 0;  ///< serial input that was not a 0x10 to a known board
  uint64_t at_queries = 0;         ///< local AT commands from the gateway (answered)
  uint64_t acks_too_large = 0;     ///< 0x10 from the gateway above the radios' payload limit (refused)
  uint64_t frames_too_large = 0;   ///< board transmissions refused as too large by their radios
};

/// The 64-bit radio address of a sensor: crusher.json's `address`, else 0013A200 followed by the
/// id's decimal digits read as hex (1001 -> 0013A20000001001) when it has at most 8 digits.
uint64_t SensorAddress(const core::SensorInfo& sensor);
/// The 32-bit id the firmware reports; throws std::invalid_argument unless the id is a whole
/// number below 2^32.
uint32_t FirmwareSensorId(const std::string& id);

class Fleet {
 public:
  /// `truth` must outlive the fleet. Throws std::invalid_argument on a sensor the firmware
  /// cannot be provisioned for (its id, or a firmware Config that fails CheckConfig).
  Fleet(const core::CrusherConfig& crusher, const TruthModel& truth, const FleetOptions& options);
  ~Fleet();
  Fleet(const Fleet&) = delete;
  Fleet& operator=(const Fleet&) = delete;

  int64_t start_s() const { return start_s_; }
  double now() const { return now_; }
  /// Time of the next board wake or packet arrival (`sample`: as in AdvanceTo).
  double NextEventTime(bool sample = true) const;
  /// Runs every event up to `t` in time order. When `sample` is false (the campaign is over),
  /// boards with nothing left to send are no longer woken.
  void AdvanceTo(double t, bool sample = true);

  /// Serial side of the coordinator: API frames for the gateway, and the gateway's frames.
  std::vector<uint8_t> TakeSerialOutput();
  void OnSerialInput(const uint8_t* data, size_t len);
  /// Records written to the serial side that the gateway has not acked yet.
  size_t unacked_serial_records() const { return unacked_.size(); }
  /// Forgets them (the gateway did not answer: it is away or its spool is full).
  void ForgetUnacked() { unacked_.clear(); }

  /// Records still queued in the boards (not yet acked to them).
  size_t queued_records() const;
  size_t in_flight() const { return network_.in_flight(); }
  const std::vector<LedgerEntry>& ledger() const { return ledger_; }
  FleetCounters counters() const;
  const NetworkCounters& network_counters() const { return network_.counters(); }
  size_t board_count() const { return boards_.size(); }

 private:
  struct Board;
  void WakeBoard(Board& b, uint32_t at);
  void Arrive(const Packet& p);
  void AnswerAt(const protocol::AtCommand& cmd);
  void OnGatewayTransmit(const protocol::TransmitRequest& req);

  const TruthModel& truth_;
  FleetOptions options_;
  int64_t start_s_ = 0;
  double now_ = 0;
  VirtualNetwork network_;
  std::vector<std::unique_ptr<Board>> boards_;
  std::map<uint64_t, Board*> by_address_;
  std::vector<uint8_t> serial_out_;
  protocol::FrameDecoder serial_in_;
  std::set<std::pair<uint32_t, uint32_t>> unacked_;  // (sensor id, seq) written, not yet acked
  std::vector<LedgerEntry> ledger_;
  FleetCounters counters_;
  uint8_t coordinator_frame_id_ = 0;
};

}  // namespace lw::sim
