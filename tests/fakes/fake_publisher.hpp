#pragma once
// An mqtt::Publisher that keeps every message instead of sending it (gateway unit tests, fuzz).
#include <string>
#include <vector>

#include "mqtt/publisher.hpp"

namespace lw::test {

/// Publisher fake: records every message; connection and refusal are test controls.
class FakePublisher : public mqtt::Publisher {
 public:
  using OutMessage = mqtt::OutMessage;
  std::vector<OutMessage> sent;
  bool connected = true;
  bool refuse = false;

  std::vector<OutMessage> SentOn(const std::string& topic_suffix) const {
    std::vector<OutMessage> out;
    for (const OutMessage& m : sent) {
      if (m.topic.size() >= topic_suffix.size() &&
          m.topic.compare(m.topic.size() - topic_suffix.size(), topic_suffix.size(), topic_suffix) == 0) {
        out.push_back(m);
      }
    }
    return out;
  }

 private:
  bool DoPublish(const OutMessage& message) override {
    if (!connected || refuse) return false;
    sent.push_back(message);
    return true;
  }
  bool DoIsConnected() const override { return connected; }
};

}  // namespace lw::test
