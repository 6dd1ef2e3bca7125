#pragma once
/// State pages for the STM32 port.
/// - L4PageFlash: two 2 KiB pages of the STM32L4's own flash. The L4 programs 64-bit double-words
///   with ECC: a double-word can be programmed once after an erase, so Program() pads the range to
///   whole double-words with 0xFF, skips double-words it would not change, and refuses (false) to
///   clear bits of a double-word already programmed. The app's state slots (docs/firmware.md,
///   Persistence) write each slot once per erase, which is what this allows.
/// - F4SectorFlash: two sectors of the STM32F4 (16 KiB each: the smallest the F405 has), byte
///   programming (PSIZE x8, any supply voltage), no ECC. Not used under QEMU: its flash is a ROM
///   and the flash interface is not modelled.
/// - RamFlash: two RAM pages standing in for flash where there is none to program (QEMU).
/// Flash operations poll BSY with a bounded wait and report errors through the return value. The
/// flash drivers take their register and flash-array accesses through `Io`, so a host test runs
/// them against a model of the flash interface (tests/unit/hal/test_stm32_flash.cpp).
#include <cstddef>
#include <cstdint>

#include "hal/flash.hpp"
#include "hal/stm32/mmio.hpp"
#include "hal/stm32/regs.hpp"

namespace lw::hal::stm32 {

template <size_t kPageBytes, size_t kPageCount>
class RamFlash final : public FlashPages {
 private:
  size_t DoPageSize() override { return kPageBytes; }
  size_t DoPageCount() override { return kPageCount; }
  bool DoErase(size_t page) override {
    if (page >= kPageCount) return false;
    for (auto& b : pages_[page]) b = 0xFF;
    return true;
  }
  bool DoProgram(size_t page, size_t offset, const uint8_t* data, size_t len) override {
    if (page >= kPageCount || offset > kPageBytes || len > kPageBytes - offset) return false;
    for (size_t i = 0; i < len; ++i) pages_[page][offset + i] &= data[i];
    return true;
  }
  bool DoRead(size_t page, size_t offset, uint8_t* data, size_t len) override {
    if (page >= kPageCount || offset > kPageBytes || len > kPageBytes - offset) return false;
    for (size_t i = 0; i < len; ++i) data[i] = pages_[page][offset + i];
    return true;
  }
  uint8_t pages_[kPageCount][kPageBytes];
};

namespace detail {
// Erase of a 2 KiB L4 page takes up to ~25 ms, a 16 KiB F4 sector up to 500 ms.
inline constexpr uint32_t kEraseSpins = 50000000;
}  // namespace detail

template <class Io = Mmio>
class L4PageFlash final : public FlashPages {
 public:
  /// `first_page`: index of the first of the two pages (the linker script reserves them).
  explicit L4PageFlash(uint32_t first_page) : first_page_(first_page) {}

 private:
  static constexpr size_t kPages = 2;
  size_t DoPageSize() override { return l4::kFlashPageSize; }
  size_t DoPageCount() override { return kPages; }
  uintptr_t Address(size_t page, size_t offset) const {
    return l4::kFlashBase + (first_page_ + page) * l4::kFlashPageSize + offset;
  }
  static bool Unlock() {
    if (Io::Read32(l4::kFlashCr) & l4::kFlashCrLock) {
      Io::Write32(l4::kFlashKeyr, 0x45670123);
      Io::Write32(l4::kFlashKeyr, 0xCDEF89AB);
    }
    if (!WaitClear<Io>(l4::kFlashSr, l4::kFlashSrBsy)) return false;
    Io::Write32(l4::kFlashSr, l4::kFlashSrErrors | l4::kFlashSrEop);  // clear stale flags (w1c)
    return (Io::Read32(l4::kFlashCr) & l4::kFlashCrLock) == 0;
  }
  static void Lock() { Io::Write32(l4::kFlashCr, l4::kFlashCrLock); }
  static bool Finish(uint32_t spins) {
    const bool done = WaitClear<Io>(l4::kFlashSr, l4::kFlashSrBsy, spins);
    const bool ok = done && (Io::Read32(l4::kFlashSr) & l4::kFlashSrErrors) == 0;
    Io::Write32(l4::kFlashSr, l4::kFlashSrErrors | l4::kFlashSrEop);
    return ok;
  }
  bool DoErase(size_t page) override {
    if (page >= kPages || !Unlock()) return false;
    const uint32_t pnb = (first_page_ + static_cast<uint32_t>(page)) << l4::kFlashCrPnbShift;
    Io::Write32(l4::kFlashCr, l4::kFlashCrPer | (pnb & l4::kFlashCrPnbMask));
    Io::Write32(l4::kFlashCr, l4::kFlashCrPer | (pnb & l4::kFlashCrPnbMask) | l4::kFlashCrStrt);
    const bool ok = Finish(detail::kEraseSpins);
    Lock();
    return ok;
  }
  bool DoProgram(size_t page, size_t offset, const uint8_t* data, size_t len) override {
    if (page >= kPages || offset > l4::kFlashPageSize || len > l4::kFlashPageSize - offset) return false;
    if (len == 0) return true;
    if (!Unlock()) return false;
    bool ok = true;
    for (size_t dw = offset & ~size_t{7}; ok && dw < offset + len; dw += 8) {
      uint8_t old[8], now[8];
      for (size_t k = 0; k < 8; ++k) {
        old[k] = Io::Read8(Address(page, dw + k));
        const size_t at = dw + k;
        now[k] = (at >= offset && at < offset + len) ? static_cast<uint8_t>(old[k] & data[at - offset]) : old[k];
      }
      bool same = true, erased = true;
      for (size_t k = 0; k < 8; ++k) {
        same = same && now[k] == old[k];
        erased = erased && old[k] == 0xFF;
      }
      if (same) continue;
      if (!erased) {  // ECC: a programmed double-word cannot be programmed again
        ok = false;
        break;
      }
      uint32_t lo = 0, hi = 0;
      for (size_t k = 0; k < 4; ++k) {
        lo |= static_cast<uint32_t>(now[k]) << (8 * k);
        hi |= static_cast<uint32_t>(now[k + 4]) << (8 * k);
      }
      Io::Write32(l4::kFlashCr, l4::kFlashCrPg);
      Io::Write32(Address(page, dw), lo);  // first word, then the second: starts the program
      Io::Write32(Address(page, dw + 4), hi);
      ok = Finish(kSpinLimit);
      Io::Write32(l4::kFlashCr, 0);
    }
    Lock();
    return ok;
  }
  bool DoRead(size_t page, size_t offset, uint8_t* data, size_t len) override {
    if (page >= kPages || offset > l4::kFlashPageSize || len > l4::kFlashPageSize - offset) return false;
    for (size_t i = 0; i < len; ++i) data[i] = Io::Read8(Address(page, offset + i));
    return true;
  }
  uint32_t first_page_;
};

template <class Io = Mmio>
class F4SectorFlash final : public FlashPages {
 public:
  static constexpr size_t kSectorSize = 16 * 1024;
  /// `first_sector`: 1 or 2 (16 KiB sectors 1-3 at 0x08004000..0x0800FFFF); uses it and the next.
  explicit F4SectorFlash(uint32_t first_sector) : first_sector_(first_sector) {}
  /// Whether a flash interface answers: after reset FLASH_CR reads LOCK = 1. Under QEMU the
  /// interface is not modelled (reads 0) and the array is a ROM: erases and programs would report
  /// success and change nothing, so a board checks this at boot (before any unlock) and keeps its
  /// state pages elsewhere when it is false.
  static bool Present() { return (Io::Read32(f4::kFlashCr) & f4::kFlashCrLock) != 0; }

 private:
  static constexpr size_t kPages = 2;
  size_t DoPageSize() override { return kSectorSize; }
  size_t DoPageCount() override { return kPages; }
  uintptr_t Address(size_t page, size_t offset) const { return 0x08000000u + (first_sector_ + page) * kSectorSize + offset; }
  static bool Unlock() {
    if (Io::Read32(f4::kFlashCr) & f4::kFlashCrLock) {
      Io::Write32(f4::kFlashKeyr, 0x45670123);
      Io::Write32(f4::kFlashKeyr, 0xCDEF89AB);
    }
    if (!WaitClear<Io>(f4::kFlashSr, f4::kFlashSrBsy)) return false;
    Io::Write32(f4::kFlashSr, f4::kFlashSrErrors | f4::kFlashSrEop);
    return (Io::Read32(f4::kFlashCr) & f4::kFlashCrLock) == 0;
  }
  static void Lock() { Io::Write32(f4::kFlashCr, f4::kFlashCrLock); }
  static bool Finish(uint32_t spins) {
    const bool done = WaitClear<Io>(f4::kFlashSr, f4::kFlashSrBsy, spins);
    const bool ok = done && (Io::Read32(f4::kFlashSr) & f4::kFlashSrErrors) == 0;
    Io::Write32(f4::kFlashSr, f4::kFlashSrErrors | f4::kFlashSrEop);
    return ok;
  }
  bool DoErase(size_t page) override {
    if (page >= kPages || !Unlock()) return false;
    const uint32_t snb = (first_sector_ + static_cast<uint32_t>(page)) << f4::kFlashCrSnbShift;
    Io::Write32(f4::kFlashCr, f4::kFlashCrSer | f4::kFlashCrPsizeX8 | snb);
    Io::Write32(f4::kFlashCr, f4::kFlashCrSer | f4::kFlashCrPsizeX8 | snb | f4::kFlashCrStrt);
    const bool ok = Finish(detail::kEraseSpins);
    Lock();
    return ok;
  }
  bool DoProgram(size_t page, size_t offset, const uint8_t* data, size_t len) override {
    if (page >= kPages || offset > kSectorSize || len > kSectorSize - offset) return false;
    if (!Unlock()) return false;
    bool ok = true;
    Io::Write32(f4::kFlashCr, f4::kFlashCrPg | f4::kFlashCrPsizeX8);
    for (size_t i = 0; ok && i < len; ++i) {
      const uintptr_t a = Address(page, offset + i);
      Io::Write8(a, static_cast<uint8_t>(Io::Read8(a) & data[i]));
      ok = Finish(kSpinLimit);
    }
    Io::Write32(f4::kFlashCr, 0);
    Lock();
    return ok;
  }
  bool DoRead(size_t page, size_t offset, uint8_t* data, size_t len) override {
    if (page >= kPages || offset > kSectorSize || len > kSectorSize - offset) return false;
    for (size_t i = 0; i < len; ++i) data[i] = Io::Read8(Address(page, offset + i));
    return true;
  }
  uint32_t first_sector_;
};

}  // namespace lw::hal::stm32
