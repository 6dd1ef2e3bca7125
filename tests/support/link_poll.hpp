#pragma once
// Polling an mqtt::Link as its owner's loop does, for the link tests.
#include <poll.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <vector>

#include "mqtt/link.hpp"

namespace lw::test {

inline int64_t SteadyMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

struct LinkRun {
  std::vector<mqtt::LinkEvent> events;
  int polls = 0;  ///< Poll() calls made
};

/// Polls `link` (waiting up to 20 ms on wake_fd() between calls) until `done` holds for the events
/// seen so far, at most `timeout_ms`.
inline LinkRun PollLinkUntil(mqtt::Link& link, const std::function<bool(const std::vector<mqtt::LinkEvent>&)>& done,
                             int64_t timeout_ms) {
  LinkRun run;
  const int64_t end = SteadyMs() + timeout_ms;
  while (!done(run.events) && SteadyMs() < end) {
    ++run.polls;
    for (mqtt::LinkEvent& e : link.Poll(SteadyMs())) run.events.push_back(std::move(e));
    if (done(run.events)) break;
    pollfd p{link.wake_fd(), POLLIN, 0};
    (void)::poll(&p, 1, 20);
  }
  return run;
}

inline size_t CountEvents(const std::vector<mqtt::LinkEvent>& events, mqtt::LinkEvent::Kind kind) {
  size_t n = 0;
  for (const mqtt::LinkEvent& e : events) n += e.kind == kind;
  return n;
}

}  // namespace lw::test
