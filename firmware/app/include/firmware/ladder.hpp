#pragma once
/// Reading the wear ladder: several SPI reads, a majority vote per loop, the loops contiguous from
/// the wear face, and fault flags. Pure decoding is split from I/O (ReadLadder / DecodeLadder).
#include <cstdint>

#include "hal/gpio.hpp"
#include "hal/spi.hpp"
#include "protocol/sensor_payload.hpp"

namespace lw::firmware {

/// Byte after the ladder's data bytes: the inputs of the chain's last shift register are
/// hard-wired to this pattern, so a stuck bus (all 0x00 / 0xFF) is told apart from a worn ladder.
inline constexpr uint8_t kLadderSignature = 0xA5;
inline constexpr uint8_t kMaxVotes = 9;

struct LadderSample {
  uint8_t intact[protocol::kMaxBitmapBytes] = {};  ///< voted bitmap, bit i = loop i intact
  uint8_t loops_intact = 0;                        ///< highest intact loop + 1: loops below the broken run at the wear face
  uint16_t flags = 0;  ///< protocol::RecordFlag bits: kFlagNonContiguous, kFlagAllOpen, kFlagFlicker, kFlagSpiStuck
  bool valid = false;  ///< false when the bus was stuck or failed: no thickness from this sample
};

/// Votes over `votes` raw reads (each `(loops+7)/8 + 1` bytes including the signature byte).
LadderSample DecodeLadder(const uint8_t raw[][protocol::kMaxBitmapBytes + 1], uint8_t votes, uint8_t loops);

/// Powers the ladder, reads it `votes` times over SPI, powers it off, and decodes. Blocking.
LadderSample ReadLadder(hal::Spi& spi, hal::DigitalOut& power, uint8_t votes, uint8_t loops);

}  // namespace lw::firmware
