// MCU port building blocks on the host: the ISR -> task byte ring and the 64-bit tick counter
// behind the MPS2 RTC (hal/include/hal/port/).
#include <atomic>
#include <cstdint>
#include <random>
#include <thread>
#include <vector>

#include "hal/port/spsc_ring.hpp"
#include "hal/port/tick_counter.hpp"

#include <CppUTest/TestHarness.h>

using lw::hal::port::MillisToSeconds;
using lw::hal::port::ReadTwice;
using lw::hal::port::SpscRing;
using lw::hal::port::TickCounter64;

TEST_GROUP(SpscRing){};

TEST(SpscRing, EmptyRingPopsNothing) {
  SpscRing<8> ring;
  uint8_t b = 0xAA;
  CHECK_FALSE(ring.Pop(&b));
  LONGS_EQUAL(0xAA, b);
  LONGS_EQUAL(0, ring.size());
}

TEST(SpscRing, HoldsNMinusOneAndCountsEachOverrun) {
  SpscRing<8> ring;
  LONGS_EQUAL(7, ring.capacity());
  for (uint8_t i = 0; i < 7; ++i) CHECK_TRUE(ring.Push(i));
  LONGS_EQUAL(7, ring.size());
  CHECK_FALSE(ring.Push(100));
  CHECK_FALSE(ring.Push(101));
  LONGS_EQUAL(2, ring.overruns());
  // The dropped bytes are the new ones; what was queued comes out intact, in order.
  uint8_t b = 0;
  for (uint8_t i = 0; i < 7; ++i) {
    CHECK_TRUE(ring.Pop(&b));
    LONGS_EQUAL(i, b);
  }
  CHECK_FALSE(ring.Pop(&b));
  LONGS_EQUAL(2, ring.overruns());
}

TEST(SpscRing, WrapsAroundManyTimesInOrder) {
  SpscRing<5> ring;
  uint8_t next_in = 0, next_out = 0;
  for (int round = 0; round < 1000; ++round) {
    const int burst = 1 + round % 4;  // 1..4 = capacity: indices wrap at every offset
    for (int i = 0; i < burst; ++i) CHECK_TRUE(ring.Push(next_in++));
    LONGS_EQUAL(burst, ring.size());
    uint8_t b = 0;
    while (ring.Pop(&b)) LONGS_EQUAL(next_out++, b);
  }
  LONGS_EQUAL(0, ring.overruns());
  LONGS_EQUAL(next_in, next_out);
}

TEST(SpscRing, OverrunThenDrainThenFillAgain) {
  SpscRing<4> ring;
  for (uint8_t i = 0; i < 10; ++i) ring.Push(i);
  LONGS_EQUAL(7, ring.overruns());
  uint8_t b = 0;
  CHECK_TRUE(ring.Pop(&b));
  LONGS_EQUAL(0, b);
  CHECK_TRUE(ring.Push(42));  // room again after one pop
  std::vector<uint8_t> out;
  while (ring.Pop(&b)) out.push_back(b);
  CHECK((out == std::vector<uint8_t>{1, 2, 42}));
}

// A producer thread and a consumer thread: every byte arrives once, in order, or is counted as
// an overrun. (On the host the two run truly in parallel: stronger than an ISR on one core.)
TEST(SpscRing, ConcurrentProducerAndConsumerLoseNothingUncounted) {
  SpscRing<64> ring;
  constexpr uint32_t kBytes = 2'000'000;
  uint32_t pushed = 0;
  std::atomic<bool> done{false};
  std::thread producer([&] {
    for (uint32_t i = 0; i < kBytes; ++i) pushed += ring.Push(static_cast<uint8_t>(i * 7)) ? 1 : 0;
    done = true;
  });
  uint32_t popped = 0, out_of_order = 0;
  uint32_t expect_index = 0;  // index of the next byte the producer may have pushed
  uint8_t b = 0;
  auto consume = [&] {
    while (ring.Pop(&b)) {
      // Bytes are i*7 for increasing i; skips (overruns) are allowed, reordering is not.
      while (expect_index < kBytes && static_cast<uint8_t>(expect_index * 7) != b) ++expect_index;
      if (expect_index == kBytes) ++out_of_order;
      ++expect_index;
      ++popped;
    }
  };
  for (;;) {
    const bool finished = done.load();
    consume();
    if (finished) break;
  }
  producer.join();
  LONGS_EQUAL(pushed, popped);
  LONGS_EQUAL(kBytes, popped + ring.overruns());
  LONGS_EQUAL(0, out_of_order);
}

TEST_GROUP(TickCounter64){};

TEST(TickCounter64, CountsPastTheThirtyTwoBitWrap) {
  // 2^32 ms = 49.7 days, inside one 95-day campaign: a uint32 counter went back to 0 here.
  constexpr uint64_t kWrap = 1ull << 32;
  TickCounter64 ms(kWrap - 3);
  uint64_t last = ms.Read();
  for (int i = 0; i < 6; ++i) {
    ms.Tick();
    const uint64_t now = ms.Read();
    CHECK(now == last + 1);
    last = now;
  }
  CHECK(last == kWrap + 3);
  // The RTC's seconds keep counting: 4294967 s before the wrap, 4294967 s and more after it.
  CHECK(static_cast<uint32_t>(last / 1000) >= 4294967u);
}

TEST(TickCounter64, NinetyFiveDaysOfSecondsStayMonotonic) {
  uint32_t last_s = 0;
  for (uint64_t day = 0; day <= 95; ++day) {
    TickCounter64 at(day * 86'400'000ull);
    const uint32_t s = static_cast<uint32_t>(at.Read() / 1000);
    CHECK(s >= last_s);
    last_s = s;
  }
  LONGS_EQUAL(95u * 86'400u, last_s);
}

// The tick interrupt lands between the reader's loads, exactly at the carry: without the second
// look at the high word the reader would combine the old high word with the new low word and
// see time jump back 2^32 ms (or, the other way round, forward).
TEST(TickCounter64, ReadTwiceRetriesWhenACarryLandsBetweenTheLoads) {
  uint32_t high = 7, low = 0xFFFFFFFFu;
  auto isr_tick = [&] {
    if (++low == 0) ++high;
  };
  int loads_of_low = 0;
  // Interrupt after the high word was read, before the low word is.
  const uint64_t v1 = ReadTwice([&] { return high; },
                                [&] {
                                  if (loads_of_low++ == 0) isr_tick();
                                  return low;
                                });
  CHECK(v1 == (8ull << 32));
  LONGS_EQUAL(2, loads_of_low);  // it did retry

  // Interrupt after the low word was read, before the high word is read again.
  high = 7;
  low = 0xFFFFFFFFu;
  int loads_of_high = 0;
  const uint64_t v2 = ReadTwice(
      [&] {
        if (loads_of_high++ == 1) isr_tick();
        return high;
      },
      [&] { return low; });
  CHECK(v2 == (8ull << 32));
  LONGS_EQUAL(4, loads_of_high);
}

TEST(TickCounter64, ReadWithoutInterruptsTakesOnePass) {
  int loads = 0;
  const uint64_t v = ReadTwice(
      [&] {
        ++loads;
        return 1u;
      },
      [] { return 5u; });
  CHECK(v == ((1ull << 32) | 5u));
  LONGS_EQUAL(2, loads);
}

TEST(TickCounter64, SecondsWithoutA64BitDivisionMatchTheDivision) {
  constexpr uint64_t kWrap = 1ull << 32;
  const uint64_t edges[] = {0,
                            999,
                            1000,
                            kWrap - 1,
                            kWrap,
                            kWrap + 703,
                            kWrap + 704,
                            2 * kWrap - 1,
                            2 * kWrap,
                            95ull * 86'400'000,
                            1000ull * kWrap + 123,
                            14'500'000ull * kWrap - 1};
  for (uint64_t ms : edges) CHECK(MillisToSeconds(ms) == ms / 1000);
  std::mt19937_64 rng(15);
  for (int i = 0; i < 1'000'000; ++i) {
    const uint64_t ms = rng() % (14'500'000ull << 32);
    if (MillisToSeconds(ms) != ms / 1000) FAIL(("MillisToSeconds(" + std::to_string(ms) + ")").c_str());
  }
  TickCounter64 at_wrap(kWrap - 1);
  CHECK(at_wrap.Seconds() == 4'294'967u);
  at_wrap.Tick();
  CHECK(at_wrap.Seconds() == 4'294'967u);  // 2^32 ms = 4 294 967.296 s
}
