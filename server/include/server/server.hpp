#pragma once
/// linerwatch-server: MQTT readings -> SQLite (exactly once) -> commit acks, live global wear
/// (retained `.../wear`), forecasts, REST and the dashboard.
#include <atomic>
#include <cstdint>
#include <ostream>
#include <string>
#include <vector>

#include "mqtt/topics.hpp"
#include "server/notify.hpp"

namespace lw::server {

struct ServerOptions {
  std::string broker;
  std::string db;
  std::string http = "127.0.0.1:8080";
  std::string crusher_dir;
  std::string tokens;
  std::string username;
  std::string password;
  std::string tls_ca;
  std::string client_id = "linerwatch-server";
  std::string topic_root{mqtt::kDefaultTopicPrefix};
  std::string web_dir;                     ///< default: the build's / installed dashboard folder
  std::string clock_file;                  ///< simulation: "now" (unix ms) is read from this file
  std::vector<std::string> allowed_hosts;  ///< host names the HTTP API answers to (besides addresses, localhost)
  int64_t wear_interval_ms = 1000;
  int64_t batch_max = 1000;
  int64_t commit_delay_ms = 5;       ///< group commit: wait this long for more readings before a commit
  NotificationConfig notifications;  ///< the --config file's "notifications" (docs/alarms.md); empty: none
  bool help = false;
};

/// Throws core::UsageError with a one-line reason.
ServerOptions ParseServerOptions(const std::vector<std::string>& args);
std::string ServerHelp();

/// Runs until `stop` becomes true. Logs to `log`. Throws std::runtime_error on a startup failure
/// (unreadable database, no crusher, port in use, bad tokens file).
void RunServer(const ServerOptions& options, const std::atomic<bool>& stop, std::ostream& log);

}  // namespace lw::server
