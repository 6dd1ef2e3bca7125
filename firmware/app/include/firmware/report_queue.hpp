#pragma once
/// Bounded queue of records waiting for the gateway's acknowledgement. Fixed storage, no heap.
/// When full, heartbeats are given up before thickness steps; every drop is counted.
#include <cstddef>
#include <cstdint>

#include "firmware/config.hpp"
#include "protocol/sensor_payload.hpp"

namespace lw::firmware {

/// A record as it waits in the queue: protocol::SensorRecord without age_s (computed at each
/// transmission from sampled_at_s), fields ordered without padding (28 bytes, not 36).
struct StoredRecord {
  uint32_t seq = 0;
  uint16_t thickness_dmm = 0;
  uint16_t flags = 0;
  uint16_t battery_mv = 0;
  uint8_t loops_intact = 0;
  int8_t temperature_c = 0;
  uint8_t loop_bitmap[protocol::kMaxBitmapBytes] = {};
};

struct QueuedRecord {
  StoredRecord record;
  uint32_t sampled_at_s = 0;  ///< RTC time of the sample (age_s is computed at transmission)
  uint32_t next_try_s = 0;    ///< not sent again before this time
  uint8_t attempts = 0;
  bool heartbeat = false;
  /// The record as transmitted at `now` (age_s = now - sampled_at_s).
  protocol::SensorRecord ToSensorRecord(uint32_t now) const {
    protocol::SensorRecord r;
    r.seq = record.seq;
    r.age_s = now - sampled_at_s;
    r.thickness_dmm = record.thickness_dmm;
    r.loops_intact = record.loops_intact;
    r.flags = record.flags;
    r.battery_mv = record.battery_mv;
    r.temperature_c = record.temperature_c;
    for (size_t i = 0; i < protocol::kMaxBitmapBytes; ++i) r.loop_bitmap[i] = record.loop_bitmap[i];
    return r;
  }
};
static_assert(sizeof(QueuedRecord) <= 40, "a queue slot is 40 bytes at most (RAM budget, docs/firmware.md)");

class ReportQueue {
 public:
  /// Adds a record. When full, drops the oldest heartbeat; if none, drops the new record when it
  /// is a heartbeat, else the oldest step. Returns false when something was dropped.
  bool Push(const QueuedRecord& rec);
  /// Removes the record with this seq; returns whether it was there.
  bool Ack(uint32_t seq);
  /// Indices (oldest first) of up to `max` records due at `now`; returns the count.
  size_t Due(uint32_t now, size_t* indices, size_t max) const;
  QueuedRecord& at(size_t i) { return items_[i]; }
  const QueuedRecord& at(size_t i) const { return items_[i]; }
  size_t size() const { return size_; }
  bool full() const { return size_ == kQueueCapacity; }
  uint32_t dropped_heartbeats() const { return dropped_heartbeats_; }
  uint32_t dropped_steps() const { return dropped_steps_; }
  uint32_t dropped_total() const { return dropped_heartbeats_ + dropped_steps_; }
  /// Earliest next_try_s among queued records (UINT32_MAX when empty).
  uint32_t NextDue() const;

 private:
  void RemoveAt(size_t i);
  QueuedRecord items_[kQueueCapacity];
  size_t size_ = 0;
  uint32_t dropped_heartbeats_ = 0;
  uint32_t dropped_steps_ = 0;
};

}  // namespace lw::firmware
