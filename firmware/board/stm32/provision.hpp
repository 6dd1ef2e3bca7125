#pragma once
// The STM32 boards' provisioning (protocol/provision.hpp): the image's board marker and the
// record scripts/flash writes to the board's provisioning page, applied to the Config at boot.
#include "firmware/config.hpp"
#include "protocol/provision.hpp"

namespace lw::board {

/// The 8 marker bytes of `board_id`, for a `.lw_board` constant (the linker keeps it after the
/// vector table).
struct BoardMarker {
  uint8_t bytes[protocol::kBoardMarkerSize];
};
constexpr BoardMarker MakeBoardMarker(uint16_t board_id) {
  return {{'L', 'W', 'B', 'D', static_cast<uint8_t>(board_id), static_cast<uint8_t>(board_id >> 8), 0xFF, 0xFF}};
}

enum class ProvisionResult : uint8_t {
  kApplied,  ///< the record's sensor id, api mode and ladder size are in the Config
  kAbsent,   ///< no record: the Config keeps the image's defaults
  kRefused,  ///< a corrupt record or one for another board: the board must not talk
};

/// Reads the record at `address` (memory-mapped flash) into `c`.
inline ProvisionResult ApplyProvision(uint16_t board_id, uintptr_t address, firmware::Config& c) {
  protocol::Provision p;
  const protocol::ProvisionStatus s = protocol::DecodeProvision(reinterpret_cast<const uint8_t*>(address), &p);
  if (s == protocol::ProvisionStatus::kMissing) return ProvisionResult::kAbsent;
  if (s != protocol::ProvisionStatus::kOk || p.board != board_id) return ProvisionResult::kRefused;
  c.sensor_id = p.sensor_id;
  c.api_mode = static_cast<protocol::ApiMode>(p.api_mode);
  c.ladder_loops = p.ladder_loops;
  return ProvisionResult::kApplied;
}

/// The fault state of a board that must not talk: no radio traffic, the core asleep for good
/// (the watchdog is not started yet, so it stays there until the record is fixed and it is reset).
/// Not inlined: a debugger (openocd's `halt`, the QEMU test's monitor) tells by the program
/// counter that the board stopped here.
[[noreturn]] __attribute__((noinline)) inline void HaltUnprovisioned() {
  for (;;) __asm volatile("wfi");
}

}  // namespace lw::board
