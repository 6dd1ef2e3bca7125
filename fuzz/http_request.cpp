// The server's HTTP front end end to end: arbitrary bytes as one client's side of a TCP connection to
// a real HttpApi (server/src/http_guard.cpp's accept loop and head checks, the route table and its
// scopes checked before any body is read, then the resources: readings POST, alarm rules, reline,
// acks, queries) over the fixture crusher "fz1" (fuzz/data/crusher) with an SQLite database in the
// scratch folder. First byte: bit 0 selects the server with --tokens (tokens "reader-secret" read,
// "writer-secret" read and write; in the dictionary) or the open one; the rest is sent as it is,
// then the client closes its sending side.
// Properties: every answer the server sends starts with an HTTP/1.1 status line; no answer is a 500
// (a resource that threw on a malformed request); an input that starts with a request line and
// holds a whole head (its empty line within the 32 KiB head cap) gets an answer, a refusal at least,
// although the client half-closes at once; after every 64 inputs both servers still answer
// GET /healthz on a new connection (nothing is stuck: no worker, no slot held).
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cctype>
#include <chrono>
#include <cstring>
#include <memory>
#include <string>
#include <string_view>

#include "fuzz_support.hpp"
#include "server/http_api.hpp"
#include "unit/server/server_fixture.hpp"

using lw::fuzz::Check;
using lw::fuzz::Fail;

namespace {

/// One server: the parts of tests/unit/server (a fresh database in a scratch folder) and its API on 127.0.0.1.
struct Server {
  lw::test::ServerParts parts;
  std::unique_ptr<lw::server::HttpApi> api;
  int port = 0;
  explicit Server(bool with_tokens) : parts(LW_FUZZ_DATA_DIR, with_tokens) {
    lw::server::HttpLimits limits;
    limits.head_timeout_ms = limits.body_timeout_ms = limits.io_timeout_ms = 2'000;  // within libFuzzer's -timeout
    parts.ctx.limits = limits;
    api = std::make_unique<lw::server::HttpApi>(parts.ctx);
    port = api->Bind("127.0.0.1", 0);
    api->Start();
  }
  ~Server() { api->Stop(); }
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;
};

/// Sends `bytes` on a new connection, closes the sending side, returns everything the server sent
/// until it closed (at most 1 MiB and 5 s: the server's own timeouts are 2 s).
std::string Exchange(int port, const char* bytes, size_t size) {
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  int fd = -1;
  // A few hundred connections a second for minutes: a refused or unroutable connect (the loopback's
  // ports in TIME_WAIT) is the harness's, so it is retried for 5 s before it counts.
  for (int attempt = 0;; ++attempt) {
    fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd >= 0 && ::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0) break;
    const int error = errno;
    if (fd >= 0) ::close(fd);
    if (attempt == 50) Fail(std::string("cannot connect to the server: ") + std::strerror(error));
    ::usleep(100'000);
  }
  std::string got;
  char buf[65536];
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  size_t sent = 0;
  bool shut = false;
  while (std::chrono::steady_clock::now() < deadline && got.size() < (1u << 20)) {
    if (sent == size && !shut) {
      ::shutdown(fd, SHUT_WR);
      shut = true;
    }
    pollfd p{fd, static_cast<short>(POLLIN | (sent < size ? POLLOUT : 0)), 0};
    if (::poll(&p, 1, 100) <= 0) continue;
    if (p.revents & POLLOUT) {
      const ssize_t n = ::send(fd, bytes + sent, size - sent, MSG_NOSIGNAL);
      if (n > 0) sent += static_cast<size_t>(n);
      if (n < 0) sent = size;  // the server closed: read what it said
    }
    if (p.revents & (POLLIN | POLLHUP | POLLERR)) {
      const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
      if (n <= 0) break;
      got.append(buf, static_cast<size_t>(n));
    }
  }
  const linger reset{1, 0};  // no TIME_WAIT left per input
  ::setsockopt(fd, SOL_SOCKET, SO_LINGER, &reset, sizeof reset);
  ::close(fd);
  return got;
}

/// Every status line in `answer` (at the start and after each response's end, found loosely: a
/// line starting "HTTP/1.1 "), checked: a digit triple, never 500.
void CheckAnswer(const std::string& answer) {
  if (answer.empty()) return;  // closed without a word (a head that never completed before EOF)
  Check(answer.rfind("HTTP/1.1 ", 0) == 0 && answer.size() >= 12,
        "the answer does not start with a status line: " + answer.substr(0, 200));
  for (size_t at = 0; at != std::string::npos; at = answer.find("\r\nHTTP/1.1 ", at + 1)) {
    const size_t s = at == 0 ? 9 : at + 11;
    Check(answer.size() >= s + 3, "a status line cut short");
    Check(answer.compare(s, 3, "500") != 0, "a 500 answer: " + answer.substr(at, 400));
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static Server open(false);
  static Server guarded(true);
  static size_t runs = 0;
  if (size == 0) return 0;
  const Server& s = (data[0] & 1) ? guarded : open;
  const std::string_view sent(reinterpret_cast<const char*>(data + 1), size - 1);
  const std::string answer = Exchange(s.port, sent.data(), sent.size());
  CheckAnswer(answer);
  const size_t head_end = sent.find("\r\n\r\n");
  if (!sent.empty() && std::isalpha(static_cast<unsigned char>(sent[0])) && head_end != std::string_view::npos &&
      head_end + 4 <= lw::server::HttpLimits{}.max_head_bytes) {
    Check(!answer.empty(), "a whole request head got no answer: " + std::string(sent.substr(0, 200)));
  }
  if (++runs % 64 == 0) {
    static const std::string kHealth = "GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
    for (const Server* each : {&open, &guarded}) {
      const std::string h = Exchange(each->port, kHealth.data(), kHealth.size());
      Check(h.rfind("HTTP/1.1 200", 0) == 0 || h.rfind("HTTP/1.1 503", 0) == 0,
            "GET /healthz is not answered: " + h.substr(0, 200));
    }
  }
  return 0;
}
