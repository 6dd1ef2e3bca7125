#include "mqtt/paho_link.hpp"

#include <MQTTAsync.h>
#include <dirent.h>
#include <mqtt/async_client.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdlib>

#include <algorithm>
#include <atomic>
#include <deque>
#include <mutex>
#include <utility>

namespace lw::mqtt {

// Paho C (1.3 in Debian 12) leaves Nagle's algorithm on its broker socket and has no option to
// turn it off: a PUBACK or a small PUBLISH written while an earlier segment is unacknowledged
// waits for the broker's delayed ACK (40 ms on Linux). Each commit-ack round trip of a sensor
// cost ~80 ms that way (lw_bench_gateway_replay: 78 ms per round whatever the number of
// sensors). So every connected TCP socket of the process gets TCP_NODELAY after a connect (this
// process's only TCP sockets are its MQTT connections; a socket that already has it is unchanged).
void NoDelayOnTcpSockets() {
  DIR* dir = opendir("/proc/self/fd");
  if (!dir) return;
  while (const dirent* e = readdir(dir)) {
    char* end = nullptr;
    const long fd = std::strtol(e->d_name, &end, 10);
    if (end == e->d_name || *end != '\0' || fd == dirfd(dir)) continue;
    int type = 0;
    socklen_t type_len = sizeof type;
    if (getsockopt(static_cast<int>(fd), SOL_SOCKET, SO_TYPE, &type, &type_len) != 0 || type != SOCK_STREAM) continue;
    sockaddr_storage addr{};
    socklen_t addr_len = sizeof addr;
    if (getsockname(static_cast<int>(fd), reinterpret_cast<sockaddr*>(&addr), &addr_len) != 0) continue;
    if (addr.ss_family != AF_INET && addr.ss_family != AF_INET6) continue;
    const int one = 1;
    (void)setsockopt(static_cast<int>(fd), IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  }
  closedir(dir);
}

struct PahoLink::Impl {
  // Declaration order matters for destruction: the client (last) goes first, so no Paho callback
  // can run against the queue, the mutex or the wake descriptor after they are gone.
  struct WakeFd {
    int fd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    ~WakeFd() {
      if (fd >= 0) close(fd);
    }
  };
  LinkOptions options;
  ::mqtt::connect_options connect_options;
  std::mutex mutex;
  std::deque<LinkEvent> events;  // filled by Paho's threads, drained by Poll()
  std::atomic<bool> connected{false};
  ::mqtt::token_ptr pending_connect;
  ConnectSchedule schedule;
  WakeFd wake;
  ::mqtt::async_client client;

  explicit Impl(LinkOptions o) : options(std::move(o)), schedule(options), client(options.uri, options.client_id, nullptr) {}
  ~Impl() {
    try {
      client.disable_callbacks();
    } catch (const std::exception&) {
    }
  }

  // Wakes the poller only when the queue was empty: Poll() reads the descriptor before it takes
  // the whole queue, so an event queued behind others is taken with them (one write per burst of
  // messages instead of one system call per message).
  void Push(LinkEvent e) {
    bool was_empty = false;
    {
      std::lock_guard<std::mutex> lock(mutex);
      was_empty = events.empty();
      events.push_back(std::move(e));
    }
    const uint64_t one = 1;
    if (was_empty && wake.fd >= 0) (void)!write(wake.fd, &one, sizeof one);
  }
};

namespace {
/// Paho C (Debian's build, without HIGH_PERFORMANCE) records its own trace in memory by default:
/// every function entry and exit on its threads takes a mutex, reads the clock and copies the
/// function's name into a ring of trace entries, and every packet's protocol line is formatted with
/// vsnprintf, whether or not anything ever reads the ring (only MQTT_C_CLIENT_TRACE prints it).
/// With the level at ERROR that ring keeps only errors: what Paho's HIGH_PERFORMANCE build does by
/// default. Left alone when the operator asked for Paho's trace (MQTT_C_CLIENT_TRACE or
/// MQTT_C_CLIENT_TRACE_LEVEL set). Process-wide; the library reads the variables at its first client.
void QuietPahoTrace() {
  if (std::getenv("MQTT_C_CLIENT_TRACE") || std::getenv("MQTT_C_CLIENT_TRACE_LEVEL")) return;
  MQTTAsync_setTraceLevel(MQTTASYNC_TRACE_ERROR);
}

bool IsTls(const std::string& uri) {
  return uri.rfind("ssl://", 0) == 0 || uri.rfind("mqtts://", 0) == 0 || uri.rfind("wss://", 0) == 0;
}
}  // namespace

PahoLink::PahoLink(LinkOptions options) {
  try {
    impl_ = std::make_unique<Impl>(std::move(options));
  } catch (const ::mqtt::exception& e) {
    throw std::runtime_error("broker: " + std::string(e.what()));
  }
  QuietPahoTrace();  // after the client: its creation initialises Paho's trace settings
  Impl& im = *impl_;
  auto& co = im.connect_options;
  co.set_clean_session(im.options.clean_session);
  co.set_keep_alive_interval(im.options.keep_alive_s);
  co.set_connect_timeout(10);
  co.set_max_inflight(1000);
  co.set_automatic_reconnect(false);  // Poll() reconnects with our own backoff
  if (!im.options.username.empty()) {
    co.set_user_name(im.options.username);
    co.set_password(im.options.password);
  }
  if (!im.options.will.topic.empty()) {
    co.set_will(
        ::mqtt::will_options(im.options.will.topic, im.options.will.payload, im.options.will.qos, im.options.will.retained));
  }
  if (IsTls(im.options.uri)) {
    ::mqtt::ssl_options ssl;
    if (!im.options.tls_ca.empty()) ssl.set_trust_store(im.options.tls_ca);
    ssl.set_enable_server_cert_auth(true);
    co.set_ssl(std::move(ssl));
  }
  // Callbacks run on Paho's threads: they only queue.
  im.client.set_connected_handler([&im](const std::string&) {
    im.connected = true;
    im.Push({LinkEvent::Kind::kConnected, "", ""});
  });
  im.client.set_connection_lost_handler([&im](const std::string& cause) {
    im.connected = false;
    im.Push({LinkEvent::Kind::kDisconnected, "", cause.empty() ? "connection lost" : cause});
  });
  im.client.set_message_callback([&im](::mqtt::const_message_ptr msg) {
    im.Push({LinkEvent::Kind::kMessage, msg->get_topic(), msg->to_string()});
  });
}

PahoLink::~PahoLink() {
  if (!impl_) return;
  // Destroying the client while a connect is in flight crashes Paho's C library
  // (eclipse-paho/paho.mqtt.c#220): an attempt still going (the broker unreachable at shutdown) is
  // waited out first; its connect timeout (10 s) ends it.
  try {
    if (impl_->pending_connect) impl_->pending_connect->wait_for(std::chrono::seconds(15));
  } catch (const std::exception&) {
    // It failed: nothing in flight any more.
  }
  try {
    if (impl_->client.is_connected()) impl_->client.disconnect(0)->wait_for(std::chrono::seconds(2));
  } catch (const std::exception&) {
  }
}

std::vector<LinkEvent> PahoLink::Poll(int64_t now_ms) {
  Impl& im = *impl_;
  std::vector<LinkEvent> out;
  if (im.pending_connect && im.pending_connect->is_complete()) {
    const int rc = im.pending_connect->get_return_code();
    im.pending_connect.reset();
    // rc 0: connected (the connected handler may run just before or after the token completes).
    if (rc != 0) {
      const std::string why = ::mqtt::exception::error_str(rc) + " (code " + std::to_string(rc) + ")";
      const int64_t wait = im.schedule.Failed(now_ms);
      out.push_back({LinkEvent::Kind::kDisconnected, "",
                     "connect to " + im.options.uri + " failed: " + why + "; retrying in " + std::to_string(wait) + " ms"});
    }
  }
  if (im.wake.fd >= 0) {
    uint64_t count = 0;
    (void)!read(im.wake.fd, &count, sizeof count);
  }
  std::deque<LinkEvent> queued;
  {
    std::lock_guard<std::mutex> lock(im.mutex);
    queued.swap(im.events);
  }
  for (LinkEvent& e : queued) {
    if (e.kind == LinkEvent::Kind::kConnected) {
      NoDelayOnTcpSockets();
      im.schedule.Connected(now_ms);
      try {
        for (const std::string& filter : im.options.subscriptions) im.client.subscribe(filter, 1);
      } catch (const ::mqtt::exception& ex) {
        out.push_back({LinkEvent::Kind::kDisconnected, "", std::string("subscribe failed: ") + ex.what()});
      }
    } else if (e.kind == LinkEvent::Kind::kDisconnected) {
      im.schedule.Lost(now_ms);
    }
    out.push_back(std::move(e));
  }
  if (!im.connected && !im.pending_connect && im.schedule.Due(now_ms)) {
    const ConnectSchedule::Attempt attempt = im.schedule.Start();
    im.connect_options.set_clean_session(attempt.clean_session);
    if (!attempt.notice.empty()) out.push_back({LinkEvent::Kind::kDisconnected, "", attempt.notice});
    try {
      im.pending_connect = im.client.connect(im.connect_options);
    } catch (const ::mqtt::exception& ex) {
      out.push_back({LinkEvent::Kind::kDisconnected, "", std::string("connect: ") + ex.what()});
      im.schedule.Failed(now_ms);
    }
  }
  return out;
}

void PahoLink::Reconnect(const std::string& reason) {
  Impl& im = *impl_;
  im.connected = false;
  try {
    if (im.client.is_connected()) im.client.disconnect(0)->wait_for(std::chrono::milliseconds(1000));
  } catch (const std::exception&) {
    // Already going: Poll() connects again either way.
  }
  im.Push({LinkEvent::Kind::kDisconnected, "", reason});
}

void PahoLink::Shutdown(const OutMessage& final_message, int timeout_ms) {
  Impl& im = *impl_;
  try {
    if (!im.client.is_connected()) return;
    if (!final_message.topic.empty()) {
      im.client
          .publish(final_message.topic, final_message.payload.data(), final_message.payload.size(), final_message.qos,
                   final_message.retained)
          ->wait_for(std::chrono::milliseconds(timeout_ms));
    }
    im.client.disconnect(timeout_ms)->wait_for(std::chrono::milliseconds(timeout_ms));
  } catch (const std::exception&) {
    // Best effort: the broker publishes the last will if the goodbye did not get through.
  }
  im.connected = false;
}

bool PahoLink::DoPublish(const OutMessage& message) {
  Impl& im = *impl_;
  if (!im.connected) return false;
  try {
    im.client.publish(message.topic, message.payload.data(), message.payload.size(), message.qos, message.retained);
    return true;
  } catch (const ::mqtt::exception&) {
    return false;
  }
}

int PahoLink::wake_fd() const {
  return impl_->wake.fd;
}

bool PahoLink::DoIsConnected() const {
  return impl_->connected;
}

}  // namespace lw::mqtt
