// The STM32 port's SPI driver for the ladder (hal/stm32/hc165.hpp) against a register-level fake:
// the F4 or L4 SPI peripheral as the reference manuals describe its registers (CR1, CR2, SR, DR;
// the L4's RX FIFO, FRXTH and data packing), a GPIO port for the SH/LD latch, and a model of a
// daisy chain of 74HC165 parallel-in shift registers clocked by SCK. QEMU cannot check this: its
// STM32 SPI model has no device to attach on the netduinoplus2 bus and clocks a frame on DR reads
// as well as writes.
#include <cstdint>
#include <cstring>
#include <deque>
#include <vector>

#include "hal/stm32/hc165.hpp"
#include "hal/stm32/regs.hpp"
#include "hal/stm32/usart.hpp"

#include <CppUTest/TestHarness.h>

namespace st = lw::hal::stm32;

namespace {

/// 74HC165 chain: register 0's QH drives MISO, register k's SER is register k+1's QH, the last
/// register's SER is tied low. SH/LD low loads the parallel inputs (and holds them while low);
/// each rising SCK edge with SH/LD high shifts every register one place towards QH.
class Hc165Model {
 public:
  explicit Hc165Model(size_t registers) : inputs_(registers, 0), shift_(registers, 0) {}
  void SetInputs(size_t reg, uint8_t value) { inputs_[reg] = value; }
  void SetLoad(bool low) {
    load_low_ = low;
    if (low) {
      shift_ = inputs_;
      ++loads_;
    }
  }
  bool Qh() const { return (shift_[0] & 0x80) != 0; }
  void RisingEdge() {
    ++edges_;
    if (load_low_) return;  // parallel load dominates
    for (size_t k = 0; k < shift_.size(); ++k) {
      const bool ser = k + 1 < shift_.size() ? (shift_[k + 1] & 0x80) != 0 : false;
      shift_[k] = static_cast<uint8_t>((shift_[k] << 1) | (ser ? 1 : 0));
    }
  }
  int loads() const { return loads_; }
  int edges() const { return edges_; }

 private:
  std::vector<uint8_t> inputs_, shift_;
  bool load_low_ = false;
  int loads_ = 0, edges_ = 0;
};

enum class Family { kF4, kL4 };

/// The SPI peripheral (at st::f4::kSpi1 == st::l4::kSpi1) and the latch's GPIO port, behind the
/// addresses the driver uses.
class FakeSpiBoard {
 public:
  FakeSpiBoard(Family family, Hc165Model& chain, uintptr_t gpio, uint32_t latch_pin)
      : family_(family), chain_(chain), gpio_(gpio), latch_pin_(latch_pin) {
    cr2_ = family == Family::kL4 ? 0x0700u : 0u;  // L4 reset: DS = 8 bits, FRXTH = 0
  }
  bool stuck = false;  // the peripheral never completes a frame (unclocked)
  int sr_reads = 0;

  uint32_t Read(uintptr_t addr, int size) {
    if (addr == kSpi + st::spi::kCr1) return cr1_;
    if (addr == kSpi + st::spi::kCr2) return cr2_;
    if (addr == kSpi + st::spi::kSr) {
      ++sr_reads;
      return Sr();
    }
    if (addr == kSpi + st::spi::kDr) {
      uint32_t v = 0;
      const int bytes = family_ == Family::kL4 ? (size == 1 ? 1 : 2) : 1;
      for (int i = 0; i < bytes && !rx_.empty(); ++i) {
        v |= static_cast<uint32_t>(rx_.front()) << (8 * i);
        rx_.pop_front();
      }
      return v;
    }
    if (addr >= gpio_ && addr < gpio_ + 0x400) return 0;
    FAIL("driver read an address the fake does not model");
    return 0;
  }

  void Write(uintptr_t addr, uint32_t value, int size) {
    if (addr == kSpi + st::spi::kCr1) {
      cr1_ = value;
    } else if (addr == kSpi + st::spi::kCr2) {
      cr2_ = value;
      if (family_ == Family::kL4 && ((cr2_ >> 8) & 0xF) < 3) cr2_ = (cr2_ & ~0xF00u) | 0x700u;  // "not used": 8 bits
    } else if (addr == kSpi + st::spi::kDr) {
      // The L4 packs two 8-bit frames into a 16- or 32-bit access of DR.
      const int frames = (family_ == Family::kL4 && size > 1 && FrameBits() <= 8) ? 2 : 1;
      for (int f = 0; f < frames; ++f) Frame();
    } else if (addr == gpio_ + st::gpio::kBsrr) {
      if (value & (1u << (latch_pin_ + 16))) chain_.SetLoad(true);
      if (value & (1u << latch_pin_)) chain_.SetLoad(false);
    } else if (addr >= gpio_ && addr < gpio_ + 0x400) {
      // MODER/AFR: configuration only
    } else {
      FAIL("driver wrote an address the fake does not model");
    }
  }
  uint32_t cr1() const { return cr1_; }

 private:
  static constexpr uintptr_t kSpi = st::f4::kSpi1;
  int FrameBits() const {
    if (family_ == Family::kF4) return (cr1_ & (1u << 11)) ? 16 : 8;  // DFF
    return static_cast<int>((cr2_ >> 8) & 0xF) + 1;
  }
  uint32_t Sr() const {
    uint32_t sr = st::spi::kSrTxe;
    const size_t need = family_ == Family::kL4 && (cr2_ & (1u << 12)) == 0 ? 2 : 1;  // FRXTH
    if (!stuck && rx_.size() >= need) sr |= st::spi::kSrRxne;
    if (ovr_) sr |= st::spi::kSrOvr;
    return sr;
  }
  // One frame on the wire, if the peripheral is an enabled master; the received bits as the
  // configured mode samples them.
  void Frame() {
    if (stuck || (cr1_ & st::spi::kCr1Spe) == 0 || (cr1_ & st::spi::kCr1Mstr) == 0) return;
    if ((cr1_ & st::spi::kCr1Ssm) && (cr1_ & st::spi::kCr1Ssi) == 0) return;  // mode fault: NSS low
    const bool cpha = (cr1_ & st::spi::kCr1Cpha) != 0;
    const int bits = FrameBits();
    uint32_t word = 0;
    for (int b = 0; b < bits; ++b) {
      // Mode 0/2 sample on the first edge (QH before the shift); CPHA = 1 samples on the second,
      // after the rising edge has shifted: one bit late.
      bool bit;
      if (!cpha) {
        bit = chain_.Qh();
        chain_.RisingEdge();
      } else {
        chain_.RisingEdge();
        bit = chain_.Qh();
      }
      word = (word << 1) | (bit ? 1u : 0u);
    }
    if (cr1_ & st::spi::kCr1Lsbfirst) {
      uint32_t r = 0;
      for (int b = 0; b < bits; ++b) r |= ((word >> b) & 1u) << (bits - 1 - b);
      word = r;
    }
    if (family_ == Family::kF4) {
      if (!rx_.empty()) ovr_ = true;  // one-frame DR: an unread byte is overrun
      rx_.clear();
    } else if (rx_.size() >= 4) {
      ovr_ = true;  // 32-bit FIFO full
      return;
    }
    for (int i = 0; i < (bits + 7) / 8; ++i) rx_.push_back(static_cast<uint8_t>(word >> (8 * ((bits + 7) / 8 - 1 - i))));
  }

  Family family_;
  Hc165Model& chain_;
  uintptr_t gpio_;
  uint32_t latch_pin_;
  uint32_t cr1_ = 0, cr2_ = 0;
  std::deque<uint8_t> rx_;
  bool ovr_ = false;
};

FakeSpiBoard* g_board = nullptr;

struct FakeIo {
  static uint32_t Read32(uintptr_t a) { return g_board->Read(a, 4); }
  static void Write32(uintptr_t a, uint32_t v) { g_board->Write(a, v, 4); }
  static uint8_t Read8(uintptr_t a) { return static_cast<uint8_t>(g_board->Read(a, 1)); }
  static void Write8(uintptr_t a, uint8_t v) { g_board->Write(a, v, 1); }
};

constexpr uint32_t kLatchPin = 4;
constexpr size_t kLoops = 100, kDataBytes = (kLoops + 7) / 8, kRegisters = kDataBytes + 1;  // + signature

// Wires loops 0..intact-1 intact onto the chain's inputs (loop 8i + b on input b of register i)
// and the 0xA5 signature on the last register.
void Wire(Hc165Model& chain, size_t intact) {
  for (size_t r = 0; r < kDataBytes; ++r) {
    uint8_t v = 0;
    for (size_t b = 0; b < 8; ++b)
      if (r * 8 + b < intact) v = static_cast<uint8_t>(v | (1u << b));
    chain.SetInputs(r, v);
  }
  chain.SetInputs(kDataBytes, 0xA5);
}

std::vector<uint8_t> Expected(size_t intact) {
  std::vector<uint8_t> out(kRegisters, 0);
  for (size_t i = 0; i < intact; ++i) out[i / 8] = static_cast<uint8_t>(out[i / 8] | (1u << (i % 8)));
  out[kDataBytes] = 0xA5;
  return out;
}

template <class Layout>
void ReadsTheChain(Family family) {
  Hc165Model chain(kRegisters);
  FakeSpiBoard board(family, chain, st::f4::kGpioA, kLatchPin);
  g_board = &board;
  st::Hc165Chain<Layout, FakeIo> spi(st::f4::kSpi1, st::f4::kGpioA, kLatchPin);
  spi.Init(3);
  lw::hal::Spi& bus = spi;
  for (size_t intact : {size_t{100}, size_t{84}, size_t{83}, size_t{1}, size_t{0}}) {
    Wire(chain, intact);
    uint8_t rx[kRegisters + 2];
    std::memset(rx, 0xEE, sizeof rx);
    const int loads = chain.loads();
    CHECK_TRUE(bus.Transfer(nullptr, rx, sizeof rx));
    LONGS_EQUAL(loads + 1, chain.loads());  // latched once per transfer
    const auto want = Expected(intact);
    MEMCMP_EQUAL(want.data(), rx, kRegisters);
    LONGS_EQUAL(0, rx[kRegisters]);  // beyond the chain: the tied-low SER
    LONGS_EQUAL(0, rx[kRegisters + 1]);
  }
  LONGS_EQUAL(5 * 8 * static_cast<long>(kRegisters + 2), chain.edges());  // 8 clocks a byte, nothing more
  g_board = nullptr;
}

}  // namespace

TEST_GROUP(Stm32Hc165){};

TEST(Stm32Hc165, F4ReadsEveryLoopAndTheSignatureInWireOrder) {
  ReadsTheChain<st::f4::SpiLayout>(Family::kF4);
}

TEST(Stm32Hc165, L4ReadsEveryLoopAndTheSignatureInWireOrder) {
  ReadsTheChain<st::l4::SpiLayout>(Family::kL4);
}

// The family difference the port keeps: on the L4, RXNE for 8-bit frames needs CR2.FRXTH. The F4
// configuration on L4 registers never sees RXNE after one byte, and the bounded wait fails the
// transfer instead of hanging.
TEST(Stm32Hc165, F4ConfigurationOnAnL4FailsBoundedInsteadOfHanging) {
  Hc165Model chain(kRegisters);
  FakeSpiBoard board(Family::kL4, chain, st::f4::kGpioA, kLatchPin);
  g_board = &board;
  st::Hc165Chain<st::f4::SpiLayout, FakeIo> spi(st::f4::kSpi1, st::f4::kGpioA, kLatchPin);
  spi.Init(3);
  lw::hal::Spi& bus = spi;
  uint8_t rx[kRegisters];
  CHECK_FALSE(bus.Transfer(nullptr, rx, sizeof rx));
  CHECK(board.sr_reads <= static_cast<int>(st::kSpinLimit) + 16);
  g_board = nullptr;
}

TEST(Stm32Hc165, AStuckBusFailsTheTransfer) {
  Hc165Model chain(kRegisters);
  FakeSpiBoard board(Family::kF4, chain, st::f4::kGpioA, kLatchPin);
  g_board = &board;
  st::Hc165Chain<st::f4::SpiLayout, FakeIo> spi(st::f4::kSpi1, st::f4::kGpioA, kLatchPin);
  spi.Init(3);
  lw::hal::Spi& bus = spi;
  board.stuck = true;
  uint8_t rx[kRegisters];
  CHECK_FALSE(bus.Transfer(nullptr, rx, sizeof rx));
  board.stuck = false;
  Wire(chain, 50);
  CHECK_TRUE(bus.Transfer(nullptr, rx, sizeof rx));  // recovers on the next transfer
  MEMCMP_EQUAL(Expected(50).data(), rx, kRegisters);
  g_board = nullptr;
}

TEST(Stm32Hc165, AnUninitialisedBusFails) {
  Hc165Model chain(kRegisters);
  FakeSpiBoard board(Family::kF4, chain, st::f4::kGpioA, kLatchPin);
  g_board = &board;
  st::Hc165Chain<st::f4::SpiLayout, FakeIo> spi(st::f4::kSpi1, st::f4::kGpioA, kLatchPin);
  lw::hal::Spi& bus = spi;
  uint8_t rx[kRegisters];
  CHECK_FALSE(bus.Transfer(nullptr, rx, sizeof rx));
  LONGS_EQUAL(0, chain.edges());
  g_board = nullptr;
}

TEST(Stm32Hc165, InitSelectsMasterMode0MsbFirstWithSoftwareNss) {
  Hc165Model chain(kRegisters);
  FakeSpiBoard board(Family::kF4, chain, st::f4::kGpioA, kLatchPin);
  g_board = &board;
  st::Hc165Chain<st::f4::SpiLayout, FakeIo> spi(st::f4::kSpi1, st::f4::kGpioA, kLatchPin);
  spi.Init(5);
  const uint32_t cr1 = board.cr1();
  LONGS_EQUAL(0, cr1 & (st::spi::kCr1Cpol | st::spi::kCr1Cpha | st::spi::kCr1Lsbfirst));
  CHECK(cr1 & st::spi::kCr1Mstr);
  CHECK(cr1 & st::spi::kCr1Spe);
  LONGS_EQUAL(5, (cr1 >> st::spi::kCr1BrShift) & 7);
  g_board = nullptr;
}
