#pragma once
/// cpp-httplib behind a guard. Debian 12's cpp-httplib 0.11.4 buffers a request line or header
/// without a newline without limit, reads chunked and gzip bodies past set_payload_max_length, and
/// gives every connection a worker thread from accept to close (so slow or idle connections starve
/// the pool). GuardedServer keeps httplib's request parsing, routing and responses but owns the
/// listening socket: one poll loop accepts connections and reads each request head with caps on
/// bytes, header count and time as the bytes arrive, without a thread per connection; only a
/// complete head is handed to a worker, whose stream caps the body's bytes and time. Idle
/// keep-alive connections go back to the loop. Connections are capped in total and per client IP.
#include "server/http_api.hpp"

// After Eigen (via http_api.hpp): <resolv.h> (via httplib) defines the macro _res, a parameter
// name inside Eigen.
#include <httplib.h>

#include <atomic>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace lw::server {

class GuardedServer : public httplib::Server {
 public:
  explicit GuardedServer(const HttpLimits& limits);
  ~GuardedServer() override;
  GuardedServer(const GuardedServer&) = delete;
  GuardedServer& operator=(const GuardedServer&) = delete;

  /// Accepts and serves on the socket bound by bind_to_port / bind_to_any_port until Shutdown().
  void Serve();
  /// Stops accepting, closes idle connections, waits for the workers. Safe to call twice.
  void Shutdown();

  struct Conn;  // a client connection (defined in http_guard.cpp)

 private:
  // httplib's own accept loop (listen / listen_after_bind) is never used.
  bool process_and_close_socket(socket_t sock) override;

  void Accept();
  void ReadHead(Conn& c);
  void Worker();
  void Release(Conn& c);                                         // closes the socket and gives back the connection slots
  void Refuse(Conn& c, int status, const std::string& message);  // replies, then lingers briefly
  void Wake();

  HttpLimits limits_;
  int wake_[2] = {-1, -1};
  std::atomic<bool> stopping_{false};
  std::vector<std::thread> workers_;
  std::vector<Conn*> conns_;  // the loop's: idle, reading a head, or lingering after an error reply

  std::mutex mutex_;  // guards everything below
  std::condition_variable jobs_cv_;
  std::deque<Conn*> jobs_;       // complete heads waiting for a worker
  std::vector<Conn*> returned_;  // keep-alive connections handed back by workers
  size_t open_ = 0;
  std::map<std::string, size_t> per_client_;
  bool served_ = false;
};

}  // namespace lw::server
