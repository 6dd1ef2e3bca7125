#pragma once
/// The Paho MQTT C++ adapter of the gateway and the server: the only file that includes Paho's
/// headers (in the .cpp). Paho's callbacks only queue events; the owner's thread calls Poll() to
/// (re)connect with exponential backoff, subscribe after every connect, and collect what happened,
/// and publishes through the Publisher interface. Never calls the client from inside a Paho callback.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "mqtt/publisher.hpp"

namespace lw::mqtt {

struct LinkOptions {
  std::string uri;  ///< tcp://, ssl://, mqtt://, mqtts://
  std::string client_id;
  std::string username;
  std::string password;
  std::string tls_ca;                      ///< trust store for ssl:// (empty: system default)
  OutMessage will;                         ///< last will (retained offline status)
  std::vector<std::string> subscriptions;  ///< QoS 1, renewed after every connect
  int64_t reconnect_min_ms = 1000;
  int64_t reconnect_max_ms = 60'000;
  int keep_alive_s = 20;
  /// false: a persistent session (fixed client_id): the broker keeps subscriptions and queues QoS 1
  /// messages while the client is away. The gateway uses true (its spool guarantees delivery); the
  /// server uses false.
  bool clean_session = true;
};

struct LinkEvent {
  enum class Kind { kConnected, kDisconnected, kMessage };
  Kind kind = Kind::kMessage;
  std::string topic;    ///< kMessage
  std::string payload;  ///< kMessage; reason text for kDisconnected
};

/// Sets TCP_NODELAY on every connected TCP socket of the process (its MQTT connections): Paho C
/// leaves Nagle's algorithm on, which holds small PUBACKs and PUBLISHes for the broker's delayed
/// ACK (40 ms). PahoLink calls it after each connect; another Paho client in the process may too.
void NoDelayOnTcpSockets();

class PahoLink : public Publisher {
 public:
  /// Throws std::runtime_error when Paho refuses the URI or options.
  explicit PahoLink(LinkOptions options);
  ~PahoLink() override;
  PahoLink(const PahoLink&) = delete;
  PahoLink& operator=(const PahoLink&) = delete;

  /// Drives the connection (starts a connect attempt when due) and returns the events since the
  /// last call, in order. Non-blocking.
  std::vector<LinkEvent> Poll(int64_t now_ms);

  /// Drops the connection now (when it is up) and reports a kDisconnected event with `reason`;
  /// Poll() connects again with its backoff. For a connection that stopped carrying messages.
  void Reconnect(const std::string& reason);

  /// A descriptor that becomes readable when events are queued: poll() it beside the serial port
  /// so commit acks are handled at once (Poll() drains it).
  int wake_fd() const;

  /// Publishes `final_message` (if its topic is not empty) and disconnects, waiting at most
  /// `timeout_ms`. Blocking.
  void Shutdown(const OutMessage& final_message, int timeout_ms);

 private:
  bool DoPublish(const OutMessage& message) override;
  bool DoIsConnected() const override;

  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lw::mqtt
