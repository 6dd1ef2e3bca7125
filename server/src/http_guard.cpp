#include "http_guard.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <strings.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <memory>
#include <string_view>

namespace lw::server {

using Clock = std::chrono::steady_clock;

/// The longest header field line httplib 0.11.4 parses (CPPHTTPLIB_HEADER_MAX_LENGTH).
constexpr size_t kMaxHeaderLine = 8192;

struct GuardedServer::Conn {
  int fd = -1;
  std::string ip;
  int port = 0;
  std::string local_ip;  ///< the address the client connected to (httplib asks for it per request)
  int local_port = 0;
  std::string buf;  ///< received, not yet consumed by a request
  enum class State { kIdle, kHead, kLinger } state = State::kIdle;
  Clock::time_point deadline;
  size_t head_len = 0;          ///< bytes of the complete head at the start of buf
  uint64_t body_allowance = 0;  ///< body bytes the request may send (framing included)
  uint64_t body_limit = 0;      ///< the request's body limit (the 413 message names it)
  bool linger = false;          ///< handed back by a worker to drain unread body bytes, then close
  bool parked = false;          ///< handed back by a parked worker: its idle deadline is already set
  size_t served = 0;            ///< requests answered on this connection
  size_t lingered = 0;          ///< bytes discarded after an error reply
};

namespace {

int RemainingMs(Clock::time_point deadline) {
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
  return static_cast<int>(std::clamp<int64_t>(ms, 0, 1'000'000));
}

const char* Reason(int status) {
  switch (status) {
    case 400:
      return "Bad Request";
    case 408:
      return "Request Timeout";
    case 411:
      return "Length Required";
    case 413:
      return "Payload Too Large";
    case 414:
      return "URI Too Long";
    case 415:
      return "Unsupported Media Type";
    case 431:
      return "Request Header Fields Too Large";
    case 501:
      return "Not Implemented";
    case 503:
      return "Service Unavailable";
    default:
      return "Error";
  }
}

std::string ErrorResponse(int status, const std::string& message) {
  std::string body = "{\"error\":\"";
  for (const char ch : message) {  // messages are ours; escape anyway
    if (ch == '"' || ch == '\\') body += '\\';
    if (static_cast<unsigned char>(ch) >= 0x20) body += ch;
  }
  body += "\"}";
  return "HTTP/1.1 " + std::to_string(status) + " " + Reason(status) +
         "\r\nContent-Type: application/json\r\nConnection: close\r\nContent-Length: " + std::to_string(body.size()) +
         "\r\n\r\n" + body;
}

/// Writes `head` then `body` within `timeout_ms` (the socket is non-blocking) with sendmsg, so that
/// the kernel takes both at once: one segment for a small response. False on error or timeout.
bool SendBoth(int fd, std::string_view head, const char* body, size_t body_size, int timeout_ms) {
  const auto deadline = Clock::now() + std::chrono::milliseconds(timeout_ms);
  size_t done = 0;
  const size_t total = head.size() + body_size;
  while (done < total) {
    iovec iov[2];
    int n_iov = 0;
    if (done < head.size()) iov[n_iov++] = {const_cast<char*>(head.data()) + done, head.size() - done};
    const size_t body_done = done > head.size() ? done - head.size() : 0;
    if (body_size > body_done) iov[n_iov++] = {const_cast<char*>(body) + body_done, body_size - body_done};
    msghdr msg{};
    msg.msg_iov = iov;
    msg.msg_iovlen = static_cast<size_t>(n_iov);
    const ssize_t n = ::sendmsg(fd, &msg, MSG_NOSIGNAL);
    if (n > 0) {
      done += static_cast<size_t>(n);
      continue;
    }
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) return false;
    pollfd p{fd, POLLOUT, 0};
    const int left = RemainingMs(deadline);
    if (left == 0 || ::poll(&p, 1, left) <= 0) return false;
  }
  return true;
}

/// Writes all of `data` within `timeout_ms` (the socket is non-blocking). False on error or timeout.
bool SendAll(int fd, const char* data, size_t size, int timeout_ms) {
  return SendBoth(fd, {}, data, size, timeout_ms);
}

/// The text form and port of a socket address (empty and 0 for a family other than IPv4/IPv6).
std::string AddressText(const sockaddr_storage& addr, int* port) {
  char host[INET6_ADDRSTRLEN] = {};
  *port = 0;
  if (addr.ss_family == AF_INET) {
    const auto* a = reinterpret_cast<const sockaddr_in*>(&addr);
    ::inet_ntop(AF_INET, &a->sin_addr, host, sizeof host);
    *port = ntohs(a->sin_port);
  } else if (addr.ss_family == AF_INET6) {
    const auto* a = reinterpret_cast<const sockaddr_in6*>(&addr);
    ::inet_ntop(AF_INET6, &a->sin6_addr, host, sizeof host);
    *port = ntohs(a->sin6_port);
  }
  return host;
}

std::string Lower(std::string s) {
  for (auto& ch : s) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  return s;
}

std::string TrimSpaces(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t");
  if (a == std::string::npos) return {};
  return s.substr(a, s.find_last_not_of(" \t") - a + 1);
}

/// The stream httplib reads a request from and writes its response to: the head (and any bytes
/// after it) from the loop's buffer, then the socket, within the request's byte and time budget.
class GuardedStream : public httplib::Stream {
 public:
  GuardedStream(GuardedServer::Conn& c, const HttpLimits& limits)
      : c_(c),
        limits_(limits),
        budget_(c.head_len + c.body_allowance),
        deadline_(Clock::now() + std::chrono::milliseconds(limits.body_timeout_ms)) {}

  bool failed() const { return failed_; }
  bool complete() const { return consumed_ == budget_; }
  /// Bytes received beyond what httplib consumed (a pipelined next request).
  std::string Leftover() const { return c_.buf.substr(std::min(pos_, c_.buf.size())); }

  bool is_readable() const override {
    if (pos_ < c_.buf.size()) return true;
    pollfd p{c_.fd, POLLIN, 0};
    return ::poll(&p, 1, std::min(limits_.io_timeout_ms, RemainingMs(deadline_))) > 0;
  }

  /// Writable and the peer still there: a hang-up ends a streamed response (SSE) at once.
  bool is_writable() const override {
    pollfd p{c_.fd, POLLOUT | POLLRDHUP, 0};
    if (::poll(&p, 1, limits_.io_timeout_ms) <= 0) return false;
    return (p.revents & (POLLERR | POLLHUP | POLLRDHUP)) == 0 && (p.revents & POLLOUT);
  }

  ssize_t read(char* ptr, size_t size) override {
    if (failed_) return -1;
    if (consumed_ >= budget_) {
      Fail(413, "request body larger than " + std::to_string(c_.body_limit) + " bytes");
      return -1;
    }
    size = static_cast<size_t>(std::min<uint64_t>(size, budget_ - consumed_));
    if (pos_ < c_.buf.size()) {
      const size_t n = std::min(size, c_.buf.size() - pos_);
      std::memcpy(ptr, c_.buf.data() + pos_, n);
      pos_ += n;
      consumed_ += n;
      return static_cast<ssize_t>(n);
    }
    while (true) {
      const ssize_t n = ::recv(c_.fd, ptr, size, 0);
      if (n >= 0) {
        consumed_ += static_cast<uint64_t>(n);
        return n;
      }
      if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) return -1;
      const int left = RemainingMs(deadline_);
      pollfd p{c_.fd, POLLIN, 0};
      if (left == 0 || ::poll(&p, 1, std::min(limits_.io_timeout_ms, left)) <= 0) {
        Fail(408, "request body not received in time");
        return -1;
      }
    }
  }

  /// httplib writes a response as two writes, the head then the body. The head is held and sent
  /// with the body in one sendmsg (Flush() sends it alone when no body follows): one segment for a
  /// small response, so a kept-alive client never waits on Nagle or a delayed ACK between the two.
  ssize_t write(const char* ptr, size_t size) override {
    if (failed_) return -1;  // our error reply went out instead
    const std::string_view text(ptr, size);
    if (!wrote_ && held_.empty() && size < 16384 && text.find("\r\n\r\n") == size - 4 && text.rfind("HTTP/1.1 100", 0) != 0) {
      held_.assign(ptr, size);  // the response head: wait for the body
      return static_cast<ssize_t>(size);
    }
    wrote_ = true;
    const bool ok = held_.empty() ? SendAll(c_.fd, ptr, size, limits_.io_timeout_ms)
                                  : SendBoth(c_.fd, held_, ptr, size, limits_.io_timeout_ms);
    held_.clear();
    return ok ? static_cast<ssize_t>(size) : -1;
  }
  /// Sends a held response head (a response without a body). False when it could not be sent.
  bool Flush() {
    if (held_.empty()) return true;
    wrote_ = true;
    const bool ok = SendAll(c_.fd, held_.data(), held_.size(), limits_.io_timeout_ms);
    held_.clear();
    return ok;
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    ip = c_.ip;
    port = c_.port;
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    ip = c_.local_ip;
    port = c_.local_port;
  }
  socket_t socket() const override { return c_.fd; }

 private:
  void Fail(int status, const std::string& message) {
    failed_ = true;
    if (!wrote_) {
      const std::string reply = ErrorResponse(status, message);
      SendAll(c_.fd, reply.data(), reply.size(), limits_.io_timeout_ms);
    }
  }

  GuardedServer::Conn& c_;
  const HttpLimits& limits_;
  uint64_t budget_;
  Clock::time_point deadline_;
  size_t pos_ = 0;
  uint64_t consumed_ = 0;
  bool failed_ = false;
  bool wrote_ = false;
  std::string held_;  ///< a response head not sent yet
};

}  // namespace

GuardedServer::GuardedServer(const HttpLimits& limits) : limits_(limits) {
  if (::pipe2(wake_, O_CLOEXEC | O_NONBLOCK) != 0) throw std::runtime_error("cannot create a pipe");
  park_fd_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK | EFD_SEMAPHORE);
  if (park_fd_ < 0) {
    ::close(wake_[0]);
    ::close(wake_[1]);
    throw std::runtime_error("cannot create an eventfd");
  }
}

GuardedServer::~GuardedServer() {
  Shutdown();
  const socket_t listener = svr_sock_.exchange(INVALID_SOCKET);  // bound but never served
  if (listener != INVALID_SOCKET) ::close(listener);
  ::close(wake_[0]);
  ::close(wake_[1]);
  ::close(park_fd_);
}

bool GuardedServer::process_and_close_socket(socket_t sock) {
  // Not reached: Serve() replaces httplib's accept loop. Close what we were given regardless.
  ::close(sock);
  return false;
}

void GuardedServer::Wake() {
  const char b = 1;
  [[maybe_unused]] const ssize_t n = ::write(wake_[1], &b, 1);
}

void GuardedServer::Shutdown() {
  {
    std::lock_guard<std::mutex> lock(mutex_);  // so that no worker misses the wake-up below
    stopping_ = true;
  }
  Wake();
  jobs_cv_.notify_all();
  const uint64_t every = 1u << 20;  // more than any number of workers: each parked one wakes
  [[maybe_unused]] const ssize_t n = ::write(park_fd_, &every, sizeof every);
  // Serve() joins the workers on its way out; wait for it to finish when it was started.
  std::unique_lock<std::mutex> lock(mutex_);
  jobs_cv_.wait(lock, [this] { return !served_; });
}

void GuardedServer::Release(Conn& c) {
  if (c.fd >= 0) ::close(c.fd);
  c.fd = -1;
  std::lock_guard<std::mutex> lock(mutex_);
  --open_;
  if (--per_client_[c.ip] == 0) per_client_.erase(c.ip);
}

bool GuardedServer::Refuse(Conn& c, int status, const std::string& message) {
  const std::string reply = ErrorResponse(status, message);
  [[maybe_unused]] const ssize_t n = ::send(c.fd, reply.data(), reply.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
  // Linger: stop sending, drain what the client still sends for a moment, so that closing with
  // unread bytes does not reset the connection before the client reads the reply.
  ::shutdown(c.fd, SHUT_WR);
  c.state = Conn::State::kLinger;
  c.buf.clear();
  c.buf.shrink_to_fit();
  c.deadline = Clock::now() + std::chrono::milliseconds(2000);
  return false;  // for ReadHead: no head to serve
}

void GuardedServer::Accept() {
  for (int i = 0; i < 64; ++i) {  // bounded: the loop also has heads to read
    sockaddr_storage addr{};
    socklen_t len = sizeof addr;
    const int fd = ::accept4(svr_sock_, reinterpret_cast<sockaddr*>(&addr), &len, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) {
      // Out of file descriptors: the listening socket stays readable; do not spin on it.
      if (errno == EMFILE || errno == ENFILE) std::this_thread::sleep_for(std::chrono::milliseconds(20));
      return;
    }
    auto c = std::make_unique<Conn>();
    c->fd = fd;
    c->ip = AddressText(addr, &c->port);
    sockaddr_storage local{};
    socklen_t local_len = sizeof local;
    if (::getsockname(fd, reinterpret_cast<sockaddr*>(&local), &local_len) == 0) c->local_ip = AddressText(local, &c->local_port);
    std::string refusal;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      size_t& mine = per_client_[c->ip];
      if (open_ >= limits_.max_connections) {
        refusal = "server busy: " + std::to_string(limits_.max_connections) + " connections open; retry later";
      } else if (mine >= limits_.max_connections_per_client) {
        refusal = "too many connections from " + c->ip + " (at most " + std::to_string(limits_.max_connections_per_client) + ")";
      } else {
        ++open_;
        ++mine;
      }
      if (mine == 0) per_client_.erase(c->ip);
    }
    if (!refusal.empty()) {  // not counted: answered and closed at once
      const std::string reply = ErrorResponse(503, refusal);
      [[maybe_unused]] const ssize_t n = ::send(fd, reply.data(), reply.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
      ::close(fd);
      continue;
    }
    const int one = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    c->state = Conn::State::kIdle;
    c->deadline = Clock::now() + std::chrono::milliseconds(limits_.idle_timeout_ms);
    conns_.push_back(c.release());
  }
}

bool GuardedServer::ReadHead(Conn& c) {
  if (c.state == Conn::State::kLinger) {
    char sink[16384];
    while (true) {
      const ssize_t n = ::recv(c.fd, sink, sizeof sink, 0);
      if (n > 0) {
        c.lingered += static_cast<size_t>(n);
        if (c.lingered > (4u << 20)) c.deadline = Clock::now();  // enough: close
        continue;
      }
      if (n == 0 || (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) c.deadline = Clock::now();
      return false;
    }
  }
  // Read no further than one byte past the head cap: the cap holds whatever the client sends.
  // Received into the stack and appended: growing buf by the read's size first would zero 16 KB
  // of it for every read, twice a request (the second read finds nothing).
  bool ended = false;  // the client has closed its sending side
  char chunk[16384];
  while (c.buf.size() <= limits_.max_head_bytes) {
    const size_t want = std::min<size_t>(sizeof chunk, limits_.max_head_bytes + 1 - c.buf.size());
    const ssize_t n = ::recv(c.fd, chunk, want, 0);
    if (n > 0) c.buf.append(chunk, static_cast<size_t>(n));
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
      c.state = Conn::State::kLinger;  // the connection failed: close now
      c.deadline = Clock::now();
      return false;
    }
    if (n == 0) ended = true;
    if (n <= 0) break;
  }
  // A client that half-closes after its request (nc -N, a script's shutdown) still reads the
  // answer: a whole head already received is served. Without one, nothing more can come: close.
  if (ended && c.buf.find("\r\n\r\n") == std::string::npos) {
    c.state = Conn::State::kLinger;
    c.deadline = Clock::now();
    return false;
  }
  if (c.buf.empty()) return false;
  if (c.state == Conn::State::kIdle) {
    c.state = Conn::State::kHead;  // the head must now arrive complete within head_timeout_ms
    c.deadline = Clock::now() + std::chrono::milliseconds(limits_.head_timeout_ms);
  }
  // Empty lines before a request line are allowed (RFC 9112 2.2); httplib would not skip them.
  const size_t start = c.buf.find_first_not_of("\r\n");
  if (start == std::string::npos) {
    if (c.buf.size() >= limits_.max_head_bytes) return Refuse(c, 400, "no request line");
    return false;
  }
  if (start > 0 && c.buf[start - 1] == '\n') c.buf.erase(0, start);
  const size_t eol = c.buf.find('\n');
  if ((eol == std::string::npos ? c.buf.size() : eol) > limits_.max_request_line) {
    return Refuse(c, 414, "request line longer than " + std::to_string(limits_.max_request_line) + " bytes");
  }
  const size_t end = c.buf.find("\r\n\r\n");
  if (end == std::string::npos || end + 4 > limits_.max_head_bytes) {
    if (c.buf.size() >= limits_.max_head_bytes) {
      return Refuse(c, 431,
                    "request head (request line and headers) longer than " + std::to_string(limits_.max_head_bytes) + " bytes");
    }
    return false;  // wait for more
  }
  c.head_len = end + 4;
  // RFC 9110 5.5: a NUL in a field value is refused (httplib reads values as C strings: a token
  // "a\0b" would be compared as "a").
  if (std::memchr(c.buf.data(), '\0', c.head_len) != nullptr) return Refuse(c, 400, "a NUL byte in the request head");
  // What httplib would trust blindly: the body's framing. Checked here, before any body is read.
  size_t headers = 0;
  bool has_length = false, chunked = false;
  uint64_t length = 0;
  const std::string method = c.buf.substr(0, c.buf.find(' '));
  for (size_t p = eol + 1; p < end + 2;) {
    const size_t q = c.buf.find("\r\n", p);
    const std::string line = c.buf.substr(p, q - p);
    p = q + 2;
    if (line.empty()) continue;
    if (++headers > limits_.max_headers)
      return Refuse(c, 431, "more than " + std::to_string(limits_.max_headers) + " header fields");
    // httplib refuses a longer header line as a bare 400 (CPPHTTPLIB_HEADER_MAX_LENGTH).
    if (line.size() > kMaxHeaderLine)
      return Refuse(c, 431, "a header field longer than " + std::to_string(kMaxHeaderLine) + " bytes");
    const size_t colon = line.find(':');
    if (colon == std::string::npos) return Refuse(c, 400, "malformed header line");
    // RFC 9112 5.1: whitespace between a field name and the colon is refused, never trimmed (a
    // proxy and httplib could otherwise read different framing).
    if (colon == 0 || line.find_first_of(" \t") < colon) return Refuse(c, 400, "whitespace in or before a header field name");
    const std::string name = Lower(line.substr(0, colon));
    const std::string value = Lower(TrimSpaces(line.substr(colon + 1)));
    if (name == "content-length") {
      if (has_length || value.empty() || value.size() > 19 || value.find_first_not_of("0123456789") != std::string::npos) {
        return Refuse(c, 400, "malformed or repeated Content-Length");
      }
      has_length = true;
      length = std::stoull(value);
    } else if (name == "transfer-encoding") {
      if (value != "chunked" || chunked)
        return Refuse(c, 501, "Transfer-Encoding other than a single 'chunked' is not supported");
      chunked = true;
    } else if (name == "content-encoding" && value != "identity") {
      return Refuse(c, 415, "compressed request bodies (Content-Encoding) are not accepted");
    }
  }
  if (has_length && chunked) return Refuse(c, 400, "both Content-Length and Transfer-Encoding");
  // The route's limit, from the path as httplib will route it (decoded, without the query).
  const size_t target_at = method.size() + 1;
  const size_t target_end = std::min(c.buf.find(' ', target_at), eol);
  const std::string target = target_at < target_end ? c.buf.substr(target_at, target_end - target_at) : std::string();
  const std::string path = httplib::detail::decode_url(target.substr(0, target.find('?')), false);
  c.body_limit = std::min(limits_.max_body_bytes, body_limit_ ? body_limit_(method, path) : limits_.max_body_bytes);
  if (has_length && length > c.body_limit) {
    return Refuse(c, 413,
                  "request body of " + std::to_string(length) + " bytes; at most " + std::to_string(c.body_limit) + " for " +
                      method + " " + path);
  }
  const bool body_method = method == "POST" || method == "PUT" || method == "PATCH";
  if (body_method && !has_length && !chunked) return Refuse(c, 411, "a " + method + " needs Content-Length or chunked encoding");
  // Chunked: counted as received, framing included (64 KiB of it beyond the cap).
  c.body_allowance = has_length ? length : chunked ? c.body_limit + 64 * 1024 : 0;
  return true;
}

void GuardedServer::HandOff(Conn& c) {
  // A worker owns the connection now; it comes back through returned_ for keep-alive.
  conns_.erase(std::find(conns_.begin(), conns_.end(), &c));
  bool release = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    jobs_.push_back(&c);
    release = idle_workers_ == 0 && parked_ > 0;
  }
  jobs_cv_.notify_one();
  if (release) {  // every worker is serving or parked: one parked worker gives its connection back
    const uint64_t one = 1;
    [[maybe_unused]] const ssize_t n = ::write(park_fd_, &one, sizeof one);
  }
}

GuardedServer::Conn* GuardedServer::TakeJob() {
  const size_t cap = std::max<size_t>(limits_.max_requests_per_client, 1);
  for (auto it = jobs_.begin(); it != jobs_.end(); ++it) {
    Conn* c = *it;
    size_t& busy = busy_per_client_[c->ip];
    if (busy < cap) {
      ++busy;
      jobs_.erase(it);
      return c;
    }
  }
  return nullptr;
}

GuardedServer::Served GuardedServer::ServeRequest(Conn& c) {
  if (stopping_) return Served::kClose;
  GuardedStream strm(c, limits_);
  const bool last = c.served + 1 >= limits_.max_requests_per_connection;
  bool closed = false;
  const bool processed = process_request(strm, last, closed, nullptr);
  const bool ok = strm.Flush() && processed;
  ++c.served;
  // Kept alive only when the request was read exactly to its end (httplib leaves the body of a
  // refused request unread; those bytes must not be parsed as the next request).
  if (ok && !closed && !last && !strm.failed() && strm.complete() && !stopping_) {
    c.buf = strm.Leftover();
    c.state = Conn::State::kIdle;
    c.head_len = 0;
    c.body_allowance = 0;
    return Served::kKeep;
  }
  // Answered before its body was read (404, 405, 401, 403): closing with the body's bytes unread
  // would reset the connection and could lose the reply; drain them for a moment.
  return !stopping_ && !strm.failed() && !strm.complete() ? Served::kLinger : Served::kClose;
}

GuardedServer::Next GuardedServer::NextHead(Conn& c, bool* busy) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopping_ || !jobs_.empty()) return Next::kBack;  // other heads wait: this worker is theirs
    if (c.buf.empty()) {
      if (--busy_per_client_[c.ip] == 0) busy_per_client_.erase(c.ip);
      *busy = false;
      ++parked_;
    }
  }
  if (!*busy) {
    c.deadline = Clock::now() + std::chrono::milliseconds(limits_.idle_timeout_ms);
    Next waited = Next::kExpired;
    while (true) {
      pollfd p[2] = {{c.fd, POLLIN, 0}, {park_fd_, POLLIN, 0}};
      const int n = ::poll(p, 2, RemainingMs(c.deadline));
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;  // idle until its timeout (or poll failed): close
      if (p[0].revents) {
        waited = Next::kServe;
        break;
      }
      uint64_t token = 0;
      if (::read(park_fd_, &token, sizeof token) == sizeof token || stopping_) {
        waited = Next::kBack;  // a queued head needs this worker
        break;
      }  // else another parked worker took the release
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      --parked_;
    }
    if (waited != Next::kServe) {
      c.parked = true;  // the loop keeps the idle deadline set above
      return waited;
    }
  }
  if (!ReadHead(c)) return Next::kBack;  // incomplete or refused: the loop goes on with it (state and deadline set)
  if (*busy) return Next::kServe;
  std::lock_guard<std::mutex> lock(mutex_);
  size_t& mine = busy_per_client_[c.ip];
  if (stopping_ || !jobs_.empty() || mine >= std::max<size_t>(limits_.max_requests_per_client, 1)) {
    if (mine == 0) busy_per_client_.erase(c.ip);
    jobs_.push_back(&c);  // its turn comes as a queued head's; this worker takes the next job
    return Next::kQueued;
  }
  ++mine;
  *busy = true;
  return Next::kServe;
}

void GuardedServer::Worker() {
  while (true) {
    Conn* c = nullptr;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      ++idle_workers_;
      jobs_cv_.wait(lock, [this, &c] { return (c = TakeJob()) != nullptr || stopping_; });
      --idle_workers_;
      if (!c) return;  // stopping
    }
    // A kept-alive client's next request is served by the worker that answered the last one,
    // waiting on the connection: through the loop it costs the loop's wake-up, a hand-off to a
    // worker and the connection's return, each a task switch (on a busy machine a scheduler slice).
    Served served = ServeRequest(*c);
    bool busy = true;
    Next next = Next::kBack;
    while (served == Served::kKeep && (next = NextHead(*c, &busy)) == Next::kServe) served = ServeRequest(*c);
    bool queued = false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (busy && --busy_per_client_[c->ip] == 0) busy_per_client_.erase(c->ip);
      queued = !jobs_.empty();
    }
    if (served == Served::kKeep && next == Next::kQueued) continue;  // c is a queued head: this worker takes a job
    if (served == Served::kKeep && next == Next::kExpired) served = Served::kClose;
    // The client closed (or the connection failed) while this worker waited on it: closed here,
    // not handed to the loop to close, which would cost the loop a wake-up beside the next request.
    if (served == Served::kKeep && next == Next::kBack && c->state == Conn::State::kLinger && c->deadline <= Clock::now())
      served = Served::kClose;
    // The client's next queued head may now take a worker. Only then are the workers woken: each
    // idle worker woken for nothing costs two task switches, and with every request they were
    // most of the server's CPU.
    if (queued) jobs_cv_.notify_all();
    if (served == Served::kClose) {
      Release(*c);
      delete c;
      continue;
    }
    c->linger = served == Served::kLinger;
    if (c->linger) ::shutdown(c->fd, SHUT_WR);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      returned_.push_back(c);
    }
    Wake();
  }
}

void GuardedServer::Serve() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (served_ || stopping_) return;
    served_ = true;
  }
  for (size_t i = 0; i < std::max<size_t>(limits_.workers, 1); ++i) workers_.emplace_back([this] { Worker(); });
  ::fcntl(svr_sock_, F_SETFL, ::fcntl(svr_sock_, F_GETFL) | O_NONBLOCK);
  std::vector<pollfd> fds;
  std::vector<Conn*> polled;
  while (!stopping_) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (Conn* c : returned_) {
        if (c->linger) {
          c->state = Conn::State::kLinger;
          c->buf.clear();  // a lingering connection's bytes are discarded
          c->deadline = Clock::now() + std::chrono::milliseconds(2000);
        } else if (c->state == Conn::State::kIdle && !c->parked) {
          c->deadline = Clock::now() + std::chrono::milliseconds(limits_.idle_timeout_ms);
        }  // else a head the worker began to read (its head deadline runs) or refused (lingering)
        c->parked = false;
        conns_.push_back(c);
      }
      returned_.clear();
    }
    for (size_t i = 0; i < conns_.size();) {
      Conn* c = conns_[i];
      if (c->state == Conn::State::kIdle && !c->buf.empty() && ReadHead(*c)) {
        HandOff(*c);  // a pipelined request already received
        continue;
      }
      if (Clock::now() >= c->deadline) {
        if (c->state == Conn::State::kHead) {
          Refuse(*c, 408, "request head not received within " + std::to_string(limits_.head_timeout_ms / 1000) + " s");
          ++i;
          continue;
        }
        Release(*c);  // idle too long, or done lingering
        delete c;
        conns_.erase(conns_.begin() + static_cast<std::ptrdiff_t>(i));
        continue;
      }
      ++i;
    }
    fds.clear();
    polled.clear();
    fds.push_back({wake_[0], POLLIN, 0});
    fds.push_back({svr_sock_, POLLIN, 0});
    int timeout = 1000;
    for (Conn* c : conns_) {
      fds.push_back({c->fd, POLLIN, 0});
      polled.push_back(c);
      timeout = std::min(timeout, RemainingMs(c->deadline) + 1);
    }
    if (::poll(fds.data(), fds.size(), timeout) < 0 && errno != EINTR) break;
    if (fds[0].revents) {
      char b[64];
      while (::read(wake_[0], b, sizeof b) > 0) {
      }
    }
    for (size_t k = 0; k < polled.size(); ++k) {
      if (fds[k + 2].revents && ReadHead(*polled[k])) HandOff(*polled[k]);
    }
    if (fds[1].revents & POLLIN) Accept();
  }
  // Shutting down: no new connections; workers finish the request they serve (event streams end
  // when the bus closes), queued heads are dropped.
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;  // also when poll() failed
  }
  const socket_t listener = svr_sock_.exchange(INVALID_SOCKET);
  if (listener != INVALID_SOCKET) ::close(listener);
  jobs_cv_.notify_all();
  for (auto& t : workers_) t.join();
  workers_.clear();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    conns_.insert(conns_.end(), returned_.begin(), returned_.end());
    returned_.clear();
    conns_.insert(conns_.end(), jobs_.begin(), jobs_.end());  // heads no worker took
    jobs_.clear();
  }
  for (Conn* c : conns_) {
    Release(*c);
    delete c;
  }
  conns_.clear();
  std::lock_guard<std::mutex> lock(mutex_);
  served_ = false;
  jobs_cv_.notify_all();
}

}  // namespace lw::server
