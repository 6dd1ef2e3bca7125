// The STM32 port's flash page drivers (hal/stm32/flash.hpp) against register-level models of the
// flash interfaces, and the firmware's power-loss-safe StateStore on top of them:
// - STM32L4 (RM0394 3.3): KEYR unlock sequence, page erase (PER, PNB, STRT), double-word
//   programming with PG: two 32-bit writes to one double-word, the first at an 8-aligned address
//   (else PGAERR), byte or half-word writes are SIZERR, and a double-word not erased cannot be
//   programmed again (ECC: PROGERR) unless with all zeros.
// - STM32F4 (RM0090 3.6): KEYR unlock, sector erase (SER, SNB, STRT), byte programming with
//   PSIZE x8 (an access wider than PSIZE is PGPERR), no ECC.
#include <cstdint>
#include <map>
#include <vector>

#include "firmware/persistence.hpp"
#include "hal/stm32/flash.hpp"
#include "hal/stm32/regs.hpp"

#include <CppUTest/TestHarness.h>

namespace st = lw::hal::stm32;

namespace {

enum class Family { kF4, kL4 };

class FlashModel {
 public:
  explicit FlashModel(Family f) : family_(f) {}
  Family family_;
  std::map<uintptr_t, uint8_t> array;  // absent = erased (0xFF)
  bool locked = true;
  int key_step = 0;
  uint32_t cr = 0, sr = 0;
  int programs = 0, erases = 0;
  bool pending_low = false;
  uintptr_t pending_addr = 0;
  uint32_t pending_word = 0;

  uintptr_t Keyr() const { return family_ == Family::kL4 ? st::l4::kFlashKeyr : st::f4::kFlashKeyr; }
  uintptr_t Sr() const { return family_ == Family::kL4 ? st::l4::kFlashSr : st::f4::kFlashSr; }
  uintptr_t Cr() const { return family_ == Family::kL4 ? st::l4::kFlashCr : st::f4::kFlashCr; }
  size_t PageSize() const { return family_ == Family::kL4 ? 2048 : 16384; }
  bool InArray(uintptr_t a) const { return a >= 0x08000000 && a < 0x08040000; }
  uint8_t Byte(uintptr_t a) const {
    auto it = array.find(a);
    return it == array.end() ? 0xFF : it->second;
  }
  void Error(uint32_t bit) { sr |= bit; }

  uint32_t Read(uintptr_t a, int size) {
    if (a == Sr()) return sr;
    if (a == Cr()) return cr | (locked ? (1u << 31) : 0u);
    if (InArray(a)) {
      uint32_t v = 0;
      for (int i = 0; i < size; ++i) v |= static_cast<uint32_t>(Byte(a + static_cast<uintptr_t>(i))) << (8 * i);
      return v;
    }
    FAIL("read of an address the model does not have");
    return 0;
  }

  void Write(uintptr_t a, uint32_t v, int size) {
    if (a == Keyr()) {
      if (key_step == 0 && v == 0x45670123) {
        key_step = 1;
      } else if (key_step == 1 && v == 0xCDEF89AB) {
        locked = false;
        key_step = 0;
      } else {
        key_step = 2;  // a wrong sequence locks the interface until reset
      }
      return;
    }
    if (a == Sr()) {
      sr &= ~v;  // write 1 to clear
      return;
    }
    if (a == Cr()) {
      if (v & (1u << 31)) {
        locked = true;
        cr = 0;
        return;
      }
      if (locked) return;  // CR is write-protected while locked
      cr = v & ~(1u << 16);
      if (v & (1u << 16)) Start();
      return;
    }
    if (InArray(a)) {
      Program(a, v, size);
      return;
    }
    FAIL("write to an address the model does not have");
  }

 private:
  void Start() {
    if (family_ == Family::kL4) {
      if (!(cr & st::l4::kFlashCrPer)) return;
      const uintptr_t page = (cr >> 3) & 0xFF;
      EraseRange(0x08000000 + page * 2048, 2048);
    } else {
      if (!(cr & st::f4::kFlashCrSer)) return;
      const uintptr_t sector = (cr >> 3) & 0xF;
      CHECK_TEXT(sector >= 1 && sector <= 3, "the model has only the 16 KiB sectors 1-3");
      EraseRange(0x08000000 + sector * 16384, 16384);
    }
    ++erases;
  }
  void EraseRange(uintptr_t base, size_t len) {
    for (size_t i = 0; i < len; ++i) array.erase(base + i);
  }
  void Program(uintptr_t a, uint32_t v, int size) {
    if (locked || !(cr & 1u)) {
      Error(1u << 7);  // PGSERR: write to the array without PG
      return;
    }
    if (family_ == Family::kF4) {
      const int psize = 1 << ((cr >> 8) & 3);
      if (size > psize) {
        Error(1u << 6);  // PGPERR
        return;
      }
      for (int i = 0; i < size; ++i) {
        const uintptr_t at = a + static_cast<uintptr_t>(i);
        array[at] = static_cast<uint8_t>(Byte(at) & (v >> (8 * i)));
      }
      ++programs;
      return;
    }
    if (size != 4) {
      Error(1u << 6);  // SIZERR
      return;
    }
    if (!pending_low) {
      if (a % 8 != 0) {
        Error(1u << 5);  // PGAERR
        return;
      }
      pending_low = true;
      pending_addr = a;
      pending_word = v;
      return;
    }
    pending_low = false;
    if (a != pending_addr + 4) {
      Error(1u << 5);
      return;
    }
    const uint64_t dw = pending_word | (static_cast<uint64_t>(v) << 32);
    bool erased = true;
    for (int i = 0; i < 8; ++i) erased = erased && Byte(pending_addr + static_cast<uintptr_t>(i)) == 0xFF;
    if (!erased && dw != 0) {
      Error(1u << 3);  // PROGERR: ECC, a programmed double-word cannot be reprogrammed
      return;
    }
    for (int i = 0; i < 8; ++i) array[pending_addr + static_cast<uintptr_t>(i)] = static_cast<uint8_t>(dw >> (8 * i));
    ++programs;
  }
};

FlashModel* g_flash = nullptr;

struct FakeIo {
  static uint32_t Read32(uintptr_t a) { return g_flash->Read(a, 4); }
  static void Write32(uintptr_t a, uint32_t v) { g_flash->Write(a, v, 4); }
  static uint8_t Read8(uintptr_t a) { return static_cast<uint8_t>(g_flash->Read(a, 1)); }
  static void Write8(uintptr_t a, uint8_t v) { g_flash->Write(a, v, 1); }
};

template <class Driver>
void EraseProgramRead(Family family, Driver& driver) {
  lw::hal::FlashPages& flash = driver;
  FlashModel& m = *g_flash;
  CHECK_TRUE(flash.Erase(1));
  uint8_t buf[40];
  CHECK_TRUE(flash.Read(1, 0, buf, sizeof buf));
  for (uint8_t b : buf) LONGS_EQUAL(0xFF, b);
  const uint8_t rec[24] = {0x4C, 0x57, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 0x12, 0x34, 0xED, 0xCB};
  CHECK_TRUE(flash.Program(1, 0, rec, sizeof rec));
  CHECK_TRUE(flash.Read(1, 0, buf, sizeof rec));
  MEMCMP_EQUAL(rec, buf, sizeof rec);
  CHECK_TRUE(flash.Read(1, 24, buf, 8));
  for (int i = 0; i < 8; ++i) LONGS_EQUAL(0xFF, buf[i]);  // padding left erased
  LONGS_EQUAL(0, m.sr);
  CHECK_TRUE(m.locked);  // locked again after every operation
  // An unaligned range in fresh double-words (L4: padded with 0xFF to whole double-words).
  const uint8_t tail[5] = {0xA1, 0xA2, 0xA3, 0xA4, 0xA5};
  CHECK_TRUE(flash.Program(1, 43, tail, sizeof tail));
  CHECK_TRUE(flash.Read(1, 40, buf, 16));
  const uint8_t want[16] = {0xFF, 0xFF, 0xFF, 0xA1, 0xA2, 0xA3, 0xA4, 0xA5, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF};
  MEMCMP_EQUAL(want, buf, 16);
  // Out of range and bad page: refused, nothing written.
  const int programs = m.programs;
  CHECK_FALSE(flash.Program(1, flash.PageSize() - 4, rec, 8));
  CHECK_FALSE(flash.Program(2, 0, rec, 8));
  CHECK_FALSE(flash.Erase(2));
  LONGS_EQUAL(programs, m.programs);
  // Clearing more bits of a programmed double-word: the L4's ECC refuses it, the F4 ANDs.
  const uint8_t zeros[2] = {0x00, 0x00};
  if (family == Family::kL4) {
    CHECK_FALSE(flash.Program(1, 0, zeros, 2));
    CHECK_TRUE(flash.Read(1, 0, buf, 2));
    LONGS_EQUAL(0x4C, buf[0]);
  } else {
    CHECK_TRUE(flash.Program(1, 0, zeros, 2));
    CHECK_TRUE(flash.Read(1, 0, buf, 2));
    LONGS_EQUAL(0, buf[0]);
  }
  CHECK_TRUE(flash.Erase(1));
  CHECK_TRUE(flash.Read(1, 0, buf, 8));
  LONGS_EQUAL(0xFF, buf[0]);
}

// The app's store saves by erasing the older slot and programming its 24-byte record once:
// exactly what a once-per-erase double-word flash allows. Many saves, then a fresh load.
template <class Driver>
void StateStoreRoundTrips(Driver& driver) {
  lw::hal::FlashPages& flash = driver;
  lw::firmware::StateStore store(flash, 0);
  lw::firmware::PersistentState s;
  CHECK_FALSE(store.Load(&s));  // fresh board
  for (uint32_t i = 1; i <= 20; ++i) {
    s.seq_reserved_until = 64 * i;
    s.reported_loops = static_cast<uint8_t>(100 - i);
    s.ladder_loops = 100;
    s.boots = i;
    CHECK_TRUE(store.Save(&s));
  }
  LONGS_EQUAL(0, g_flash->sr);
  lw::firmware::StateStore after_reset(flash, 0);
  lw::firmware::PersistentState loaded;
  CHECK_TRUE(after_reset.Load(&loaded));
  LONGS_EQUAL(64 * 20, loaded.seq_reserved_until);
  LONGS_EQUAL(80, loaded.reported_loops);
  LONGS_EQUAL(20, loaded.boots);
}

}  // namespace

TEST_GROUP(Stm32Flash){void teardown() override{g_flash = nullptr;
}
}
;

TEST(Stm32Flash, L4PagesEraseProgramAndReadWithDoubleWordEcc) {
  FlashModel m(Family::kL4);
  g_flash = &m;
  st::L4PageFlash<FakeIo> flash(126);
  EraseProgramRead(Family::kL4, flash);
}

TEST(Stm32Flash, F4SectorsEraseProgramAndReadBytes) {
  FlashModel m(Family::kF4);
  g_flash = &m;
  st::F4SectorFlash<FakeIo> flash(2);
  EraseProgramRead(Family::kF4, flash);
}

TEST(Stm32Flash, TheAppsStateStoreRoundTripsOnL4Pages) {
  FlashModel m(Family::kL4);
  g_flash = &m;
  st::L4PageFlash<FakeIo> flash(126);
  StateStoreRoundTrips(flash);
  CHECK(m.erases >= 20);
}

TEST(Stm32Flash, TheAppsStateStoreRoundTripsOnF4Sectors) {
  FlashModel m(Family::kF4);
  g_flash = &m;
  st::F4SectorFlash<FakeIo> flash(2);
  StateStoreRoundTrips(flash);
}

TEST(Stm32Flash, ALockedInterfaceFailsTheOperation) {
  FlashModel m(Family::kL4);
  m.key_step = 2;  // a wrong key sequence earlier: locked until reset
  g_flash = &m;
  st::L4PageFlash<FakeIo> flash(126);
  lw::hal::FlashPages& f = flash;
  const uint8_t one[1] = {0};
  CHECK_FALSE(f.Erase(0));
  CHECK_FALSE(f.Program(0, 0, one, 1));
  LONGS_EQUAL(0, m.programs + m.erases);
}
