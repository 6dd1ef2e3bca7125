#pragma once
// A hostile MQTT "broker" for tests: a plain TCP listener on 127.0.0.1 that runs a script per
// accepted connection (on its own thread) and speaks as much MQTT 3.1.1 as the script writes with
// the helpers below: it can answer anything, malformed bytes included. It never connects out.
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace lw::test {

/// One MQTT packet as the fake broker read it: the first byte and what follows the length.
struct MqttPacket {
  uint8_t header = 0;
  std::string body;
  uint8_t type() const { return header >> 4; }  // 1 CONNECT, 3 PUBLISH, 4 PUBACK, 8 SUBSCRIBE, 12 PINGREQ, 14 DISCONNECT
};

/// MQTT's variable-length "remaining length" of `n` (at most 268,435,455).
inline std::string MqttLength(uint32_t n) {
  std::string out;
  do {
    uint8_t b = n % 128;
    n /= 128;
    if (n > 0) b |= 0x80;
    out.push_back(static_cast<char>(b));
  } while (n > 0);
  return out;
}

inline std::string MqttString(const std::string& s) {
  return std::string{static_cast<char>(s.size() >> 8), static_cast<char>(s.size() & 0xff)} + s;
}

/// CONNACK with return code `rc` (0 accepted, 1..5 the refusals of MQTT 3.1.1, others invalid).
inline std::string Connack(uint8_t rc) {
  return std::string{'\x20', '\x02', '\x00', static_cast<char>(rc)};
}

/// PUBLISH of `payload` on `topic`; QoS 1 and 2 carry `mid`. `qos` is written as given (3 is invalid).
inline std::string Publish(const std::string& topic, const std::string& payload, int qos = 1, uint16_t mid = 1) {
  std::string body = MqttString(topic);
  if (qos > 0) body += std::string{static_cast<char>(mid >> 8), static_cast<char>(mid & 0xff)};
  body += payload;
  return std::string(1, static_cast<char>(0x30 | (qos << 1))) + MqttLength(static_cast<uint32_t>(body.size())) + body;
}

/// SUBACK for the SUBSCRIBE packet `subscribe` (every filter granted QoS 1).
inline std::string Suback(const MqttPacket& subscribe) {
  // SUBSCRIBE: packet id, then (filter, options) pairs.
  size_t filters = 0;
  for (size_t pos = 2; pos + 2 <= subscribe.body.size(); ++filters) {
    const size_t len = (static_cast<uint8_t>(subscribe.body[pos]) << 8) | static_cast<uint8_t>(subscribe.body[pos + 1]);
    pos += 2 + len + 1;
  }
  std::string body = subscribe.body.substr(0, 2) + std::string(filters, '\x01');
  return "\x90" + MqttLength(static_cast<uint32_t>(body.size())) + body;
}

/// One accepted connection, as the script sees it. Every wait ends at the broker's stop.
class BrokerConnection {
 public:
  BrokerConnection(int fd, const std::atomic<bool>& stop) : fd_(fd), stop_(stop) {}

  /// Writes all of `bytes` (false when the client closed or the broker stops).
  bool Send(const std::string& bytes) {
    size_t done = 0;
    while (done < bytes.size()) {
      if (!WaitFor(POLLOUT, 100)) {
        if (stop_) return false;
        continue;
      }
      const ssize_t n = ::send(fd_, bytes.data() + done, bytes.size() - done, MSG_NOSIGNAL);
      if (n <= 0) return false;
      done += static_cast<size_t>(n);
    }
    return true;
  }

  /// The next whole packet from the client within `timeout_ms`; nullopt on timeout, close or stop.
  std::optional<MqttPacket> Read(int timeout_ms = 10'000) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
    while (true) {
      if (auto p = Parse()) return p;
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - std::chrono::steady_clock::now()).count();
      if (left <= 0 || stop_) return std::nullopt;
      if (!WaitFor(POLLIN, static_cast<int>(std::min<int64_t>(left, 100)))) continue;
      char buf[4096];
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n <= 0) return std::nullopt;
      in_.append(buf, static_cast<size_t>(n));
    }
  }

  /// Reads packets until one of `type` (others are kept in `seen()`), within `timeout_ms`.
  std::optional<MqttPacket> ReadUntil(uint8_t type, int timeout_ms = 10'000) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
    while (std::chrono::steady_clock::now() < end) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - std::chrono::steady_clock::now()).count();
      auto p = Read(static_cast<int>(left));
      if (!p) return std::nullopt;
      if (p->type() == type) return p;
      seen_.push_back(std::move(*p));
    }
    return std::nullopt;
  }

  /// Holds the connection open, reading (and keeping) whatever the client sends, until the client
  /// closes it, the broker stops or `timeout_ms` passes.
  void Hold(int timeout_ms = 60'000) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
    while (!stop_ && std::chrono::steady_clock::now() < end) {
      if (!WaitFor(POLLIN, 100)) continue;
      char buf[4096];
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n <= 0) return;
      in_.append(buf, static_cast<size_t>(n));
      while (auto p = Parse()) seen_.push_back(std::move(*p));
    }
  }

  /// Reads the client's CONNECT and answers `rc`; then, when accepted, its SUBSCRIBE with a SUBACK.
  /// False when the client did not do its part.
  bool Handshake(uint8_t rc = 0) {
    if (!ReadUntil(1) || !Send(Connack(rc))) return false;
    if (rc != 0) return true;
    auto sub = ReadUntil(8);
    return sub && Send(Suback(*sub));
  }

  const std::vector<MqttPacket>& seen() const { return seen_; }

 private:
  bool WaitFor(short events, int timeout_ms) {
    pollfd p{fd_, events, 0};
    return ::poll(&p, 1, timeout_ms) > 0;
  }

  std::optional<MqttPacket> Parse() {
    if (in_.size() < 2) return std::nullopt;
    uint32_t length = 0, mult = 1;
    size_t pos = 1;
    for (;; ++pos) {
      if (pos >= in_.size() || pos > 4) return std::nullopt;  // our client sends valid lengths
      const uint8_t b = static_cast<uint8_t>(in_[pos]);
      length += (b & 127u) * mult;
      mult *= 128;
      if (!(b & 128)) break;
    }
    if (in_.size() < pos + 1 + length) return std::nullopt;
    MqttPacket p{static_cast<uint8_t>(in_[0]), in_.substr(pos + 1, length)};
    in_.erase(0, pos + 1 + length);
    return p;
  }

  int fd_;
  const std::atomic<bool>& stop_;
  std::string in_;
  std::vector<MqttPacket> seen_;
};

/// Listens on a free 127.0.0.1 port; each accepted connection runs `script(index, connection)`
/// (index 0 for the first) on the broker's thread and is closed when the script returns.
class FakeBroker {
 public:
  using Script = std::function<void(int index, BrokerConnection& connection)>;

  explicit FakeBroker(Script script) : script_(std::move(script)) {
    listen_fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    const int one = 1;
    ::setsockopt(listen_fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = 0;
    socklen_t len = sizeof a;
    if (::bind(listen_fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || ::listen(listen_fd_, 8) != 0 ||
        ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&a), &len) != 0) {
      ::close(listen_fd_);
      throw std::runtime_error("fake broker: cannot listen on 127.0.0.1");
    }
    port_ = ntohs(a.sin_port);
    thread_ = std::thread([this] { Run(); });
  }
  ~FakeBroker() {
    stop_ = true;
    thread_.join();
    ::close(listen_fd_);
  }
  FakeBroker(const FakeBroker&) = delete;
  FakeBroker& operator=(const FakeBroker&) = delete;

  std::string uri() const { return "tcp://127.0.0.1:" + std::to_string(port_); }
  int port() const { return port_; }
  /// Connections accepted so far.
  int connections() const { return accepted_; }
  /// Every packet the client sent on connection `index` that the script did not consume (after the
  /// script returned).
  std::vector<MqttPacket> seen(int index) const {
    std::lock_guard<std::mutex> lock(mutex_);
    return index < static_cast<int>(seen_.size()) ? seen_[static_cast<size_t>(index)] : std::vector<MqttPacket>{};
  }

 private:
  void Run() {
    while (!stop_) {
      pollfd p{listen_fd_, POLLIN, 0};
      if (::poll(&p, 1, 50) <= 0) continue;
      const int fd = ::accept(listen_fd_, nullptr, nullptr);
      if (fd < 0) continue;
      const int one = 1;
      ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
      const int index = accepted_++;
      BrokerConnection c(fd, stop_);
      script_(index, c);
      ::close(fd);
      std::lock_guard<std::mutex> lock(mutex_);
      seen_.resize(static_cast<size_t>(index) + 1);
      seen_[static_cast<size_t>(index)] = c.seen();
    }
  }

  Script script_;
  int listen_fd_ = -1;
  int port_ = 0;
  std::atomic<bool> stop_{false};
  std::atomic<int> accepted_{0};
  mutable std::mutex mutex_;
  std::vector<std::vector<MqttPacket>> seen_;
  std::thread thread_;
};

}  // namespace lw::test
