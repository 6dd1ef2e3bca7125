#pragma once
/// Building block for MCU ports (freestanding, tested on the host in tests/unit/hal/): a byte ring
/// between one producer, an interrupt handler, and one consumer, the task loop.
#include <atomic>
#include <cstddef>
#include <cstdint>

namespace lw::hal::port {

/// Holds up to N - 1 bytes. The indices are std::atomic: the producer writes a byte and then
/// publishes it with a release store of `head`; the consumer's acquire load of `head` therefore
/// sees the byte, and the same pairing on `tail` keeps the producer from overwriting a slot the
/// consumer is still reading. (`volatile` orders only volatile accesses among themselves: the
/// compiler may move the buffer write after the index update, and it says nothing to a core that
/// reorders memory accesses.) Needs lock-free 32-bit atomics, checked below: Armv7-M and later
/// (Cortex-M3/M4/M7/M33: a plain LDR/STR plus DMB). An Armv6-M port (Cortex-M0/M0+, no lock-free
/// atomics in GCC) needs another ring (single core: compiler barriers suffice there).
template <size_t N>
class SpscRing {
  static_assert(N >= 2 && N <= 0x10000, "ring size");
  static_assert(std::atomic<uint32_t>::is_always_lock_free, "SpscRing needs lock-free 32-bit atomics on this target");

 public:
  /// Producer only (ISR). Queues `b`; when the ring is full the byte is dropped, counted in
  /// overruns(), and false returned. Never blocks.
  bool Push(uint8_t b) {
    const uint32_t head = head_.load(std::memory_order_relaxed);
    const uint32_t next = Advance(head);
    if (next == tail_.load(std::memory_order_acquire)) {
      overruns_.store(overruns_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);  // one writer
      return false;
    }
    buf_[head] = b;
    head_.store(next, std::memory_order_release);
    return true;
  }

  /// Consumer only (task). Takes the oldest byte; false when empty. Never blocks.
  bool Pop(uint8_t* b) {
    const uint32_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_.load(std::memory_order_acquire)) return false;
    *b = buf_[tail];
    tail_.store(Advance(tail), std::memory_order_release);
    return true;
  }

  /// Bytes waiting (exact for the consumer; a lower bound while the producer runs).
  size_t size() const {
    const uint32_t head = head_.load(std::memory_order_acquire);
    const uint32_t tail = tail_.load(std::memory_order_relaxed);
    return head >= tail ? head - tail : N - tail + head;
  }
  static constexpr size_t capacity() { return N - 1; }
  /// Bytes dropped because the ring was full, since construction (wraps at 2^32).
  uint32_t overruns() const { return overruns_.load(std::memory_order_relaxed); }

 private:
  static constexpr uint32_t Advance(uint32_t i) { return i + 1 == N ? 0 : i + 1; }
  uint8_t buf_[N] = {};
  std::atomic<uint32_t> head_{0};
  std::atomic<uint32_t> tail_{0};
  std::atomic<uint32_t> overruns_{0};
};

}  // namespace lw::hal::port
