#include "server/events.hpp"

#include <algorithm>

namespace lw::server {

void EventBus::Publish(const std::string& crusher, const std::string& name, const std::string& data) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ring_.push_back({{next_id_++, crusher, name, data}, nullptr});
    while (ring_.size() > capacity_) ring_.pop_front();
  }
  cv_.notify_all();
}

void EventBus::PublishLazy(const std::string& crusher, const std::string& name, std::function<std::string()> make) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ring_.push_back({{next_id_++, crusher, name, {}}, std::move(make)});
    while (ring_.size() > capacity_) ring_.pop_front();
  }
  cv_.notify_all();
}

std::vector<Event> EventBus::WaitAfter(int64_t* after, const std::string& crusher, std::chrono::milliseconds wait) {
  std::unique_lock<std::mutex> lock(mutex_);
  cv_.wait_for(lock, wait, [&] { return closed_ || (!ring_.empty() && ring_.back().event.id > *after); });
  std::vector<Event> out;
  for (Held& h : ring_) {
    if (h.event.id <= *after || h.event.crusher != crusher) continue;
    if (h.make) {
      h.event.data = h.make();
      h.make = nullptr;
    }
    out.push_back(h.event);
  }
  if (!ring_.empty()) *after = std::max(*after, ring_.back().event.id);
  return out;
}

int64_t EventBus::LastId() {
  std::lock_guard<std::mutex> lock(mutex_);
  return next_id_ - 1;
}

void EventBus::Close() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    closed_ = true;
  }
  cv_.notify_all();
}

bool EventBus::closed() {
  std::lock_guard<std::mutex> lock(mutex_);
  return closed_;
}

}  // namespace lw::server
