#include "firmware/ladder.hpp"

namespace lw::firmware {

LadderSample DecodeLadder(const uint8_t raw[][protocol::kMaxBitmapBytes + 1], uint8_t votes, uint8_t loops) {
  LadderSample s;
  const uint8_t bytes = static_cast<uint8_t>((loops + 7u) / 8u);
  uint8_t good = 0;
  uint8_t counts[protocol::kMaxLadderLoops] = {};
  bool disagree = false;
  for (uint8_t v = 0; v < votes; ++v) {
    if (raw[v][bytes] != kLadderSignature) continue;  // stuck bus or a bad read
    // Bits beyond the ladder are tied low; any set means a corrupted read.
    if (loops % 8 && (raw[v][bytes - 1] >> (loops % 8)) != 0) continue;
    ++good;
    for (uint8_t i = 0; i < loops; ++i) {
      if (raw[v][i / 8] & (1u << (i % 8))) ++counts[i];
    }
  }
  if (good == 0) {
    s.flags = protocol::kFlagSpiStuck;
    return s;
  }
  for (uint8_t i = 0; i < loops; ++i) {
    if (counts[i] != 0 && counts[i] != good) disagree = true;
    if (2u * counts[i] > good) s.intact[i / 8] = static_cast<uint8_t>(s.intact[i / 8] | (1u << (i % 8)));
  }
  s.valid = true;
  if (good < votes) s.flags |= protocol::kFlagSpiStuck;  // some reads failed the signature
  if (disagree) s.flags |= protocol::kFlagFlicker;
  // Wear breaks loops from the face (highest index) down: thickness = highest intact loop + 1.
  int highest = -1;
  for (int i = loops - 1; i >= 0; --i) {
    if (s.intact[i / 8] & (1u << (i % 8))) {
      highest = i;
      break;
    }
  }
  s.loops_intact = static_cast<uint8_t>(highest + 1);
  if (highest < 0) s.flags |= protocol::kFlagAllOpen;
  for (int i = 0; i < highest; ++i) {
    if (!(s.intact[i / 8] & (1u << (i % 8)))) {
      s.flags |= protocol::kFlagNonContiguous;  // a loop below the face is open: crack, not wear
      break;
    }
  }
  return s;
}

LadderSample ReadLadder(hal::Spi& spi, hal::DigitalOut& power, uint8_t votes, uint8_t loops) {
  uint8_t raw[kMaxVotes][protocol::kMaxBitmapBytes + 1] = {};
  if (votes > kMaxVotes) votes = kMaxVotes;
  if (loops > protocol::kMaxLadderLoops) loops = static_cast<uint8_t>(protocol::kMaxLadderLoops);
  const size_t len = (loops + 7u) / 8u + 1u;
  power.Set(true);
  for (uint8_t v = 0; v < votes; ++v) {
    if (!spi.Transfer(nullptr, raw[v], len)) {
      for (size_t i = 0; i < len; ++i) raw[v][i] = 0;  // fails the signature check
    }
  }
  power.Set(false);
  return DecodeLadder(raw, votes, loops);
}

}  // namespace lw::firmware
