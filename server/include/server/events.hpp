#pragma once
/// Fan-out of live events (new readings, new wear) to Server-Sent-Event clients: a bounded ring
/// of recent events with increasing ids; readers wait for ids after the last one they saw.
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <vector>

namespace lw::server {

struct Event {
  int64_t id = 0;
  std::string crusher;
  std::string name;  ///< "reading", "wear", "alarm" or "campaign"
  std::string data;  ///< JSON, one line
};

class EventBus {
 public:
  explicit EventBus(size_t capacity = 2000) : capacity_(capacity) {}
  void Publish(const std::string& crusher, const std::string& name, const std::string& data);
  /// An event whose data `make` builds only when a reader first takes it (under the bus's lock):
  /// most readings are never read by anyone (no dashboard open), so their JSON is never built.
  void PublishLazy(const std::string& crusher, const std::string& name, std::function<std::string()> make);
  /// Events of `crusher` with id > *after, waiting up to `wait` for any new event; *after becomes
  /// the newest id seen. Returns early (possibly empty) when Close() was called.
  std::vector<Event> WaitAfter(int64_t* after, const std::string& crusher, std::chrono::milliseconds wait);
  int64_t LastId();
  void Close();
  bool closed();

 private:
  size_t capacity_;
  std::mutex mutex_;
  std::condition_variable cv_;
  struct Held {
    Event event;
    std::function<std::string()> make;  ///< set until event.data is built
  };
  std::deque<Held> ring_;
  int64_t next_id_ = 1;
  bool closed_ = false;
};

}  // namespace lw::server
