// linerwatch-gateway: XBee coordinator serial port -> SQLite spool -> MQTT (docs/gateway.md).
// One thread runs everything below; Paho's own threads only queue events for it (paho_link.cpp).
#include <fcntl.h>
#include <poll.h>
#include <sys/file.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/file_lock.hpp"
#include "core/clock.hpp"
#include "core/sd_notify.hpp"
#include "gateway/config.hpp"
#include "gateway/gateway.hpp"
#include "gateway/messages.hpp"
#include "gateway/metrics.hpp"
#include "gateway/serial_port.hpp"
#include "gateway/spool.hpp"
#include "mqtt/messages.hpp"
#include "mqtt/paho_link.hpp"
#include "mqtt/topics.hpp"
#include "metrics_server.hpp"

namespace {

/// Bytes of the serial port read and spooled together at most (a pty holds ~20 KiB waiting;
/// a real port at 115200 baud brings ~12 KiB a second).
constexpr size_t kSerialReadBytes = 64 * 1024;

volatile std::sig_atomic_t g_stop = 0;
void OnSignal(int) {
  g_stop = 1;
}

int64_t NowMs() {
  return lw::core::WallClockMs();
}

/// The retained `gateway/status` offline message (the last will and the goodbye).
std::string Offline(const std::string& gateway_id) {
  return lw::mqtt::EncodeStatus({false, gateway_id, lw::mqtt::IsoUtc(NowMs())});
}

void Log(const std::string& line) {
  // Lines carry text from the radio and the broker: the one log mechanism escapes them.
  static lw::core::Logger log(std::cerr, "linerwatch-gateway");
  log(line);
}

lw::gateway::GatewayOptions MakeGatewayOptions(const lw::gateway::Config& config, const lw::core::Clock& clock) {
  lw::gateway::GatewayOptions options;
  options.site = config.site;
  options.crusher = config.crusher;
  options.gateway_id = config.gateway_id;
  options.api_mode = config.api_mode == 1 ? lw::protocol::ApiMode::kUnescaped : lw::protocol::ApiMode::kEscaped;
  options.window = config.window;
  options.max_batch = config.max_batch;
  options.max_devices = config.max_devices;
  options.republish_after_ms = static_cast<int64_t>(config.republish_after_s * 1000);
  options.stats_interval_ms = static_cast<int64_t>(config.stats_interval_s * 1000);
  options.log = Log;
  if (clock.is_file()) {
    Log("reading times come from the virtual clock in " + config.clock_file + " (simulation)");
    options.stamp_clock = [&clock](int64_t) {
      const bool was_ok = clock.ok();
      const int64_t t = clock.NowMs();
      if (was_ok && !clock.ok()) Log("clock file " + clock.path() + ": unreadable or not Unix ms; using the last good time");
      return t;
    };
  }
  return options;
}

lw::mqtt::LinkOptions MakeLinkOptions(const lw::gateway::Config& config, const lw::mqtt::Topics& topics) {
  lw::mqtt::LinkOptions link_options;
  link_options.uri = config.broker;
  link_options.client_id = config.gateway_id;
  link_options.username = config.username;
  link_options.password = config.password;
  link_options.tls_ca = config.tls_ca;
  link_options.reconnect_min_ms = static_cast<int64_t>(config.reconnect_min_s * 1000);
  link_options.reconnect_max_ms = static_cast<int64_t>(config.reconnect_max_s * 1000);
  link_options.will = {topics.Status(), Offline(config.gateway_id), 1, true};
  link_options.subscriptions = {topics.CommittedFilter()};
  return link_options;
}

// What the loop keeps about the serial port between turns: its last error, when to try to
// open it again, and whether that failure is logged already (once until it opens).
struct SerialRetry {
  std::string error;
  int64_t next_open_ms = 0;
  bool reported_open_error = false;
};

void OpenSerialWhenDue(const lw::gateway::Config& config, lw::gateway::SerialPort& serial, lw::gateway::Gateway& gateway,
                       SerialRetry& retry, int64_t now) {
  if (!serial.is_open() && now >= retry.next_open_ms) {
    if (serial.Open(&retry.error)) {
      Log("serial " + config.serial + " open (" + std::to_string(config.baud) + " baud, API mode " +
          std::to_string(config.api_mode) + ")");
      retry.reported_open_error = false;
      gateway.OnRadioOpened(now);  // asks the coordinator for NP and EE
    } else {
      if (!retry.reported_open_error) Log(retry.error + " (retrying every 2 s)");
      retry.reported_open_error = true;
      retry.next_open_ms = now + 2000;
    }
  }
}

// Everything waiting, up to the buffer, in one go: its frames are spooled in one transaction
// (one fsync), however many reads of the port that takes. Then the link's events are served
// before the port is read again, so a busy serial line does not hold back publications.
void ReadSerial(const lw::gateway::Config& config, lw::gateway::SerialPort& serial, lw::gateway::Gateway& gateway,
                std::vector<uint8_t>& buffer, SerialRetry& retry, int64_t now) {
  const long n = serial.ReadWaiting(buffer.data(), buffer.size());
  if (n > 0) {
    gateway.OnBytes(buffer.data(), static_cast<size_t>(n), now);
  } else if (n == 0) {
    // A regular file at its end or a FIFO without writer polls ready forever: do not spin.
    ::poll(nullptr, 0, 100);
  } else {
    Log("serial " + config.serial + ": closed or failed; reopening");
    serial.Close();
    retry.next_open_ms = now + 1000;
  }
}

// Commit acks that came together are handled together (one spool transaction).
void ServeLink(const lw::gateway::Config& config, lw::mqtt::PahoLink& link, lw::gateway::Gateway& gateway, int64_t now) {
  using lw::mqtt::LinkEvent;
  std::vector<std::pair<std::string_view, std::string_view>> messages;
  const std::vector<LinkEvent> events = link.Poll(now);
  for (const LinkEvent& e : events) {
    if (e.kind == LinkEvent::Kind::kMessage) {
      messages.emplace_back(e.topic, e.payload);
      continue;
    }
    if (!messages.empty()) gateway.OnMessages(messages, now);
    messages.clear();
    switch (e.kind) {
      case LinkEvent::Kind::kConnected:
        Log("mqtt: connected to " + config.broker);
        gateway.OnConnected(now);
        break;
      case LinkEvent::Kind::kDisconnected:
        Log("mqtt: " + e.payload);
        break;
      case LinkEvent::Kind::kMessage:
        break;
    }
  }
  if (!messages.empty()) gateway.OnMessages(messages, now);
}

// Until SIGINT or SIGTERM: the serial port (re)opened and read, the link's events served, the
// spool pumped, the metrics published and a stalled link reset.
void Serve(const lw::gateway::Config& config, lw::gateway::SerialPort& serial, lw::mqtt::PahoLink& link,
           lw::gateway::Gateway& gateway, lw::gateway::MetricsServer* metrics) {
  SerialRetry retry;
  std::vector<uint8_t> buffer(kSerialReadBytes);
  while (!g_stop) {
    int64_t now = NowMs();
    OpenSerialWhenDue(config, serial, gateway, retry, now);
    pollfd fds[2] = {{link.wake_fd(), POLLIN, 0}, {serial.fd(), POLLIN, 0}};
    ::poll(fds, serial.is_open() ? 2 : 1, 100);
    now = NowMs();
    if (serial.is_open() && (fds[1].revents & (POLLIN | POLLHUP | POLLERR)))
      ReadSerial(config, serial, gateway, buffer, retry, now);
    ServeLink(config, link, gateway, now);
    gateway.Pump(now);
    if (metrics && metrics->Wanted()) metrics->Publish(lw::gateway::MetricsText(gateway, link.IsConnected()));
    if (gateway.LinkStalled(now)) {
      Log("mqtt: connected, but no reading publication was taken and no commit ack arrived for three "
          "republication periods while records wait: reconnecting");
      link.Reconnect("reconnecting: the connection carried nothing of QoS 1");
      gateway.OnLinkReset(now);
    }
  }
}

int Run(const lw::gateway::Config& config) {
  using namespace lw::gateway;
  // A missing port at start is a configuration error; once running, a vanished port (USB
  // adapter unplugged) is waited for instead.
  if (::access(config.serial.c_str(), F_OK) != 0) {
    std::fprintf(stderr, "linerwatch-gateway: error: --serial: %s does not exist\n", config.serial.c_str());
    return 2;
  }
  // One gateway per spool: a second instance would also steal bytes from the serial port.
  std::optional<lw::core::ExclusiveFileLock> spool_lock;
  try {
    spool_lock.emplace(config.spool, true, "linerwatch-gateway");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "linerwatch-gateway: error: spool %s\n", e.what());
    return 1;
  }
  Spool spool(config.spool, config.spool_max_records);
  Log("spool " + config.spool + ": " + std::to_string(spool.depth()) + " records waiting for a commit ack");

  SerialPort serial(config.serial, config.baud);
  const lw::core::Clock clock(config.clock_file);
  const GatewayOptions options = MakeGatewayOptions(config, clock);
  const lw::mqtt::Topics topics(config.site, config.crusher);
  auto link = std::make_unique<lw::mqtt::PahoLink>(MakeLinkOptions(config, topics));
  Gateway gateway(options, spool, *link, serial);
  std::unique_ptr<MetricsServer> metrics;
  if (!config.metrics.empty()) {
    metrics = std::make_unique<MetricsServer>(config.metrics);
    metrics->Publish(MetricsText(gateway, false));
    Log("metrics on " + metrics->url());
  }

  // Ready for systemd (Type=notify): the spool is open and locked; serial port and broker are
  // (re)opened by the loop below.
  lw::core::SdNotify("READY=1");
  Serve(config, serial, *link, gateway, metrics.get());
  Log("stopping; " + std::to_string(spool.depth()) + " records stay in the spool");
  link->Shutdown({topics.Status(), Offline(config.gateway_id), 1, true}, 2000);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  lw::gateway::Config config;
  try {
    const std::vector<std::string> args(argv, argv + argc);
    if (lw::gateway::ParseCommandLine(args, &config) == lw::gateway::ParseResult::kHelp) {
      std::fputs(lw::gateway::UsageText().c_str(), stdout);
      return 0;
    }
  } catch (const lw::gateway::ConfigError& e) {
    std::fprintf(stderr, "linerwatch-gateway: error: %s\n", e.what());
    return 2;
  }
  struct sigaction sa {};
  sa.sa_handler = OnSignal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  std::signal(SIGPIPE, SIG_IGN);
  try {
    return Run(config);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "linerwatch-gateway: error: %s\n", e.what());
    return 1;
  }
}
