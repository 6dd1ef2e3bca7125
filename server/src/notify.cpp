#include "server/notify.hpp"

#include <curl/curl.h>
#include <pthread.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <sstream>

#include "core/cmdline.hpp"
#include "core/hmac.hpp"
#include "core/time.hpp"
#include "server/alarms.hpp"
#include "server/metrics.hpp"

namespace lw::server {
namespace {

using ordered_json = nlohmann::ordered_json;

constexpr int64_t kMaxCheckS = 5;  // new events are looked for at least this often (a Wake() lost to a race)
const std::set<std::string> kEvents{"raised", "acknowledged", "cleared"};

int64_t WallS() {
  return std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

/// Reads one "notifications" object, naming each key by its path in errors.
class Reader {
 public:
  explicit Reader(std::string where) : where_(std::move(where)) {}

  [[noreturn]] void Fail(const std::string& key, const std::string& why) const {
    throw core::ConfigFileError(where_ + ", key '" + key + "': " + why);
  }
  void Keys(const nlohmann::json& j, const std::string& key, const std::set<std::string>& allowed) const {
    if (!j.is_object()) Fail(key, "must be a JSON object");
    for (const auto& [k, v] : j.items()) {
      if (!allowed.count(k)) {
        std::string list;
        for (const std::string& a : allowed) list += (list.empty() ? "" : ", ") + a;
        Fail(key + "." + k, "unknown key (allowed: " + list + ")");
      }
    }
  }
  std::string Text(const nlohmann::json& j, const std::string& name, const std::string& key, bool required) const {
    if (!j.contains(name)) {
      if (required) Fail(key + "." + name, "is required");
      return "";
    }
    if (!j[name].is_string() || j[name].get<std::string>().empty()) Fail(key + "." + name, "must be a non-empty string");
    const std::string v = j[name].get<std::string>();
    // A header or an SMTP command cannot be split by a value that carries a line break.
    if (v.find_first_of("\r\n") != std::string::npos) Fail(key + "." + name, "must be one line");
    return v;
  }
  int64_t Whole(const nlohmann::json& j, const std::string& name, const std::string& key, int64_t fallback, int64_t min,
                int64_t max) const {
    if (!j.contains(name)) return fallback;
    const nlohmann::json& v = j[name];
    if (!v.is_number_integer() || v.get<int64_t>() < min || v.get<int64_t>() > max)
      Fail(key + "." + name,
           "must be a whole number in [" + std::to_string(min) + ", " + std::to_string(max) + "], not " + v.dump());
    return v.get<int64_t>();
  }
  std::string Url(const nlohmann::json& j, const std::string& key, const std::vector<std::string>& schemes) const {
    const std::string url = Text(j, key.substr(key.rfind('.') + 1), key.substr(0, key.rfind('.')), true);
    for (const std::string& s : schemes)
      if (url.rfind(s + "://", 0) == 0 && url.size() > s.size() + 3) return url;
    std::string list;
    for (const std::string& s : schemes) list += (list.empty() ? "" : " or ") + s + "://";
    Fail(key, "must start with " + list);
  }
  /// A secret given in the object or in a file (first line, whitespace around it dropped).
  std::string Secret(const nlohmann::json& j, const std::string& key, const std::string& inline_name,
                     const std::string& file_name, bool required) const {
    const bool has_inline = !inline_name.empty() && j.contains(inline_name), has_file = j.contains(file_name);
    if (has_inline && has_file) Fail(key, "give " + inline_name + " or " + file_name + ", not both");
    if (has_inline) return Text(j, inline_name, key, true);
    if (!has_file) {
      if (required) Fail(key + "." + (inline_name.empty() ? file_name : inline_name), "is required");
      return "";
    }
    const std::string path = Text(j, file_name, key, true);
    // One short line is read, no more: a path such as /dev/zero has no end of line, ever.
    constexpr size_t kMaxLine = 4096;
    std::ifstream in(path, std::ios::binary);
    std::string line;
    bool any = false;
    for (char ch; line.size() <= kMaxLine && in.get(ch) && ch != '\n'; any = true) line += ch;
    any = any || (in && line.empty());  // a first line that is empty, with a newline after it
    if (!any) Fail(key + "." + file_name, "cannot read '" + path + "'");
    if (line.size() > kMaxLine)
      Fail(key + "." + file_name, "the first line of '" + path + "' is longer than " + std::to_string(kMaxLine) + " bytes");
    const size_t b = line.find_first_not_of(" \t\r"), e = line.find_last_not_of(" \t\r");
    if (b == std::string::npos) Fail(key + "." + file_name, "'" + path + "' is empty");
    return line.substr(b, e - b + 1);
  }
  /// "ca_file": a readable file of PEM certificates, checked now so a typo is not found at the first alarm.
  std::string CaFile(const nlohmann::json& j, const std::string& key) const {
    if (!j.contains("ca_file")) return "";
    const std::string path = Text(j, "ca_file", key, true);
    std::ifstream in(path);
    if (!in) Fail(key + ".ca_file", "cannot read '" + path + "'");
    std::string line;
    while (std::getline(in, line))
      if (line.rfind("-----BEGIN CERTIFICATE-----", 0) == 0) return path;
    Fail(key + ".ca_file", "'" + path + "' holds no PEM certificate (-----BEGIN CERTIFICATE-----)");
  }
  std::set<std::string> Events(const nlohmann::json& j, const std::string& key) const {
    if (!j.contains("events")) return kEvents;
    const nlohmann::json& e = j["events"];
    if (!e.is_array() || e.empty()) Fail(key + ".events", "must be a non-empty array of raised, acknowledged, cleared");
    std::set<std::string> out;
    for (const nlohmann::json& v : e) {
      if (!v.is_string() || !kEvents.count(v.get<std::string>()))
        Fail(key + ".events", v.dump() + " is not an event (raised, acknowledged, cleared)");
      out.insert(v.get<std::string>());
    }
    return out;
  }
  void Address(const std::string& value, const std::string& key) const {
    // A bare address: the SMTP envelope takes it as it is.
    if (value.find('@') == std::string::npos || value.find_first_of(" \t\r\n<>,;\"") != std::string::npos)
      Fail(key, "'" + value + "' is not an e-mail address (name@domain, without a display name)");
  }

 private:
  std::string where_;
};

EmailTarget ParseEmail(const Reader& r, const nlohmann::json& j) {
  const std::string key = "notifications.email";
  r.Keys(j, key, {"smtp_url", "from", "to", "username", "password_file", "starttls", "ca_file", "events"});
  EmailTarget e;
  e.smtp_url = r.Url(j, key + ".smtp_url", {"smtp", "smtps"});
  e.from = r.Text(j, "from", key, true);
  r.Address(e.from, key + ".from");
  if (!j.contains("to") || !j["to"].is_array() || j["to"].empty())
    r.Fail(key + ".to", "must be a non-empty array of e-mail addresses");
  for (const nlohmann::json& t : j["to"]) {
    if (!t.is_string()) r.Fail(key + ".to", t.dump() + " is not a string");
    r.Address(t.get<std::string>(), key + ".to");
    e.to.push_back(t.get<std::string>());
  }
  e.username = r.Text(j, "username", key, false);
  e.password = r.Secret(j, key, "", "password_file", false);
  if (!e.password.empty() && e.username.empty()) r.Fail(key + ".username", "is required with password_file");
  if (j.contains("starttls")) {
    if (!j["starttls"].is_boolean()) r.Fail(key + ".starttls", "must be true or false");
    e.starttls = j["starttls"].get<bool>();
  }
  const bool tls_from_start = e.smtp_url.rfind("smtps://", 0) == 0;
  if (e.starttls && tls_from_start) r.Fail(key + ".starttls", "smtps:// is TLS from the start; starttls is for smtp:// URLs");
  // A password never crosses the network in clear text: libcurl would send AUTH PLAIN on a plain link.
  if (!e.password.empty() && !e.starttls && !tls_from_start)
    r.Fail(key + ".password_file", "a password needs TLS: set \"starttls\": true or use an smtps:// URL");
  e.ca_file = r.CaFile(j, key);
  e.events = r.Events(j, key);
  return e;
}

/// `url` without what may be a secret (user info, path, query): for logs.
std::string Redacted(const std::string& url) {
  const size_t scheme = url.find("://");
  if (scheme == std::string::npos) return "(url)";
  const size_t start = scheme + 3;
  size_t end = url.find_first_of("/?#", start);
  if (end == std::string::npos) end = url.size();
  std::string authority = url.substr(start, end - start);
  if (const size_t at = authority.rfind('@'); at != std::string::npos) authority = authority.substr(at + 1);
  return url.substr(0, start) + authority + (end < url.size() ? "/..." : "");
}

/// A header value on one line of printable text.
/// One line of text for a header or the body: control characters (CR, LF, tab, escapes) become
/// spaces, so no value from a radio or a broker message can add a line or end the message.
std::string HeaderText(std::string s) {
  for (char& c : s)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = ' ';
  return s;
}

std::string RfcDate(int64_t s) {
  const std::time_t t = static_cast<std::time_t>(s);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[64];
  std::strftime(buf, sizeof buf, "%a, %d %b %Y %H:%M:%S +0000", &tm);
  return buf;
}

std::string Number(const std::optional<double>& v) {
  if (!v) return "-";
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.1f", *v);
  return buf;
}

std::string DashboardLink(const NotificationConfig& config, const std::string& crusher) {
  if (config.dashboard_url.empty()) return "";
  std::string base = config.dashboard_url;
  while (!base.empty() && base.back() == '/') base.pop_back();
  return base + "/#/c/" + crusher;
}

/// The e-mail of one event: headers and a plain-text body a person can act on.
std::string EmailMessage(const NotificationConfig& config, const EmailTarget& email, const AlarmRecord& a,
                         const AlarmAuditEntry& event, int64_t event_id) {
  std::string to;
  for (const std::string& t : email.to) to += (to.empty() ? "" : ", ") + t;
  std::string upper = event.action;
  for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  const std::string domain = email.from.substr(email.from.find('@') + 1);
  const std::string link = DashboardLink(config, a.crusher);
  std::ostringstream m;
  m << "From: " << email.from << "\r\n"
    << "To: " << to << "\r\n"
    << "Subject: "
    << HeaderText("[linerwatch] " + upper + " " + a.severity + ": " + a.rule + " on " + a.crusher + " (" + a.subject + ")")
    << "\r\n"
    << "Date: " << RfcDate(event.time_s) << "\r\n"
    << "Message-ID: <linerwatch-event-" << event_id << "@" << HeaderText(domain) << ">\r\n"
    << "MIME-Version: 1.0\r\n"
    << "Content-Type: text/plain; charset=utf-8\r\n"
    << "Content-Transfer-Encoding: 8bit\r\n"
    << "\r\n"
    << "Alarm " << event.action << " on crusher " << a.crusher << ".\r\n\r\n"
    << "Rule:       " << HeaderText(a.rule) << " (" << HeaderText(a.subject) << ")\r\n"
    << "Severity:   " << HeaderText(a.severity) << "\r\n"
    << "State:      " << HeaderText(a.state) << "\r\n"
    << "Detail:     " << HeaderText(a.detail) << "\r\n"
    << "Value:      " << Number(a.value) << " (threshold " << Number(a.threshold) << ")\r\n"
    << "Since:      " << core::FormatIsoSeconds(a.since_s) << "\r\n"
    << "Event:      " << event.action << " at " << core::FormatIsoSeconds(event.time_s) << " by " << HeaderText(event.by)
    << "\r\n"
    << "Alarm id:   " << a.id << " (event " << event_id << ")\r\n";
  if (!link.empty()) m << "Dashboard:  " << link << "\r\n";
  if (event.action != "cleared")
    m << "\r\nAcknowledge it on the dashboard, or: POST /api/v1/crushers/" << a.crusher << "/alarms/" << a.id << "/ack\r\n";
  return m.str();
}

/// Stops a transfer when `cancel` is set (the server is stopping).
int Progress(void* cancel, curl_off_t, curl_off_t, curl_off_t, curl_off_t) {
  return cancel && static_cast<const std::atomic<bool>*>(cancel)->load() ? 1 : 0;
}

/// One libcurl transfer's handle, headers and recipients, freed on every way out.
struct Curl {
  CURL* h = curl_easy_init();
  curl_slist* headers = nullptr;
  curl_slist* recipients = nullptr;
  char error[CURL_ERROR_SIZE] = {0};
  Curl(int64_t timeout_s, const std::atomic<bool>* cancel) {
    if (!h) return;
    curl_easy_setopt(h, CURLOPT_NOSIGNAL, 1L);  // a thread of a server: no SIGALRM for the DNS timeout
    curl_easy_setopt(h, CURLOPT_TIMEOUT, static_cast<long>(timeout_s));
    curl_easy_setopt(h, CURLOPT_CONNECTTIMEOUT, static_cast<long>(timeout_s));
    curl_easy_setopt(h, CURLOPT_ERRORBUFFER, error);
    curl_easy_setopt(h, CURLOPT_NOPROGRESS, 0L);
    curl_easy_setopt(h, CURLOPT_XFERINFOFUNCTION, Progress);
    curl_easy_setopt(h, CURLOPT_XFERINFODATA, const_cast<std::atomic<bool>*>(cancel));
  }
  ~Curl() {
    curl_slist_free_all(headers);
    curl_slist_free_all(recipients);
    if (h) curl_easy_cleanup(h);
  }
  Curl(const Curl&) = delete;
  Curl& operator=(const Curl&) = delete;
  std::string Error(CURLcode code) const { return error[0] ? std::string(error) : curl_easy_strerror(code); }
};

size_t Discard(char*, size_t size, size_t n, void*) {
  return size * n;
}

struct Upload {
  const std::string* text;
  size_t at = 0;
};
size_t ReadUpload(char* out, size_t size, size_t n, void* data) {
  Upload& u = *static_cast<Upload*>(data);
  const size_t len = std::min(size * n, u.text->size() - u.at);
  std::copy_n(u.text->data() + u.at, len, out);
  u.at += len;
  return len;
}

void CurlGlobalInit() {
  static const CURLcode once = curl_global_init(CURL_GLOBAL_DEFAULT);
  (void)once;
}

}  // namespace

NotificationConfig ParseNotificationConfig(const nlohmann::json& j, const std::string& where) {
  const Reader r(where);
  r.Keys(j, "notifications", {"webhooks", "email", "dashboard_url", "retry_initial_s", "retry_max_s", "timeout_s"});
  NotificationConfig c;
  if (j.contains("webhooks")) {
    if (!j["webhooks"].is_array()) r.Fail("notifications.webhooks", "must be an array of {url, secret}");
    for (size_t i = 0; i < j["webhooks"].size(); ++i) {
      const std::string key = "notifications.webhooks[" + std::to_string(i) + "]";
      const nlohmann::json& w = j["webhooks"][i];
      r.Keys(w, key, {"url", "secret", "secret_file", "ca_file", "events"});
      WebhookTarget t;
      t.url = r.Url(w, key + ".url", {"http", "https"});
      for (const WebhookTarget& other : c.webhooks)
        if (other.url == t.url) r.Fail(key + ".url", "names the same URL as an earlier webhook");
      t.secret = r.Secret(w, key, "secret", "secret_file", true);
      t.ca_file = r.CaFile(w, key);
      t.events = r.Events(w, key);
      c.webhooks.push_back(std::move(t));
    }
  }
  if (j.contains("email")) c.email = ParseEmail(r, j["email"]);
  if (j.contains("dashboard_url")) c.dashboard_url = r.Url(j, "notifications.dashboard_url", {"http", "https"});
  c.retry_initial_s = r.Whole(j, "retry_initial_s", "notifications", c.retry_initial_s, 1, 86'400);
  c.retry_max_s =
      r.Whole(j, "retry_max_s", "notifications", std::max(c.retry_max_s, c.retry_initial_s), c.retry_initial_s, 86'400);
  c.timeout_s = r.Whole(j, "timeout_s", "notifications", c.timeout_s, 1, 600);
  return c;
}

int64_t RetryDelay(const NotificationConfig& config, int64_t attempts) {
  int64_t delay = config.retry_initial_s;
  for (int64_t i = 1; i < attempts && delay < config.retry_max_s; ++i) delay *= 2;
  return std::min(delay, config.retry_max_s);
}

std::vector<QueuedNotification> MakeNotifications(const NotificationConfig& config, const AlarmRecord& alarm,
                                                  const AlarmAuditEntry& event, int64_t event_id) {
  std::vector<QueuedNotification> out;
  const std::string link = DashboardLink(config, alarm.crusher);
  const std::string body = ordered_json{{"event", event.action},
                                        {"event_id", event_id},
                                        {"time", core::FormatIsoSeconds(event.time_s)},
                                        {"by", event.by},
                                        {"crusher", alarm.crusher},
                                        {"alarm", AlarmJson(alarm)},
                                        {"dashboard", link.empty() ? ordered_json(nullptr) : ordered_json(link)}}
                               .dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  for (const WebhookTarget& w : config.webhooks)
    if (w.events.count(event.action)) out.push_back({"webhook", w.url, body});
  if (config.email && config.email->events.count(event.action))
    out.push_back({"email", config.email->smtp_url, EmailMessage(config, *config.email, alarm, event, event_id)});
  return out;
}

SendResult SendWebhook(const WebhookTarget& hook, const std::string& body, int64_t event_id, int64_t delivery_id,
                       int64_t timeout_s, const std::atomic<bool>* cancel) {
  CurlGlobalInit();
  Curl c(timeout_s, cancel);
  if (!c.h) return {false, "curl_easy_init failed"};
  for (const std::string& h : std::vector<std::string>{"Content-Type: application/json", "User-Agent: linerwatch-server",
                                                       "X-Linerwatch-Signature: sha256=" + core::HmacSha256Hex(hook.secret, body),
                                                       "X-Linerwatch-Event: " + std::to_string(event_id),
                                                       "X-Linerwatch-Delivery: " + std::to_string(delivery_id)})
    c.headers = curl_slist_append(c.headers, h.c_str());
  curl_easy_setopt(c.h, CURLOPT_URL, hook.url.c_str());
  curl_easy_setopt(c.h, CURLOPT_PROTOCOLS_STR, "http,https");
  if (!hook.ca_file.empty()) curl_easy_setopt(c.h, CURLOPT_CAINFO, hook.ca_file.c_str());
  curl_easy_setopt(c.h, CURLOPT_HTTPHEADER, c.headers);
  curl_easy_setopt(c.h, CURLOPT_POST, 1L);
  curl_easy_setopt(c.h, CURLOPT_POSTFIELDS, body.data());
  curl_easy_setopt(c.h, CURLOPT_POSTFIELDSIZE_LARGE, static_cast<curl_off_t>(body.size()));
  curl_easy_setopt(c.h, CURLOPT_WRITEFUNCTION, Discard);
  const CURLcode code = curl_easy_perform(c.h);
  if (code != CURLE_OK) return {false, c.Error(code)};
  long status = 0;
  curl_easy_getinfo(c.h, CURLINFO_RESPONSE_CODE, &status);
  if (status < 200 || status > 299) return {false, "HTTP " + std::to_string(status)};
  return {true, ""};
}

SendResult SendEmail(const EmailTarget& email, const std::string& message, int64_t timeout_s, const std::atomic<bool>* cancel) {
  CurlGlobalInit();
  Curl c(timeout_s, cancel);
  if (!c.h) return {false, "curl_easy_init failed"};
  for (const std::string& t : email.to) c.recipients = curl_slist_append(c.recipients, ("<" + t + ">").c_str());
  const std::string from = "<" + email.from + ">";
  Upload upload{&message};
  curl_easy_setopt(c.h, CURLOPT_URL, email.smtp_url.c_str());
  curl_easy_setopt(c.h, CURLOPT_PROTOCOLS_STR, "smtp,smtps");
  curl_easy_setopt(c.h, CURLOPT_MAIL_FROM, from.c_str());
  curl_easy_setopt(c.h, CURLOPT_MAIL_RCPT, c.recipients);
  // STARTTLS required when asked: never a fall back to plain text after the server's answer.
  if (email.starttls) curl_easy_setopt(c.h, CURLOPT_USE_SSL, static_cast<long>(CURLUSESSL_ALL));
  if (!email.ca_file.empty()) curl_easy_setopt(c.h, CURLOPT_CAINFO, email.ca_file.c_str());
  if (!email.username.empty()) {
    curl_easy_setopt(c.h, CURLOPT_USERNAME, email.username.c_str());
    curl_easy_setopt(c.h, CURLOPT_PASSWORD, email.password.c_str());
  }
  curl_easy_setopt(c.h, CURLOPT_UPLOAD, 1L);
  curl_easy_setopt(c.h, CURLOPT_READFUNCTION, ReadUpload);
  curl_easy_setopt(c.h, CURLOPT_READDATA, &upload);
  const CURLcode code = curl_easy_perform(c.h);
  if (code != CURLE_OK) return {false, c.Error(code)};
  return {true, ""};
}

Notifier::Notifier(NotificationConfig config, const std::string& db, Log log, ServerMetrics* metrics)
    : config_(std::move(config)), store_(std::make_unique<Store>(db)), log_(std::move(log)), metrics_(metrics) {
  CurlGlobalInit();
  const int64_t pending = store_->CountPendingNotifications();
  if (metrics_) metrics_->SetNotificationsPending(pending);
  if (!config_.empty() || pending > 0) {
    log_("notifications: " + std::to_string(config_.webhooks.size()) + " webhook(s), e-mail " +
         (config_.email
              ? "to " + std::to_string(config_.email->to.size()) + " recipient(s) via " + Redacted(config_.email->smtp_url)
              : std::string("off")) +
         "; " + std::to_string(pending) + " pending from before");
  }
}

Notifier::~Notifier() {
  Stop();
}

void Notifier::Start() {
  thread_ = std::thread([this] {
    pthread_setname_np(pthread_self(), "lw-notify");
    Run();
  });
}

void Notifier::Stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);  // under the lock Run() waits with: the wake-up is not missed
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void Notifier::Wake() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    woken_ = true;
  }
  cv_.notify_all();
}

void Notifier::Run() {
  while (!stop_) {
    int64_t wait_s = kMaxCheckS;
    try {
      wait_s = Turn();
    } catch (const std::exception& e) {
      log_(std::string("notifications: ") + e.what() + " (retried in a few seconds)");
    }
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait_for(lock, std::chrono::seconds(std::clamp<int64_t>(wait_s, 0, kMaxCheckS)), [&] { return stop_ || woken_; });
    woken_ = false;
  }
}

SendResult Notifier::Send(const NotificationRecord& n) {
  if (n.channel == "webhook") {
    for (const WebhookTarget& w : config_.webhooks)
      if (w.url == n.target) return SendWebhook(w, n.body, n.audit, n.id, config_.timeout_s, &stop_);
  } else if (n.channel == "email" && config_.email && config_.email->smtp_url == n.target) {
    return SendEmail(*config_.email, n.body, config_.timeout_s, &stop_);
  }
  return {false, "not configured"};
}

void Notifier::SaveDelivered(const NotificationRecord& n, const std::string& what) {
  // The receiver has it: a busy database (a long commit, an operator's sqlite3) must not make it
  // pending again, or it would be sent twice. Retried until stored; only a stop leaves it (then
  // the next start sends it again, with the same event id, as after a crash).
  for (int attempt = 0; !stop_; ++attempt) {
    try {
      store_->SaveNotificationAttempt(n);
      return;
    } catch (const std::exception& e) {
      if (attempt == 0) log_(what + " delivered, not yet recorded: " + e.what() + " (retrying)");
    }
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait_for(lock, std::chrono::milliseconds(500), [&] { return stop_.load(); });
  }
}

int64_t Notifier::Turn() {
  store_->QueueNotifications(
      [&](const AlarmRecord& a, const AlarmAuditEntry& e, int64_t id) { return MakeNotifications(config_, a, e, id); });
  int64_t next_s = kMaxCheckS;
  bool delivered = false;
  for (NotificationRecord& n : store_->PendingNotifications()) {
    if (stop_) break;
    const bool configured = n.channel == "webhook" ? std::any_of(config_.webhooks.begin(), config_.webhooks.end(),
                                                                 [&](const WebhookTarget& w) { return w.url == n.target; })
                                                   : config_.email && config_.email->smtp_url == n.target;
    // Kept, not dropped: configured again (a typo fixed), the receiver gets what it missed.
    if (!configured) continue;
    const int64_t now = WallS();
    if (n.next_attempt_s > now) {
      next_s = std::min(next_s, n.next_attempt_s - now);
      continue;
    }
    const SendResult r = Send(n);
    if (stop_ && !r.ok) break;  // cancelled by Stop(): still pending, not an attempt
    ++n.attempts;
    const std::string what = "notification " + std::to_string(n.id) + " (" + n.event + ", event " + std::to_string(n.audit) +
                             ") to " + n.channel + " " + Redacted(n.target);
    if (r.ok) {
      n.state = "delivered";
      n.done_s = WallS();
      n.last_error.clear();
      delivered = true;
    } else {
      const int64_t delay = RetryDelay(config_, n.attempts);
      n.next_attempt_s = WallS() + delay;
      n.last_error = r.error;
      log_(what + ": attempt " + std::to_string(n.attempts) + " failed: " + r.error + "; next in " + std::to_string(delay) +
           " s");
      next_s = std::min(next_s, delay);
    }
    if (r.ok) {
      SaveDelivered(n, what);
    } else {
      store_->SaveNotificationAttempt(n);
    }
    if (r.ok) log_(what + " delivered (attempt " + std::to_string(n.attempts) + ")");
    if (metrics_) metrics_->CountNotification(n.channel, r.ok);
  }
  if (metrics_) metrics_->SetNotificationsPending(store_->CountPendingNotifications());
  return delivered ? 0 : next_s;  // a receiver's next notification right after the one it took
}

}  // namespace lw::server
