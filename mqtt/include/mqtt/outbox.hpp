#pragma once
/// Messages a Publisher refused, kept in order until it takes them: the server's commit acks when
/// Paho's in-flight window is full or the link is down. Without it a refused ack was dropped and
/// the gateway had to wait for its republication period before the record was released.
/// Not thread-safe: owned and flushed by one thread (the server's MQTT loop).
#include <cstddef>
#include <cstdint>
#include <deque>

#include "mqtt/publisher.hpp"

namespace lw::mqtt {

class Outbox {
 public:
  /// At most `capacity` messages are kept; beyond it the oldest is dropped (and counted): a commit
  /// ack that is lost only makes the gateway republish its record, which is acked again.
  explicit Outbox(size_t capacity = 100'000) : capacity_(capacity == 0 ? 1 : capacity) {}

  /// Sends `message` now if nothing waits before it and the publisher takes it; else keeps it.
  void Send(Publisher& publisher, OutMessage message);
  /// Sends the kept messages in order until the publisher refuses one. Returns how many went.
  size_t Flush(Publisher& publisher);

  size_t size() const { return queue_.size(); }
  uint64_t dropped() const { return dropped_; }  ///< oldest messages dropped at capacity

 private:
  size_t capacity_;
  std::deque<OutMessage> queue_;
  uint64_t dropped_ = 0;
};

}  // namespace lw::mqtt
