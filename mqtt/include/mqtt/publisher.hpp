#pragma once
/// The publisher contract: what the gateway and the server need of an MQTT client, two methods, so
/// their logic is tested with a fake and only the Paho adapter (paho_link.hpp) includes Paho's
/// headers.
#include <string>

namespace lw::mqtt {

/// One outgoing MQTT message.
struct OutMessage {
  std::string topic;
  std::string payload;
  int qos = 1;
  bool retained = false;
};

/// Non-virtual interface (public calls private virtuals) so checks can be added in one place.
class Publisher {
 public:
  virtual ~Publisher() = default;

  /// Hands a message to the client. Non-blocking. Returns false when the client is not connected
  /// or refused the message (nothing was sent; the caller keeps it and retries later). True does
  /// NOT mean the message reached anyone: the gateway's spool keeps records until the server's
  /// commit ack.
  bool Publish(const OutMessage& message) { return DoPublish(message); }

  /// True while the client believes it is connected to the broker. Non-blocking.
  bool IsConnected() const { return DoIsConnected(); }

 private:
  virtual bool DoPublish(const OutMessage& message) = 0;
  virtual bool DoIsConnected() const = 0;
};

}  // namespace lw::mqtt
