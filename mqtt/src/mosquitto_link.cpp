#include "mqtt/mosquitto_link.hpp"

#include <mosquitto.h>
#include <poll.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <utility>

namespace lw::mqtt {
namespace {

struct Endpoint {
  std::string host;
  int port = 0;
  bool tls = false;
};

/// tcp://host[:port], mqtt://, ssl://, mqtts:// (IPv6 hosts in brackets); the default port is
/// 1883, 8883 with TLS. Throws std::runtime_error naming what is wrong.
Endpoint ParseUri(const std::string& uri) {
  const auto bad = [&uri](const std::string& why) { return std::runtime_error("broker URI '" + uri + "': " + why); };
  const size_t sep = uri.find("://");
  if (sep == std::string::npos) throw bad("no scheme (tcp://, mqtt://, ssl:// or mqtts://)");
  Endpoint e;
  const std::string scheme = uri.substr(0, sep);
  if (scheme == "ssl" || scheme == "mqtts") {
    e.tls = true;
  } else if (scheme != "tcp" && scheme != "mqtt") {
    throw bad("scheme '" + scheme + "://' is not supported by the server's MQTT client (tcp://, mqtt://, ssl:// or mqtts://)");
  }
  std::string rest = uri.substr(sep + 3);
  rest = rest.substr(0, rest.find('/'));
  std::string port_text;
  if (!rest.empty() && rest.front() == '[') {
    const size_t close = rest.find(']');
    if (close == std::string::npos) throw bad("'[' without ']' around the host");
    e.host = rest.substr(1, close - 1);
    const std::string after = rest.substr(close + 1);
    if (!after.empty() && after.front() != ':') throw bad("'" + after + "' after the host");
    if (!after.empty()) port_text = after.substr(1);
  } else {
    const size_t colon = rest.rfind(':');
    e.host = rest.substr(0, colon);
    if (colon != std::string::npos) port_text = rest.substr(colon + 1);
  }
  if (e.host.empty()) throw bad("no host");
  e.port = e.tls ? 8883 : 1883;
  if (!port_text.empty()) {
    size_t used = 0;
    long port = -1;
    try {
      port = std::stol(port_text, &used);
    } catch (const std::exception&) {
    }
    if (used != port_text.size() || port < 1 || port > 65535) throw bad("port '" + port_text + "' is not a number in 1..65535");
    e.port = static_cast<int>(port);
  }
  return e;
}

/// What `rc` means, or errno's text when the error is in errno (saved at the call). libmosquitto
/// 2.0.11's mosquitto_strerror() says "Unknown error." for codes newer than its table (a keep-alive
/// timeout, a malformed packet), and reports a broker that closed the connection in the middle of
/// a packet as an errno error with errno 0 ("Success"): those get their own words here.
std::string Reason(int rc, int saved_errno, int keep_alive_s) {
  switch (rc) {
    case MOSQ_ERR_ERRNO:
      return saved_errno == 0 ? "the broker closed the connection in the middle of a packet" : std::strerror(saved_errno);
    case MOSQ_ERR_KEEPALIVE:
      return "no answer from the broker within the keep-alive (" + std::to_string(keep_alive_s) + " s)";
    case MOSQ_ERR_MALFORMED_PACKET:
      return "malformed packet from the broker";
    case MOSQ_ERR_LOOKUP:
      return "host name lookup failed";
    default:
      return mosquitto_strerror(rc);
  }
}

/// True when poll() says the socket is ready for `events` now (or failed: the next read says how).
bool Ready(int fd, short events) {
  if (fd < 0) return false;
  pollfd p{fd, events, 0};
  return ::poll(&p, 1, 0) > 0 && (p.revents & (events | POLLHUP | POLLERR)) != 0;
}

/// Packets read in one Poll() at most, so a flood cannot keep the owner's loop from its other work.
constexpr int kMaxPacketsPerPoll = 4096;
/// Message bytes one Poll() reports at most (one message more may cross it): a broker streaming
/// large messages as fast as they are read made one Poll() return all it sent (96 MiB in a test),
/// held by the owner at once. The rest waits in the socket; wake_fd() stays readable.
constexpr size_t kMaxBytesPerPoll = 16 << 20;

}  // namespace

struct MosquittoLink::Impl {
  enum class State { kIdle, kConnecting, kConnected };

  LinkOptions options;
  Endpoint endpoint;
  ConnectSchedule schedule;
  mosquitto* client = nullptr;
  bool session_clean = false;  // the session `client` was made for
  State state = State::kIdle;
  int64_t now_ms = 0;             // the current Poll()'s time, for the callbacks
  std::vector<LinkEvent> events;  // from the callbacks and Reconnect(), taken by Poll()
  bool subscribe_due = false;
  int last_acked_mid = -1;         // the last of our QoS 1 messages the broker acknowledged
  uint64_t packets = 0;            // packets handled with a callback (CONNACK, PUBLISH, PUBACK, SUBACK)
  size_t message_bytes = 0;        // payload bytes of the messages reported by this Read()
  std::string violation;           // what the broker did that MQTT forbids (OnLog, OnConnect): Read() drops the connection
  std::string publish_log_prefix;  // how libmosquitto's debug line for a received PUBLISH starts

  explicit Impl(LinkOptions o) : options(std::move(o)), endpoint(ParseUri(options.uri)), schedule(options) {}
  ~Impl() {
    if (!client) return;
    if (state == State::kConnected) {
      state = State::kIdle;
      (void)mosquitto_disconnect(client);  // written at once when the socket takes it
    }
    mosquitto_destroy(client);
  }

  void Check(int rc, const std::string& what) const {
    if (rc != MOSQ_ERR_SUCCESS) throw std::runtime_error("broker " + options.uri + ": " + what + ": " + mosquitto_strerror(rc));
  }

  /// Makes the client for a clean or persistent session with every option (libmosquitto fixes the
  /// session when the client is made; anything it held, as a socket, is dropped).
  void MakeClient(bool clean) {
    if (!client) {
      client = mosquitto_new(options.client_id.empty() ? nullptr : options.client_id.c_str(), clean, this);
      if (!client) {
        throw std::runtime_error(
            "broker " + options.uri + ": libmosquitto client: " +
            (errno == EINVAL ? std::string("a persistent session needs a client id") : std::strerror(errno)));
      }
    } else {
      Check(mosquitto_reinitialise(client, options.client_id.empty() ? nullptr : options.client_id.c_str(), clean, this),
            "libmosquitto client");
    }
    session_clean = clean;
    publish_log_prefix = "Client " + options.client_id + " received PUBLISH (d";  // OnLog
    Check(mosquitto_int_option(client, MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V311), "MQTT 3.1.1");
    Check(mosquitto_int_option(client, MOSQ_OPT_TCP_NODELAY, 1), "TCP_NODELAY");
    Check(mosquitto_max_inflight_messages_set(client, 1000), "in-flight window");
    if (!options.username.empty()) {
      Check(mosquitto_username_pw_set(client, options.username.c_str(), options.password.c_str()), "username");
    }
    if (!options.will.topic.empty()) {
      Check(mosquitto_will_set(client, options.will.topic.c_str(), static_cast<int>(options.will.payload.size()),
                               options.will.payload.data(), options.will.qos, options.will.retained),
            "last will");
    }
    if (endpoint.tls) {
      if (options.tls_ca.empty()) {
        Check(mosquitto_int_option(client, MOSQ_OPT_TLS_USE_OS_CERTS, 1), "TLS with the system's trust store");
      } else {
        Check(mosquitto_tls_set(client, options.tls_ca.c_str(), nullptr, nullptr, nullptr, nullptr),
              "TLS trust store '" + options.tls_ca + "'");
      }
    }
    mosquitto_connect_callback_set(client, &Impl::OnConnect);
    mosquitto_disconnect_callback_set(client, &Impl::OnDisconnect);
    mosquitto_message_callback_set(client, &Impl::OnMessage);
    mosquitto_publish_callback_set(client, &Impl::OnPublish);
    mosquitto_subscribe_callback_set(client, &Impl::OnSubscribe);
    mosquitto_log_callback_set(client, &Impl::OnLog);
  }

  // Callbacks: run inside libmosquitto's calls on the owner's thread (this link runs no thread).
  static void OnConnect(mosquitto*, void* self, int rc) {
    Impl& im = *static_cast<Impl*>(self);
    ++im.packets;
    if (im.state == State::kConnected) {
      // A second CONNACK on a connection (libmosquitto 2.0.11 takes it like the first; found by
      // fuzz_mqtt_link_broker): not a new connection.
      im.violation = "a second CONNACK";
    } else if (rc == 0) {
      im.state = State::kConnected;
      im.schedule.Connected(im.now_ms);
      im.subscribe_due = true;
      im.events.push_back({LinkEvent::Kind::kConnected, "", ""});
    } else {
      im.Failed(std::string(mosquitto_connack_string(rc)) + " (code " + std::to_string(rc) + ")");
    }
  }
  static void OnDisconnect(mosquitto*, void* self, int rc) {
    const int saved_errno = errno;  // what a socket error was (libmosquitto only closed the socket since)
    Impl& im = *static_cast<Impl*>(self);
    if (im.state == State::kConnected) {
      im.state = State::kIdle;
      im.schedule.Lost(im.now_ms);
      im.events.push_back(
          {LinkEvent::Kind::kDisconnected, "", "connection lost: " + Reason(rc, saved_errno, im.options.keep_alive_s)});
    } else if (im.state == State::kConnecting) {
      im.Failed(Reason(rc, saved_errno, im.options.keep_alive_s));
    }  // kIdle: this link dropped it and said why
  }
  static void OnMessage(mosquitto*, void* self, const mosquitto_message* m) {
    Impl& im = *static_cast<Impl*>(self);
    ++im.packets;
    im.message_bytes += static_cast<size_t>(std::max(m->payloadlen, 0));
    im.events.push_back({LinkEvent::Kind::kMessage, m->topic,
                         std::string(static_cast<const char*>(m->payload), static_cast<size_t>(std::max(m->payloadlen, 0)))});
  }
  static void OnPublish(mosquitto*, void* self, int mid) {
    Impl& im = *static_cast<Impl*>(self);
    ++im.packets;
    im.last_acked_mid = mid;
  }
  static void OnSubscribe(mosquitto*, void* self, int, int, const int*) { ++static_cast<Impl*>(self)->packets; }
  /// libmosquitto keeps a QoS 2 message it receives until the broker's PUBREL, which a broker that
  /// never sends one makes last for ever: 50,000 of 1 KiB grew the process by 59 MB, without a
  /// callback (and a persistent session keeps them across reconnects). This link subscribes with
  /// QoS 1 only, so MQTT forbids the broker any QoS 2 message; its only trace is libmosquitto's
  /// debug line "Client <id> received PUBLISH (d0, q2, ...", looked for here and acted on by Read().
  /// The cost: libmosquitto formats its debug lines once a log callback is set (two per reading
  /// received; about 1.5 us a reading in lw_bench_ingest, docs/security.md).
  static void OnLog(mosquitto*, void* self, int level, const char* text) {
    if (level != MOSQ_LOG_DEBUG) return;
    Impl& im = *static_cast<Impl*>(self);
    static constexpr char kPublish[] = " received PUBLISH (d";
    const char* p = nullptr;
    if (im.options.client_id.empty()) {  // an id libmosquitto made up: the first such text
      p = std::strstr(text, kPublish);
      if (!p) return;
      p += sizeof kPublish - 1;
    } else {
      const std::string& prefix = im.publish_log_prefix;
      if (std::strncmp(text, prefix.c_str(), prefix.size()) != 0) return;
      p = text + prefix.size();
    }
    // p: "0, q2, ..."
    if (p[0] != '\0' && std::strncmp(p + 1, ", q2,", 5) == 0) im.violation = "a QoS 2 message on QoS 1 subscriptions";
  }

  void Failed(const std::string& why) {
    state = State::kIdle;
    const int64_t wait = schedule.Failed(now_ms);
    events.push_back({LinkEvent::Kind::kDisconnected, "",
                      "connect to " + options.uri + " failed: " + why + "; retrying in " + std::to_string(wait) + " ms"});
  }

  /// Reads and handles every packet the socket holds (each QoS 1 message acknowledged as it is
  /// read), at most kMaxPacketsPerPoll and kMaxBytesPerPoll. libmosquitto reads at most one packet per call and does
  /// not say whether it found one: its errno (EAGAIN) is no answer either, as it is also what
  /// libmosquitto leaves after writing a byte to its full wake-up socket pair (one per packet sent,
  /// for a loop thread this link does not run). So after a call that handled no packet the socket
  /// is asked (one poll()): nothing left, the reading ends; bytes left (a packet without callback,
  /// such as a PINGRESP, was read: a broker can send 100,000 of them before a message), it goes
  /// on. One read that finds nothing and one poll() per Poll(), not a poll() per message.
  void Read() {
    message_bytes = 0;
    for (int n = 0; n < kMaxPacketsPerPoll && message_bytes < kMaxBytesPerPoll && state != State::kIdle; ++n) {
      const uint64_t before = packets;
      if (const int rc = mosquitto_loop_read(client, 1); rc != MOSQ_ERR_SUCCESS) return Unreported(rc);
      if (!violation.empty()) return Refuse();
      if (packets == before && !Ready(mosquitto_socket(client), POLLIN)) return;
    }
  }

  /// After a libmosquitto call failed with `rc`: OnDisconnect normally said why and left the link
  /// idle. Not always: libmosquitto 2.0.11 closes the socket on a TLS handshake that fails in a read
  /// while connecting (an untrusted broker certificate, when the handshake outlasts the connect
  /// call) and returns MOSQ_ERR_TLS without the callback, and every later read "succeeds" on no
  /// socket: the link would wait for ever, saying nothing. Reported here as the callback would.
  void Unreported(int rc) {
    const int saved_errno = errno;
    if (state == State::kIdle) return;  // OnDisconnect said why
    errno = saved_errno;
    OnDisconnect(client, this, rc);
  }

  /// The broker did what MQTT forbids (`violation`): the connection is dropped and the client made
  /// again, which frees what libmosquitto held for it (QoS 2 messages); Poll() connects again with
  /// the backoff.
  void Refuse() {
    const std::string what = std::move(violation);
    violation.clear();
    state = State::kIdle;
    subscribe_due = false;
    (void)mosquitto_disconnect(client);
    MakeClient(session_clean);
    schedule.Lost(now_ms);
    events.push_back(
        {LinkEvent::Kind::kDisconnected, "",
         "connection dropped: the broker sent " + what + ", which MQTT forbids (a broken broker or a man in the middle)"});
  }

  /// Sends what libmosquitto could not write at once (a full socket, a connection being made).
  void Write() {
    for (int n = 0; n < kMaxPacketsPerPoll && state != State::kIdle && mosquitto_want_write(client); ++n) {
      errno = 0;
      if (const int rc = mosquitto_loop_write(client, 1); rc != MOSQ_ERR_SUCCESS) return Unreported(rc);
      if ((errno == EAGAIN || errno == EWOULDBLOCK) && !Ready(mosquitto_socket(client), POLLOUT)) return;
    }
  }

  void Pump() {
    // Connecting or connected, yet no socket: closed by libmosquitto without a callback (above).
    if (mosquitto_socket(client) < 0) return Unreported(MOSQ_ERR_NO_CONN);
    Read();
    Write();
    if (state != State::kIdle) (void)mosquitto_loop_misc(client);  // keep-alive; a dead link is closed here
  }

  void Connect() {
    violation.clear();  // of an earlier connection that ended otherwise first
    const ConnectSchedule::Attempt attempt = schedule.Start();
    if (!attempt.notice.empty()) events.push_back({LinkEvent::Kind::kDisconnected, "", attempt.notice});
    if (attempt.clean_session != session_clean) MakeClient(attempt.clean_session);
    state = State::kConnecting;
    const int rc = mosquitto_connect_async(client, endpoint.host.c_str(), endpoint.port, options.keep_alive_s);
    const int saved_errno = errno;
    if (rc != MOSQ_ERR_SUCCESS) Failed(Reason(rc, saved_errno, options.keep_alive_s));
  }

  /// Drops the connection without reporting it (the caller does): a DISCONNECT when the socket
  /// takes it (the broker keeps a persistent session and sends no last will), else the socket is
  /// closed by making the client again.
  void Drop() {
    state = State::kIdle;
    subscribe_due = false;
    (void)mosquitto_disconnect(client);
    if (mosquitto_socket(client) >= 0) MakeClient(session_clean);
  }
};

namespace {
void InitLibraryOnce() {
  static std::once_flag once;
  std::call_once(once, [] { mosquitto_lib_init(); });
}
}  // namespace

MosquittoLink::MosquittoLink(LinkOptions options) {
  InitLibraryOnce();
  if (options.keep_alive_s != 0 && options.keep_alive_s < 5) options.keep_alive_s = 5;  // libmosquitto's least
  impl_ = std::make_unique<Impl>(std::move(options));
  impl_->MakeClient(impl_->options.clean_session);
}

MosquittoLink::~MosquittoLink() = default;

std::vector<LinkEvent> MosquittoLink::Poll(int64_t now_ms) {
  Impl& im = *impl_;
  im.now_ms = now_ms;
  if (im.state != Impl::State::kIdle) im.Pump();
  if (im.subscribe_due && im.state == Impl::State::kConnected) {
    im.subscribe_due = false;
    for (const std::string& filter : im.options.subscriptions) {
      const int rc = mosquitto_subscribe(im.client, nullptr, filter.c_str(), 1);
      if (rc != MOSQ_ERR_SUCCESS) {
        im.events.push_back(
            {LinkEvent::Kind::kDisconnected, "", "subscribe to " + filter + " failed: " + mosquitto_strerror(rc)});
      }
    }
  }
  if (im.state == Impl::State::kIdle && im.schedule.Due(now_ms)) im.Connect();
  std::vector<LinkEvent> out;
  out.swap(im.events);
  // The next Poll's events go into room for as many as this one's: grown one by one from empty, the
  // vector moved every message it held at each doubling (2 % of the server's CPU at 7,000 a second).
  im.events.reserve(out.size());
  return out;
}

void MosquittoLink::Reconnect(const std::string& reason) {
  Impl& im = *impl_;
  if (im.state != Impl::State::kIdle) im.Drop();
  im.schedule.Lost(im.now_ms);
  im.events.push_back({LinkEvent::Kind::kDisconnected, "", reason});
}

int MosquittoLink::wake_fd() const {
  return mosquitto_socket(impl_->client);
}

void MosquittoLink::Shutdown(const OutMessage& final_message, int timeout_ms) {
  Impl& im = *impl_;
  if (im.state != Impl::State::kConnected) return;
  using Steady = std::chrono::steady_clock;
  const Steady::time_point deadline = Steady::now() + std::chrono::milliseconds(timeout_ms);
  // The final message waits for its PUBACK (as long as the deadline allows), as PahoLink's does.
  int mid = -1;
  if (!final_message.topic.empty() &&
      mosquitto_publish(im.client, &mid, final_message.topic.c_str(), static_cast<int>(final_message.payload.size()),
                        final_message.payload.data(), final_message.qos, final_message.retained) == MOSQ_ERR_SUCCESS &&
      final_message.qos > 0) {
    while (im.state == Impl::State::kConnected && im.last_acked_mid != mid && Steady::now() < deadline) {
      pollfd p{mosquitto_socket(im.client), static_cast<short>(POLLIN | (mosquitto_want_write(im.client) ? POLLOUT : 0)), 0};
      (void)::poll(&p, 1, 10);
      im.Pump();
    }
  }
  if (im.state == Impl::State::kIdle) return;
  im.state = Impl::State::kIdle;
  (void)mosquitto_disconnect(im.client);
  while (mosquitto_socket(im.client) >= 0 && mosquitto_want_write(im.client) && Steady::now() < deadline) {
    pollfd p{mosquitto_socket(im.client), POLLOUT, 0};
    (void)::poll(&p, 1, 10);
    (void)mosquitto_loop_write(im.client, 1);
  }
}

bool MosquittoLink::DoPublish(const OutMessage& message) {
  Impl& im = *impl_;
  if (im.state != Impl::State::kConnected) return false;
  return mosquitto_publish(im.client, nullptr, message.topic.c_str(), static_cast<int>(message.payload.size()),
                           message.payload.data(), message.qos, message.retained) == MOSQ_ERR_SUCCESS;
}

bool MosquittoLink::DoIsConnected() const {
  return impl_->state == Impl::State::kConnected;
}

}  // namespace lw::mqtt
