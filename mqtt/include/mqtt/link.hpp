#pragma once
/// The MQTT link contract of the gateway and the server: options, the events a link reports, and
/// the interface both adapters implement (PahoLink in paho_link.hpp, MosquittoLink in
/// mosquitto_link.hpp). The owner's thread calls Poll() to (re)connect with exponential backoff,
/// subscribe after every connect and collect what happened, and publishes through Publisher.
#include <cstdint>
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

class Link : public Publisher {
 public:
  /// Drives the connection (starts a connect attempt when due) and returns the events since the
  /// last call, in order. Non-blocking.
  virtual std::vector<LinkEvent> Poll(int64_t now_ms) = 0;

  /// Drops the connection now (when it is up) and reports a kDisconnected event with `reason`;
  /// Poll() connects again with its backoff. For a connection that stopped carrying messages.
  virtual void Reconnect(const std::string& reason) = 0;

  /// A descriptor that becomes readable when Poll() has something to do or report: poll() it
  /// beside the owner's other descriptors so commit acks are handled at once. May change after
  /// Poll() (ask again each time) and may be -1 (nothing to wait for: poll() ignores it).
  virtual int wake_fd() const = 0;

  /// Publishes `final_message` (if its topic is not empty) and disconnects, waiting at most
  /// `timeout_ms`. Blocking.
  virtual void Shutdown(const OutMessage& final_message, int timeout_ms) = 0;
};

/// When a link (re)connects, shared by both adapters: the first attempt at once, after a failed
/// attempt or a lost connection the backoff (reconnect_min_ms, doubled each time up to
/// reconnect_max_ms, reset by a connection); a persistent session whose connections keep dropping
/// right after being made is reset with one clean-session attempt.
class ConnectSchedule {
 public:
  explicit ConnectSchedule(const LinkOptions& options);

  /// True when the next attempt is due (the link asks only while no connection is up or being made).
  bool Due(int64_t now_ms) const { return now_ms >= next_attempt_ms_; }

  struct Attempt {
    bool clean_session;  ///< the session this attempt asks for
    std::string notice;  ///< non-empty: report it (a kDisconnected event) before connecting
  };
  /// A connect attempt starts now: the session it must ask for.
  Attempt Start();
  /// The attempt failed: the next waits the backoff, which doubles. Returns the wait in ms.
  int64_t Failed(int64_t now_ms);
  /// A connection was made (the backoff starts again from reconnect_min_ms).
  void Connected(int64_t now_ms);
  /// The connection was lost (or dropped on purpose): the next attempt waits the backoff.
  void Lost(int64_t now_ms);

 private:
  int64_t min_ms_, max_ms_;
  bool clean_session_;
  int64_t next_attempt_ms_ = 0;
  int64_t backoff_ms_;
  int64_t last_connected_ms_ = -1;
  int flaps_ = 0;  // connections lost within kFlapMs of being made, in a row
};

}  // namespace lw::mqtt
