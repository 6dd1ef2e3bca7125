#pragma once
/// The Paho MQTT C++ adapter of the gateway (link.hpp's contract): the only file that includes
/// Paho's headers (in the .cpp). Paho's callbacks only queue events; the owner's thread calls Poll()
/// to (re)connect with exponential backoff, subscribe after every connect, and collect what
/// happened, and publishes through the Publisher interface. Never calls the client from inside a
/// Paho callback.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "mqtt/link.hpp"

namespace lw::mqtt {

/// Sets TCP_NODELAY on every connected TCP socket of the process (its MQTT connections): Paho C
/// leaves Nagle's algorithm on, which holds small PUBACKs and PUBLISHes for the broker's delayed
/// ACK (40 ms). PahoLink calls it after each connect; another Paho client in the process may too.
void NoDelayOnTcpSockets();

class PahoLink : public Link {
 public:
  /// Throws std::runtime_error when Paho refuses the URI or options.
  explicit PahoLink(LinkOptions options);
  ~PahoLink() override;
  PahoLink(const PahoLink&) = delete;
  PahoLink& operator=(const PahoLink&) = delete;

  std::vector<LinkEvent> Poll(int64_t now_ms) override;
  void Reconnect(const std::string& reason) override;
  /// An eventfd written when Paho's threads queue the first of a burst of events (Poll() drains it).
  int wake_fd() const override;
  void Shutdown(const OutMessage& final_message, int timeout_ms) override;

 private:
  bool DoPublish(const OutMessage& message) override;
  bool DoIsConnected() const override;

  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lw::mqtt
