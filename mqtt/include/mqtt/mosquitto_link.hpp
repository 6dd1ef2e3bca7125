#pragma once
/// The libmosquitto adapter of the server (link.hpp's contract): the only file that includes
/// mosquitto.h (in the .cpp). Unlike PahoLink it runs no thread of its own: Poll() reads the broker's
/// socket on the owner's thread until it would block, every QoS 1 message acknowledged (PUBACK) as
/// it is read, and wake_fd() is that socket. A message costs the system calls of reading it and of
/// its PUBACK, no hand-over between threads (docs/performance.md, *Ingest*).
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "mqtt/link.hpp"

namespace lw::mqtt {

class MosquittoLink : public Link {
 public:
  /// Throws std::runtime_error naming what is wrong when libmosquitto cannot use the URI (not
  /// tcp://, mqtt://, ssl:// or mqtts://; no host; a bad port) or the options.
  explicit MosquittoLink(LinkOptions options);
  ~MosquittoLink() override;
  MosquittoLink(const MosquittoLink&) = delete;
  MosquittoLink& operator=(const MosquittoLink&) = delete;

  std::vector<LinkEvent> Poll(int64_t now_ms) override;
  void Reconnect(const std::string& reason) override;
  /// The broker's socket while one is open, else -1.
  int wake_fd() const override;
  void Shutdown(const OutMessage& final_message, int timeout_ms) override;

 private:
  bool DoPublish(const OutMessage& message) override;
  bool DoIsConnected() const override;

  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lw::mqtt
