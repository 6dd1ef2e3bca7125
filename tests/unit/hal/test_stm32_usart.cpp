// The STM32 port's USART driver (hal/stm32/usart.hpp) against register-level fakes of the F4
// USART (SR/DR, RXNE cleared by reading DR, ORE by SR-then-DR) and the L4 USART/LPUART (ISR, ICR,
// RDR, TDR; ORE held, with RXNEIE, until ICR.ORECF is written). The interrupt line is modelled as
// the hardware drives it, so a handler that returns with it still asserted would be re-entered.
#include <cstdint>
#include <deque>
#include <vector>

#include "hal/stm32/regs.hpp"
#include "hal/stm32/usart.hpp"

#include <CppUTest/TestHarness.h>

namespace st = lw::hal::stm32;

namespace {

template <class Layout>
class FakeUsart {
 public:
  std::deque<uint8_t> wire_in;  // bytes arriving from the radio, one into the data register at a time
  std::vector<uint8_t> wire_out;
  bool tx_stuck = false;

  /// A byte arrives: into the data register, or an overrun when it is still full.
  void Arrive(uint8_t b) {
    if (!Enabled()) return;
    if (rxne_) {
      ore_ = true;
      return;
    }
    rdr_ = b;
    rxne_ = true;
  }
  bool Enabled() const { return (cr1_ & Layout::kCr1Ue) && (cr1_ & Layout::kCr1Re); }
  bool InterruptAsserted() const { return (cr1_ & Layout::kCr1Rxneie) && (rxne_ || ore_); }
  uint32_t cr1() const { return cr1_; }

  uint32_t Read(uintptr_t off) {
    if (off == Layout::kStatus) {
      sr_read_since_dr_ = true;
      return (rxne_ ? Layout::kRxne : 0u) | (ore_ ? Layout::kOre : 0u) | (tx_stuck ? 0u : Layout::kTxe);
    }
    if (off == Layout::kRxData) {
      rxne_ = false;
      if (!Layout::kOverrunClearedByIcr && sr_read_since_dr_) ore_ = false;  // F4: SR then DR
      sr_read_since_dr_ = false;
      return rdr_;
    }
    if (off == Layout::kCr1) return cr1_;
    return 0;
  }
  void Write(uintptr_t off, uint32_t v) {
    if (off == Layout::kCr1) cr1_ = v;
    if (off == Layout::kTxData && !tx_stuck) wire_out.push_back(static_cast<uint8_t>(v));
    if (Layout::kOverrunClearedByIcr && off == Layout::kIcr && (v & Layout::kIcrOrecf)) ore_ = false;
  }

 private:
  uint32_t cr1_ = 0;
  uint8_t rdr_ = 0;
  bool rxne_ = false, ore_ = false, sr_read_since_dr_ = false;
};

constexpr uintptr_t kBase = 0x40011000;

template <class Layout>
struct Io {
  static inline FakeUsart<Layout>* fake = nullptr;
  static uint32_t Read32(uintptr_t a) { return fake->Read(a - kBase); }
  static void Write32(uintptr_t a, uint32_t v) { fake->Write(a - kBase, v); }
  static uint8_t Read8(uintptr_t a) { return static_cast<uint8_t>(fake->Read(a - kBase)); }
  static void Write8(uintptr_t a, uint8_t v) { fake->Write(a - kBase, v); }
};

// Delivers `bytes` the way the NVIC would: the handler runs while the line is asserted; `every`
// bytes arrive per handler entry (2 or more: the hardware overruns before the handler runs).
template <class Layout>
std::vector<uint8_t> Deliver(const std::vector<uint8_t>& bytes, size_t every, uint32_t* hw_overruns) {
  FakeUsart<Layout> fake;
  Io<Layout>::fake = &fake;
  st::Usart<Layout, 64, Io<Layout>> uart(kBase);
  uart.Init(139);
  CHECK(fake.Enabled());
  size_t i = 0;
  while (i < bytes.size()) {
    for (size_t k = 0; k < every && i < bytes.size(); ++k) fake.Arrive(bytes[i++]);
    for (int entries = 0; fake.InterruptAsserted(); ++entries) {
      CHECK_TEXT(entries < 4, "the handler returned with its interrupt still asserted: it would re-enter forever");
      uart.OnInterrupt();
    }
  }
  std::vector<uint8_t> got(64);
  lw::hal::Uart& u = uart;
  got.resize(u.Read(got.data(), got.size()));
  *hw_overruns = uart.hw_overruns();
  Io<Layout>::fake = nullptr;
  return got;
}

template <class Layout>
void ReceivesInOrder() {
  uint32_t ore = 0;
  const std::vector<uint8_t> bytes{0x7E, 0x00, 0x07, 0x8B, 0x01, 0xFF, 0xFE, 0x00, 0x00, 0x00, 0x75};
  const auto got = Deliver<Layout>(bytes, 1, &ore);
  CHECK(got == bytes);
  LONGS_EQUAL(0, ore);
}

template <class Layout>
void OverrunIsCountedAndCleared() {
  uint32_t ore = 0;
  const auto got = Deliver<Layout>({1, 2, 3, 4, 5, 6}, 2, &ore);  // every second byte is lost
  CHECK(got == (std::vector<uint8_t>{1, 3, 5}));
  LONGS_EQUAL(3, ore);
}

template <class Layout>
void TransmitsAndGivesUpOnAStuckTransmitter() {
  FakeUsart<Layout> fake;
  Io<Layout>::fake = &fake;
  st::Usart<Layout, 64, Io<Layout>> uart(kBase);
  uart.Init(139);
  lw::hal::Uart& u = uart;
  const uint8_t frame[] = {0x7E, 0x00, 0x04, 0x08, 0x01, 0x4E, 0x50, 0x58};
  LONGS_EQUAL(sizeof frame, u.Write(frame, sizeof frame));
  CHECK(fake.wire_out == std::vector<uint8_t>(frame, frame + sizeof frame));
  fake.tx_stuck = true;
  LONGS_EQUAL(0, u.Write(frame, sizeof frame));  // bounded: returns, nothing accepted
  Io<Layout>::fake = nullptr;
}

}  // namespace

TEST_GROUP(Stm32Usart){};

TEST(Stm32Usart, F4ReceivesEveryByteInOrder) {
  ReceivesInOrder<st::f4::UsartLayout>();
}
TEST(Stm32Usart, L4ReceivesEveryByteInOrder) {
  ReceivesInOrder<st::l4::UsartLayout>();
}
TEST(Stm32Usart, F4OverrunIsCountedAndClearedBySrThenDr) {
  OverrunIsCountedAndCleared<st::f4::UsartLayout>();
}
TEST(Stm32Usart, L4OverrunIsCountedAndClearedThroughIcr) {
  OverrunIsCountedAndCleared<st::l4::UsartLayout>();
}
TEST(Stm32Usart, F4TransmitsAndGivesUpOnAStuckTransmitter) {
  TransmitsAndGivesUpOnAStuckTransmitter<st::f4::UsartLayout>();
}
TEST(Stm32Usart, L4TransmitsAndGivesUpOnAStuckTransmitter) {
  TransmitsAndGivesUpOnAStuckTransmitter<st::l4::UsartLayout>();
}
