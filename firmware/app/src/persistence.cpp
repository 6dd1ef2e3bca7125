#include "firmware/persistence.hpp"

#include "protocol/sensor_payload.hpp"

namespace lw::firmware {
namespace {

constexpr uint32_t kMagic = 0x4C575354;  // "LWST"
constexpr size_t kRecordSize = 24;

void Put32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}
uint32_t Get32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) | (static_cast<uint32_t>(p[2]) << 16) |
         (static_cast<uint32_t>(p[3]) << 24);
}

// Layout: magic u32 | generation u32 | seq_reserved_until u32 | reported u8 | ladder u8 |
// dropped u16 | boots u32 | crc32-ish: two CRC-16s (data, and data with the generation) u32.
void Serialize(const PersistentState& s, uint8_t* out) {
  Put32(out, kMagic);
  Put32(out + 4, s.generation);
  Put32(out + 8, s.seq_reserved_until);
  out[12] = s.reported_loops;
  out[13] = s.ladder_loops;
  out[14] = static_cast<uint8_t>(s.dropped_total);
  out[15] = static_cast<uint8_t>(s.dropped_total >> 8);
  Put32(out + 16, s.boots);
  const uint16_t crc = protocol::Crc16Ccitt(out, 20);
  // The CRC is written last and its complement next to it: an erased (0xFF) or half-programmed
  // tail cannot pass both.
  out[20] = static_cast<uint8_t>(crc);
  out[21] = static_cast<uint8_t>(crc >> 8);
  out[22] = static_cast<uint8_t>(~crc);
  out[23] = static_cast<uint8_t>(~crc >> 8);
}

}  // namespace

bool StateStore::ReadSlot(size_t slot, PersistentState* out) {
  uint8_t buf[kRecordSize];
  if (!flash_.Read(first_page_ + slot, 0, buf, sizeof buf)) return false;
  if (Get32(buf) != kMagic) return false;
  const uint16_t crc = protocol::Crc16Ccitt(buf, 20);
  const uint16_t stored = static_cast<uint16_t>(buf[20] | (buf[21] << 8));
  const uint16_t inverted = static_cast<uint16_t>(buf[22] | (buf[23] << 8));
  if (crc != stored || static_cast<uint16_t>(~stored) != inverted) return false;
  out->generation = Get32(buf + 4);
  out->seq_reserved_until = Get32(buf + 8);
  out->reported_loops = buf[12];
  out->ladder_loops = buf[13];
  out->dropped_total = static_cast<uint16_t>(buf[14] | (buf[15] << 8));
  out->boots = Get32(buf + 16);
  return true;
}

bool StateStore::Load(PersistentState* out) {
  PersistentState a, b;
  const bool va = ReadSlot(0, &a);
  const bool vb = ReadSlot(1, &b);
  newest_slot_ = -1;
  if (va && (!vb || a.generation >= b.generation)) {
    *out = a;
    newest_slot_ = 0;
  } else if (vb) {
    *out = b;
    newest_slot_ = 1;
  }
  if (newest_slot_ < 0) return false;
  newest_generation_ = out->generation;
  return true;
}

bool StateStore::Save(PersistentState* state) {
  const size_t target = newest_slot_ == 0 ? 1 : 0;
  state->generation = newest_slot_ < 0 ? 1 : newest_generation_ + 1;
  uint8_t buf[kRecordSize];
  Serialize(*state, buf);
  if (!flash_.Erase(first_page_ + target)) return false;
  if (!flash_.Program(first_page_ + target, 0, buf, sizeof buf)) return false;
  newest_slot_ = static_cast<int>(target);
  newest_generation_ = state->generation;
  return true;
}

}  // namespace lw::firmware
