#pragma once
/// cpp-httplib behind a guard. Debian 12's cpp-httplib 0.11.4 buffers a request line or header
/// without a newline without limit, reads chunked and gzip bodies past set_payload_max_length, and
/// gives every connection a worker thread from accept to close (so slow or idle connections starve
/// the pool). GuardedServer keeps httplib's request parsing, routing and responses but owns the
/// listening socket: one poll loop accepts connections and reads each request head with caps on
/// bytes, header count and time as the bytes arrive, without a thread per connection; only a
/// complete head is handed to a worker, whose stream caps the body's bytes and time. An idle
/// kept-alive connection waits on the worker that served it while other workers are free, else
/// goes back to the loop. Connections are capped in total and per client IP,
/// and so are the requests one client IP has on workers at once (its other complete heads wait),
/// so that one address trickling bodies cannot hold every worker.
#include "server/http_api.hpp"

// After Eigen (via http_api.hpp): <resolv.h> (via httplib) defines the macro _res, a parameter
// name inside Eigen.
#include <httplib.h>

#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

namespace lw::server {

class GuardedServer : public httplib::Server {
 public:
  explicit GuardedServer(const HttpLimits& limits);
  ~GuardedServer() override;
  GuardedServer(const GuardedServer&) = delete;
  GuardedServer& operator=(const GuardedServer&) = delete;

  /// The body limit of a request from its method and decoded path (no query), checked as its head
  /// arrives (Content-Length: 413 before any body is read) and as a chunked body arrives; never
  /// above HttpLimits::max_body_bytes. Unset: max_body_bytes for every request. Set before Serve().
  using BodyLimit = std::function<uint64_t(std::string_view method, std::string_view path)>;
  void SetBodyLimit(BodyLimit limit) { body_limit_ = std::move(limit); }

  /// Accepts and serves on the socket bound by bind_to_port / bind_to_any_port until Shutdown().
  void Serve();
  /// Stops accepting, closes idle connections, waits for the workers. Safe to call twice.
  void Shutdown();

  struct Conn;  // a client connection (defined in http_guard.cpp)

 private:
  // httplib's own accept loop (listen / listen_after_bind) is never used.
  bool process_and_close_socket(socket_t sock) override;

  void Accept();
  /// Reads what has arrived of c's next request head and checks it (refusing it as it arrives);
  /// true when the head is complete and accepted. Touches c alone: the loop and a worker call it.
  bool ReadHead(Conn& c);
  void HandOff(Conn& c);  // the loop's: a complete head goes to the workers' queue
  void Worker();
  /// Serves one request on c (a worker's). Kept: c is ready for the next request.
  enum class Served { kKeep, kLinger, kClose };
  Served ServeRequest(Conn& c);
  /// After a kept-alive response: the worker waits on c for the client's next request (parked;
  /// it then counts against no client's cap) until the connection's idle timeout, or until a
  /// queued head needs a worker and no other worker is free. kServe: the next head is complete and
  /// this worker serves it (counted against its client's cap again); kBack: c goes back to the
  /// loop; kQueued: the head is complete but waits in the queue (its client at its cap, or other
  /// heads first); kExpired: idle too long, close. `busy`: whether c's client counts this worker.
  enum class Next { kServe, kBack, kQueued, kExpired };
  Next NextHead(Conn& c, bool* busy);
  Conn* TakeJob();        // with mutex_ held: the first queued head whose client IP is under its cap
  void Release(Conn& c);  // closes the socket and gives back the connection slots
  bool Refuse(Conn& c, int status, const std::string& message);  // replies, then lingers briefly; false
  void Wake();

  HttpLimits limits_;
  BodyLimit body_limit_;
  int wake_[2] = {-1, -1};
  int park_fd_ = -1;  // eventfd (semaphore): each count releases one parked worker
  std::atomic<bool> stopping_{false};
  std::vector<std::thread> workers_;
  std::vector<Conn*> conns_;  // the loop's: idle, reading a head, or lingering after an error reply

  std::mutex mutex_;  // guards everything below
  std::condition_variable jobs_cv_;
  std::deque<Conn*> jobs_;       // complete heads waiting for a worker
  std::vector<Conn*> returned_;  // keep-alive connections handed back by workers
  size_t open_ = 0;
  std::map<std::string, size_t> per_client_;
  std::map<std::string, size_t> busy_per_client_;  // requests on a worker, per client IP
  bool served_ = false;
  size_t idle_workers_ = 0;  // waiting for a job
  size_t parked_ = 0;        // waiting on a kept-alive connection (NextHead)
};

}  // namespace lw::server
