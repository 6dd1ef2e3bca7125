#include "mqtt/link.hpp"

#include <algorithm>

namespace lw::mqtt {
namespace {
/// A persistent session whose connections keep dropping within this long of being made (seen
/// after a SIGKILL + restart with a broker restart in between) is reset: the next attempt uses a
/// clean session once. Nothing is lost: the gateway resends every reading not yet committed.
constexpr int64_t kFlapMs = 5000;
constexpr int kFlapsBeforeReset = 2;
}  // namespace

ConnectSchedule::ConnectSchedule(const LinkOptions& options)
    : min_ms_(options.reconnect_min_ms),
      max_ms_(std::max(options.reconnect_min_ms, options.reconnect_max_ms)),
      clean_session_(options.clean_session),
      backoff_ms_(options.reconnect_min_ms) {}

ConnectSchedule::Attempt ConnectSchedule::Start() {
  const bool reset = !clean_session_ && flaps_ >= kFlapsBeforeReset;
  if (!reset) return {clean_session_, ""};
  flaps_ = 0;
  return {true,
          "the persistent session keeps dropping right after connecting: connecting once with a clean session (readings "
          "queued at the broker are dropped; the gateway resends what is not committed)"};
}

int64_t ConnectSchedule::Failed(int64_t now_ms) {
  const int64_t wait = backoff_ms_;
  next_attempt_ms_ = now_ms + wait;
  backoff_ms_ = std::min(backoff_ms_ * 2, max_ms_);
  return wait;
}

void ConnectSchedule::Connected(int64_t now_ms) {
  last_connected_ms_ = now_ms;
  backoff_ms_ = min_ms_;
}

void ConnectSchedule::Lost(int64_t now_ms) {
  const bool flap = last_connected_ms_ >= 0 && now_ms - last_connected_ms_ < kFlapMs;
  flaps_ = flap ? flaps_ + 1 : 0;
  last_connected_ms_ = -1;
  Failed(now_ms);
}

}  // namespace lw::mqtt
