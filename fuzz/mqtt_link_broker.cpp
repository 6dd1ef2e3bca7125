// The server's MQTT link (mqtt::MosquittoLink, libmosquitto) against arbitrary bytes from the broker.
// Input: everything the "broker" sends on the accepted connection, from the first byte (the seeds
// start with a CONNACK and a SUBACK so that PUBLISHes are read as such), then the broker closes its
// side. The link connects to a listener of this process on 127.0.0.1, as the server's does.
// Properties: the link reports the broker's close (a kDisconnected event, not connected any more)
// within a bounded number of Poll() calls, whatever came before it; at most one kConnected;
// messages only while connected, each with a topic. libmosquitto itself is not instrumented (the
// Debian library): its allocations are checked by ASan (double frees, leaks), its reads are not, and
// coverage guides the fuzzer only through the link's code (docs/fuzzing.md).
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <string>
#include <vector>

#include "fuzz_support.hpp"
#include "mqtt/mosquitto_link.hpp"

using lw::fuzz::Check;
using lw::fuzz::Fail;
using lw::mqtt::LinkEvent;

namespace {

/// A listener on a free 127.0.0.1 port, made once per process.
struct Listener {
  int fd = -1;
  int port = 0;
  Listener() {
    fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof a;
    if (fd < 0 || ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || ::listen(fd, 4) != 0 ||
        ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len) != 0) {
      Fail("cannot listen on 127.0.0.1");
    }
    port = ntohs(a.sin_port);
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const Listener listener;
  lw::mqtt::LinkOptions o;
  o.uri = "tcp://127.0.0.1:" + std::to_string(listener.port);
  o.client_id = "fuzz-server";
  o.subscriptions = {"linerwatch/v1/+/+/sensors/+/reading"};
  o.clean_session = false;
  o.reconnect_min_ms = o.reconnect_max_ms = 3'600'000;  // one connection per input
  o.keep_alive_s = 60;
  lw::mqtt::MosquittoLink link(o);
  int64_t now_ms = 0;  // the link's clock: one ms per Poll()
  std::vector<LinkEvent> events;
  const auto poll_link = [&] {
    for (LinkEvent& e : link.Poll(++now_ms)) events.push_back(std::move(e));
  };
  poll_link();  // starts connecting
  pollfd lp{listener.fd, POLLIN, 0};
  for (int i = 0; i < 200 && ::poll(&lp, 1, 10) <= 0; ++i) poll_link();
  const int fd = ::accept(listener.fd, nullptr, nullptr);
  if (fd < 0) Fail("the link did not connect to the listener");
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) | O_NONBLOCK);
  // The input, as fast as the link reads it; then the broker's side is closed (EOF).
  size_t sent = 0;
  for (int i = 0; sent < size && i < 100'000; ++i) {
    const ssize_t n = ::send(fd, data + sent, size - sent, MSG_NOSIGNAL);
    if (n > 0) {
      sent += static_cast<size_t>(n);
    } else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      poll_link();  // the link reads; what it sends back (PUBACKs) waits in this socket's buffer
    } else {
      break;  // the link closed the connection (a malformed packet): the rest is not needed
    }
  }
  ::shutdown(fd, SHUT_WR);
  bool ended = false;
  for (int i = 0; i < 10'000 && !ended; ++i) {
    poll_link();
    ended = !link.IsConnected() && !events.empty() && events.back().kind == LinkEvent::Kind::kDisconnected;
    if (!ended) {
      pollfd p{link.wake_fd(), POLLIN, 0};
      (void)::poll(&p, 1, 1);
    }
  }
  // No TIME_WAIT left behind per input (a reset, now that the link has read everything).
  const linger reset{1, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_LINGER, &reset, sizeof reset);
  ::close(fd);
  Check(ended,
        "the link did not report the broker's close after " + std::to_string(sent) + " of " + std::to_string(size) + " bytes");
  int connected = 0;
  bool up = false;
  for (const LinkEvent& e : events) {
    if (e.kind == LinkEvent::Kind::kConnected) {
      ++connected;
      up = true;
    } else if (e.kind == LinkEvent::Kind::kDisconnected) {
      Check(!e.payload.empty(), "a kDisconnected event without a reason");
      up = false;
    } else {
      Check(up, "a message reported while not connected");
      Check(!e.topic.empty(), "a message without a topic");
    }
  }
  Check(connected <= 1, "more than one kConnected on one connection");
  return 0;
}
