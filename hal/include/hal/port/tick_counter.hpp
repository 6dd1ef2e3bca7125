#pragma once
/// Building block for MCU ports (freestanding, tested on the host in tests/unit/hal/): a 64-bit
/// millisecond count kept by a tick interrupt on a core without 64-bit atomic stores.
///
/// A uint32 millisecond counter wraps after 2^32 ms = 49.7 days, inside one 95-day campaign: the
/// RTC contract (monotonic seconds) would jump back to 0. Here the ISR counts in two 32-bit words
/// and carries into the high word when the low one wraps; a reader takes high, low and high
/// again, and starts over when an interrupt carried in between (ReadTwice).
#include <atomic>
#include <cstdint>

namespace lw::hal::port {

/// The read-twice rule on its own: one consistent 64-bit value from a high and a low 32-bit word
/// that an interrupt (running to completion, on the reader's core) may change between the loads.
/// `load_high`/`load_low` return the current words.
template <typename LoadHigh, typename LoadLow>
uint64_t ReadTwice(LoadHigh&& load_high, LoadLow&& load_low) {
  for (;;) {
    const uint32_t high = load_high();
    const uint32_t low = load_low();
    if (load_high() == high) return (static_cast<uint64_t>(high) << 32) | low;
  }
}

/// Whole seconds of a millisecond count without a 64-bit division (on Armv7-M that pulls a
/// 700-byte libgcc routine into the image): with ms = high * 2^32 + low and
/// 2^32 = 4 294 967 * 1000 + 296, seconds = high * 4 294 967 + low / 1000 + (high * 296 +
/// low % 1000) / 1000, all in 32-bit divisions. Exact for ms below 2^32 * 14 500 000 (about
/// 2 million years).
constexpr uint64_t MillisToSeconds(uint64_t ms) {
  const auto high = static_cast<uint32_t>(ms >> 32);
  const auto low = static_cast<uint32_t>(ms);
  return static_cast<uint64_t>(high) * 4'294'967u + low / 1000u + (high * 296u + low % 1000u) / 1000u;
}

class TickCounter64 {
  static_assert(std::atomic<uint32_t>::is_always_lock_free, "TickCounter64 needs lock-free 32-bit atomics on this target");

 public:
  /// `start`: the count at construction (0 at boot; tests start near a wrap).
  explicit constexpr TickCounter64(uint64_t start = 0)
      : high_(static_cast<uint32_t>(start >> 32)), low_(static_cast<uint32_t>(start)) {}

  /// One tick. Tick interrupt only (one writer).
  void Tick() {
    const uint32_t low = low_.load(std::memory_order_relaxed) + 1;
    if (low == 0) high_.store(high_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
    low_.store(low, std::memory_order_release);
  }

  /// The count. Any context on the ticking core; never blocks (retries at most once per carry).
  uint64_t Read() const {
    return ReadTwice([this] { return high_.load(std::memory_order_acquire); },
                     [this] { return low_.load(std::memory_order_acquire); });
  }
  /// Read() / 1000 (MillisToSeconds).
  uint64_t Seconds() const { return MillisToSeconds(Read()); }

 private:
  std::atomic<uint32_t> high_;
  std::atomic<uint32_t> low_;
};

}  // namespace lw::hal::port
