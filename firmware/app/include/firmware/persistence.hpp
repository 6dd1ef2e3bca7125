#pragma once
/// Power-loss-safe persistent state: two flash slots (one page each), each holding a record with a
/// generation counter and a CRC. A save erases and programs the slot NOT holding the newest valid
/// record, so at any instant of a power loss one complete, CRC-valid record survives: either the
/// old one (the save did not finish) or the new one. Load picks the valid record with the highest
/// generation.
#include <cstdint>

#include "hal/flash.hpp"

namespace lw::firmware {

struct PersistentState {
  uint32_t generation = 0;
  uint32_t seq_reserved_until = 0;  ///< seqs below this may have been used: resume here after a reset
  uint8_t reported_loops = 0xFF;    ///< last reported loops_intact (0xFF: none yet)
  uint8_t ladder_loops = 0;
  uint16_t dropped_total = 0;
  uint32_t boots = 0;
};

class StateStore {
 public:
  StateStore(hal::FlashPages& flash, size_t first_page) : flash_(flash), first_page_(first_page) {}
  /// Reads both slots; returns false when neither holds a valid record (fresh board).
  bool Load(PersistentState* out);
  /// Writes `state` with generation = newest + 1 into the older slot. Returns false on a flash error.
  bool Save(PersistentState* state);

 private:
  bool ReadSlot(size_t slot, PersistentState* out);
  hal::FlashPages& flash_;
  size_t first_page_;
  int newest_slot_ = -1;
  uint32_t newest_generation_ = 0;
};

}  // namespace lw::firmware
