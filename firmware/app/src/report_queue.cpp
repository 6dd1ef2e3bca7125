#include "firmware/report_queue.hpp"

namespace lw::firmware {

void ReportQueue::RemoveAt(size_t i) {
  for (size_t j = i + 1; j < size_; ++j) items_[j - 1] = items_[j];
  --size_;
}

bool ReportQueue::Push(const QueuedRecord& rec) {
  bool dropped = false;
  if (full()) {
    dropped = true;
    size_t victim = size_;
    for (size_t i = 0; i < size_; ++i) {
      if (items_[i].heartbeat) {
        victim = i;
        break;
      }
    }
    if (victim < size_) {
      ++dropped_heartbeats_;
      RemoveAt(victim);
    } else if (rec.heartbeat) {
      ++dropped_heartbeats_;
      return false;
    } else {
      ++dropped_steps_;
      RemoveAt(0);
    }
  }
  items_[size_++] = rec;
  return !dropped;
}

bool ReportQueue::Ack(uint32_t seq) {
  for (size_t i = 0; i < size_; ++i) {
    if (items_[i].record.seq == seq) {
      RemoveAt(i);
      return true;
    }
  }
  return false;
}

size_t ReportQueue::Due(uint32_t now, size_t* indices, size_t max) const {
  size_t n = 0;
  for (size_t i = 0; i < size_ && n < max; ++i) {
    if (items_[i].next_try_s <= now) indices[n++] = i;
  }
  return n;
}

uint32_t ReportQueue::NextDue() const {
  uint32_t best = UINT32_MAX;
  for (size_t i = 0; i < size_; ++i) {
    if (items_[i].next_try_s < best) best = items_[i].next_try_s;
  }
  return best;
}

}  // namespace lw::firmware
