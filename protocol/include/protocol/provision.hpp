#pragma once
/// The provisioning record of a sensor board and the board table, shared by the firmware images
/// (which mark themselves with their board's id) and the host tool that checks an image and
/// builds the record scripts/flash writes (linerwatch-provision; docs/firmware.md, *Flashing and
/// provisioning*). Freestanding: no heap, no exceptions.
///
/// Record, 16 bytes little-endian at the board's `provision_address` (one erase page of its own):
///   0  u32 magic 'LWPR'     4 u8 version (1)      5 u8 api_mode (1 or 2, the radio's AP)
///   6  u16 board id         8 u32 sensor_id       12 u8 ladder_loops   13 u8 0xFF
///   14 u16 CRC-16/CCITT (Crc16Ccitt) of bytes 0..13
/// Image marker: the 8 bytes 'LWBD', u16 board id, u16 0xFFFF, linked right after the vector
/// table (section .lw_board), so a host tool finds the board an image was built for in its .bin.
#include <cstddef>
#include <cstdint>

#include "protocol/sensor_payload.hpp"

namespace lw::protocol {

inline constexpr uint32_t kProvisionMagic = 0x5250574Cu;  // "LWPR" in memory order
inline constexpr uint8_t kProvisionVersion = 1;
inline constexpr size_t kProvisionSize = 16;
inline constexpr uint8_t kBoardMarkerTag[4] = {'L', 'W', 'B', 'D'};
inline constexpr size_t kBoardMarkerSize = 8;

/// A sensor board linerwatch builds an image for.
struct BoardInfo {
  const char* name;            ///< as scripts/flash --board spells it
  uint16_t id;                 ///< in the image marker and the record
  uint16_t chip_id;            ///< the bootloader's Get ID answer (ST AN2606)
  uint32_t flash_base;         ///< where the image starts
  uint32_t image_max;          ///< bytes the image may take from flash_base (up to the record)
  uint32_t provision_address;  ///< the record's page
  const char* part;            ///< the MCU, for messages
};

inline constexpr BoardInfo kBoards[] = {
    // STM32F405 (QEMU netduinoplus2): image in sectors 0-1 (the 32 KiB budget), state in 2-3,
    // the record in sector 4 (64 KiB, 0x08010000).
    {"netduinoplus2", 0x0405, 0x413, 0x08000000u, 32u * 1024u, 0x08010000u, "STM32F405"},
    // STM32L431 (production): image below page 125, the record in page 125, state in 126-127.
    {"l431", 0x0431, 0x435, 0x08000000u, 250u * 1024u, 0x0803E800u, "STM32L431"},
};

inline const BoardInfo* FindBoardById(uint16_t id) {
  for (const BoardInfo& b : kBoards)
    if (b.id == id) return &b;
  return nullptr;
}

/// What a record provisions.
struct Provision {
  uint16_t board = 0;
  uint32_t sensor_id = 0;
  uint8_t api_mode = 2;
  uint8_t ladder_loops = 100;
};

inline void EncodeProvision(const Provision& p, uint8_t out[kProvisionSize]) {
  const auto put = [&](size_t at, uint32_t v, size_t n) {
    for (size_t i = 0; i < n; ++i) out[at + i] = static_cast<uint8_t>(v >> (8 * i));
  };
  put(0, kProvisionMagic, 4);
  out[4] = kProvisionVersion;
  out[5] = p.api_mode;
  put(6, p.board, 2);
  put(8, p.sensor_id, 4);
  out[12] = p.ladder_loops;
  out[13] = 0xFF;
  put(14, Crc16Ccitt(out, 14), 2);
}

enum class ProvisionStatus : uint8_t { kOk, kMissing, kBadCrc, kBadVersion, kBadValue };

/// Decodes a record (kMissing: no magic, e.g. erased flash reading 0xFF or 0x00).
inline ProvisionStatus DecodeProvision(const uint8_t in[kProvisionSize], Provision* p) {
  const auto get = [&](size_t at, size_t n) {
    uint32_t v = 0;
    for (size_t i = 0; i < n; ++i) v |= static_cast<uint32_t>(in[at + i]) << (8 * i);
    return v;
  };
  if (get(0, 4) != kProvisionMagic) return ProvisionStatus::kMissing;
  if (get(14, 2) != Crc16Ccitt(in, 14)) return ProvisionStatus::kBadCrc;
  if (in[4] != kProvisionVersion) return ProvisionStatus::kBadVersion;
  p->api_mode = in[5];
  p->board = static_cast<uint16_t>(get(6, 2));
  p->sensor_id = get(8, 4);
  p->ladder_loops = in[12];
  if ((p->api_mode != 1 && p->api_mode != 2) || p->ladder_loops == 0 || p->ladder_loops > kMaxLadderLoops || p->sensor_id == 0)
    return ProvisionStatus::kBadValue;
  return ProvisionStatus::kOk;
}

}  // namespace lw::protocol
