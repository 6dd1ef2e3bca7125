#pragma once
/// Notifications of alarm events (docs/alarms.md, *Notifications*): each raise, acknowledgement and
/// clear the alarm engine audits is queued in SQLite, one row per receiver (a webhook URL, the
/// e-mail), in one transaction with a cursor over the audit trail, and sent by a thread of its own
/// until the receiver takes it (a 2xx, an SMTP 250), with exponential backoff between attempts. A
/// receiver that is down, or a server restart, delays a notification but neither loses nor
/// repeats it (a repeat only if the server dies between the receiver's answer and its commit: each
/// notification carries its event's id for that case).
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "server/store.hpp"

namespace lw::server {

class ServerMetrics;

struct WebhookTarget {
  std::string url;      ///< http:// or https://
  std::string secret;   ///< the HMAC-SHA256 key of X-Linerwatch-Signature
  std::string ca_file;  ///< PEM certificates trusted for https (a private CA); empty: the system's
  std::set<std::string> events{"raised", "acknowledged", "cleared"};
};

struct EmailTarget {
  std::string smtp_url;  ///< smtp://host:port (STARTTLS with `starttls`) or smtps://host:port
  std::string from;
  std::vector<std::string> to;
  std::string username;  ///< empty: no login
  std::string password;  ///< read from password_file
  bool starttls = false;
  std::string ca_file;  ///< PEM certificates trusted for TLS (a private CA); empty: the system's
  std::set<std::string> events{"raised", "acknowledged", "cleared"};
};

/// The "notifications" object of the server's --config file.
struct NotificationConfig {
  std::vector<WebhookTarget> webhooks;
  std::optional<EmailTarget> email;
  std::string dashboard_url;  ///< the dashboard's base URL, for links; empty: none
  int64_t retry_initial_s = 10;
  int64_t retry_max_s = 3600;
  int64_t timeout_s = 10;  ///< each attempt's limit, connection included
  bool empty() const { return webhooks.empty() && !email; }
};

/// Reads the "notifications" object `j`; `where` names it in errors ("config FILE, key
/// 'notifications'"). Throws core::ConfigFileError naming the key and the bad value (an unknown
/// key, a wrong type, a URL of another scheme, an unreadable secret or password file). Secrets
/// are never in an error.
NotificationConfig ParseNotificationConfig(const nlohmann::json& j, const std::string& where);

/// The delay before attempt `attempts` + 1 after `attempts` failed ones: retry_initial_s doubled
/// per failure, at most retry_max_s.
int64_t RetryDelay(const NotificationConfig& config, int64_t attempts);

/// The notifications of one alarm event, as Store::QueueNotifications stores them: the webhook's
/// JSON body, the e-mail's whole message (RFC 5322, plain text), for every receiver that wants `event`.
std::vector<QueuedNotification> MakeNotifications(const NotificationConfig& config, const AlarmRecord& alarm,
                                                  const AlarmAuditEntry& event, int64_t event_id);

/// The outcome of one attempt.
struct SendResult {
  bool ok = false;
  std::string error;  ///< why not (a curl error, "HTTP 500"); never a secret
};
/// One webhook POST of `body` to `hook` (signed with its secret; `event_id`, `delivery_id` in headers), within `timeout_s`.
SendResult SendWebhook(const WebhookTarget& hook, const std::string& body, int64_t event_id, int64_t delivery_id,
                       int64_t timeout_s, const std::atomic<bool>* cancel = nullptr);
/// One e-mail `message` through `email`'s SMTP server, within `timeout_s`.
SendResult SendEmail(const EmailTarget& email, const std::string& message, int64_t timeout_s,
                     const std::atomic<bool>* cancel = nullptr);

/// The delivery thread. Its Store is its own connection, used on its thread only.
class Notifier {
 public:
  using Log = std::function<void(const std::string&)>;
  /// Opens `db`; logs what is pending from before (and for receivers no longer configured, kept).
  Notifier(NotificationConfig config, const std::string& db, Log log, ServerMetrics* metrics);
  ~Notifier();
  Notifier(const Notifier&) = delete;
  Notifier& operator=(const Notifier&) = delete;

  void Start();
  /// Ends the thread: an attempt under way is cancelled (the notification stays pending).
  void Stop();
  /// Alarms changed: queue and send now rather than at the next check (a few seconds at most).
  void Wake();

 private:
  void Run();
  /// Queues new events, then makes each due attempt; returns the seconds until the next one is due.
  int64_t Turn();
  void SaveDelivered(const NotificationRecord& n, const std::string& what);
  SendResult Send(const NotificationRecord& n);

  NotificationConfig config_;
  std::unique_ptr<Store> store_;
  Log log_;
  ServerMetrics* metrics_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::mutex mutex_;
  std::condition_variable cv_;
  bool woken_ = false;
};

}  // namespace lw::server
