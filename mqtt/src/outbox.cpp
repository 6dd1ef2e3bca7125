#include "mqtt/outbox.hpp"

#include <utility>

namespace lw::mqtt {

void Outbox::Send(Publisher& publisher, OutMessage message) {
  if (queue_.empty() && publisher.Publish(message)) return;
  if (queue_.size() >= capacity_) {
    queue_.pop_front();
    ++dropped_;
  }
  queue_.push_back(std::move(message));
}

size_t Outbox::Flush(Publisher& publisher) {
  size_t sent = 0;
  while (!queue_.empty() && publisher.Publish(queue_.front())) {
    queue_.pop_front();
    ++sent;
  }
  return sent;
}

}  // namespace lw::mqtt
