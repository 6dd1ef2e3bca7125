// Notifications (server/notify.hpp, docs/alarms.md): the "notifications" config and its errors,
// the retry schedule, the outbox queued once per event across connections, and the Notifier's
// delivery to a webhook that fails first (cpp-httplib receiver in this process).
#include "server/notify.hpp"

#include <sqlite3.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <thread>

#include "core/cmdline.hpp"
#include "core/hmac.hpp"
#include "server/server.hpp"
#include "support/notify_receivers.hpp"
#include "support/temp_directory.hpp"

#include <CppUTest/TestHarness.h>  // last

using lw::server::NotificationConfig;
using lw::server::ParseNotificationConfig;
using nlohmann::json;

namespace {

/// The ConfigFileError message of parsing `j`, "" when it parses.
std::string Error(const json& j) {
  try {
    (void)ParseNotificationConfig(j, "config server.json");
  } catch (const lw::core::ConfigFileError& e) {
    return e.what();
  }
  return "";
}

void CheckError(const json& j, const std::string& expected) {
  const std::string e = Error(j);
  CHECK_TEXT(e.find(expected) != std::string::npos, ("expected '" + expected + "' in: '" + e + "'").c_str());
}

json Hook(const std::string& url = "https://example.com/hook") {
  return {{"url", url}, {"secret", "s"}};
}

lw::server::AlarmRecord Alarm() {
  lw::server::AlarmRecord a;
  a.crusher = "cr1";
  a.rule = "gateway_offline";
  a.subject = "gw1";
  a.severity = "warning";
  a.state = "active";
  a.since_s = 1'796'600'000;
  a.detail = "gateway gw1 offline since then";
  a.value = 61;
  a.threshold = 30;
  return a;
}

}  // namespace

TEST_GROUP(NotifyConfig){};

TEST(NotifyConfig, AFullConfigIsRead) {
  lw::test::TempDirectory dir;
  std::ofstream(dir.File("pw")) << "  hunter2\n";
  const NotificationConfig c =
      ParseNotificationConfig({{"webhooks", {Hook(), {{"url", "http://127.0.0.1:9/x"}, {"secret", "t"}, {"events", {"raised"}}}}},
                               {"email",
                                {{"smtp_url", "smtp://mail:587"},
                                 {"from", "lw@example.com"},
                                 {"to", {"a@example.com", "b@example.com"}},
                                 {"username", "lw"},
                                 {"password_file", dir.File("pw")},
                                 {"starttls", true}}},
                               {"dashboard_url", "http://dash/"},
                               {"retry_initial_s", 5},
                               {"retry_max_s", 60}},
                              "config server.json");
  LONGS_EQUAL(2, c.webhooks.size());
  LONGS_EQUAL(1, c.webhooks[1].events.size());
  CHECK_TRUE(c.email.has_value());
  STRCMP_EQUAL("hunter2", c.email->password.c_str());
  CHECK_TRUE(c.email->starttls);
  LONGS_EQUAL(2, c.email->to.size());
  LONGS_EQUAL(5, lw::server::RetryDelay(c, 1));
  LONGS_EQUAL(10, lw::server::RetryDelay(c, 2));
  LONGS_EQUAL(40, lw::server::RetryDelay(c, 4));
  LONGS_EQUAL(60, lw::server::RetryDelay(c, 5));
  LONGS_EQUAL(60, lw::server::RetryDelay(c, 500));
}

TEST(NotifyConfig, EachBadKeyOrValueIsNamed) {
  CheckError({{"webhook", json::array()}}, "key 'notifications.webhook': unknown key");
  CheckError({{"webhooks", {{{"url", "ftp://x/y"}, {"secret", "s"}}}}},
             "key 'notifications.webhooks[0].url': must start with http:// or https://");
  CheckError({{"webhooks", {{{"url", "https://x/y"}}}}}, "key 'notifications.webhooks[0].secret': is required");
  CheckError({{"webhooks", {Hook(), Hook()}}}, "key 'notifications.webhooks[1].url': names the same URL");
  CheckError({{"webhooks", {{{"url", "https://x/y"}, {"secret", "s"}, {"events", {"fired"}}}}}},
             "key 'notifications.webhooks[0].events': \"fired\" is not an event");
  CheckError({{"email", {{"smtp_url", "http://mail"}, {"from", "a@b"}, {"to", {"c@d"}}}}},
             "key 'notifications.email.smtp_url': must start with smtp:// or smtps://");
  CheckError({{"email", {{"smtp_url", "smtp://mail"}, {"from", "a@b"}, {"to", json::array()}}}},
             "key 'notifications.email.to': must be a non-empty array");
  CheckError({{"email", {{"smtp_url", "smtp://mail"}, {"from", "Ops <a@b>"}, {"to", {"c@d"}}}}},
             "key 'notifications.email.from': 'Ops <a@b>' is not an e-mail address");
  CheckError({{"email", {{"smtp_url", "smtp://mail"}, {"from", "a@b"}, {"to", {"c@d"}}, {"password_file", "/nonexistent/pw"}}}},
             "key 'notifications.email.password_file': cannot read '/nonexistent/pw'");
  CheckError({{"email", {{"smtp_url", "smtp://mail"}, {"from", "a@b"}, {"to", {"c@d"}}, {"starttls", "yes"}}}},
             "key 'notifications.email.starttls': must be true or false");
  // A password never goes in clear text; a private CA's file is read at start, not at the first alarm.
  {
    lw::test::TempDirectory dir;
    std::ofstream(dir.File("pw")) << "hunter2\n";
    std::ofstream(dir.File("not.pem")) << "hello\n";
    CheckError(
        {{"email",
          {{"smtp_url", "smtp://mail"}, {"from", "a@b"}, {"to", {"c@d"}}, {"username", "u"}, {"password_file", dir.File("pw")}}}},
        "key 'notifications.email.password_file': a password needs TLS: set \"starttls\": true or use an smtps:// URL");
    CheckError({{"email", {{"smtp_url", "smtps://mail"}, {"from", "a@b"}, {"to", {"c@d"}}, {"ca_file", "/nonexistent/ca.pem"}}}},
               "key 'notifications.email.ca_file': cannot read '/nonexistent/ca.pem'");
    CheckError({{"webhooks", {{{"url", "https://x/y"}, {"secret", "s"}, {"ca_file", dir.File("not.pem")}}}}},
               "key 'notifications.webhooks[0].ca_file': '" + dir.File("not.pem") + "' holds no PEM certificate");
  }
  CheckError({{"retry_initial_s", 0}}, "key 'notifications.retry_initial_s': must be a whole number in [1, 86400], not 0");
  CheckError({{"timeout_s", 1.5}}, "key 'notifications.timeout_s': must be a whole number");
  CheckError({{"webhooks", {{{"url", "https://x/y"}, {"secret", "a\r\nX-Evil: 1"}}}}},
             "key 'notifications.webhooks[0].secret': must be one line");
  CheckError(json::array(), "key 'notifications': must be a JSON object");
  // Secrets are never in an error.
  const std::string e = Error({{"webhooks", {{{"url", "https://x/y"}, {"secret", "topsecret"}, {"extra", 1}}}}});
  CHECK(e.find("topsecret") == std::string::npos);
  CHECK(e.find("notifications.webhooks[0].extra") != std::string::npos);
}

// A secret file is read for its first line only, and that line is short: a path such as /dev/zero
// (no newline, ever) was read until memory ran out.
TEST(NotifyConfig, ASecretFileIsReadForOneShortLineOnly) {
  CheckError({{"webhooks", {{{"url", "https://x/y"}, {"secret_file", "/dev/zero"}}}}},
             "key 'notifications.webhooks[0].secret_file': the first line of '/dev/zero' is longer than 4096 bytes");
  lw::test::TempDirectory dir("lw-notify-secret");
  const std::string file = dir.Write("secret", "  k3y \nsecond line ignored\n").string();
  const NotificationConfig c =
      ParseNotificationConfig({{"webhooks", {{{"url", "https://x/y"}, {"secret_file", file}}}}}, "config s.json");
  STRCMP_EQUAL("k3y", c.webhooks.at(0).secret.c_str());
  CheckError({{"webhooks", {{{"url", "https://x/y"}, {"secret_file", dir.Write("empty", "").string()}}}}}, "cannot read");
  CheckError({{"webhooks", {{{"url", "https://x/y"}, {"secret_file", dir.Write("blank", " \t\n").string()}}}}}, "is empty");
}

TEST(NotifyConfig, TheServersConfigFileTakesNotificationsAndRefusesOtherObjects) {
  lw::test::TempDirectory dir;
  const std::string path = dir.File("server.json");
  const std::vector<std::string> args{"--broker", "tcp://h:1", "--db", "x", "--crusher-dir", "d", "--config", path};
  std::ofstream(path) << json{{"notifications", {{"webhooks", {Hook()}}}}}.dump();
  const lw::server::ServerOptions o = lw::server::ParseServerOptions(args);
  LONGS_EQUAL(1, o.notifications.webhooks.size());
  std::ofstream(path) << json{{"notification", json::object()}}.dump();
  try {
    (void)lw::server::ParseServerOptions(args);
    FAIL("an unknown key was taken");
  } catch (const lw::core::ConfigFileError& e) {
    STRCMP_EQUAL(("config " + path + ": unknown key 'notification' (see --help)").c_str(), e.what());
  }
  std::ofstream(path) << json{{"notifications", {{"webhooks", {{{"url", "x"}, {"secret", "s"}}}}}}}.dump();
  try {
    (void)lw::server::ParseServerOptions(args);
    FAIL("a bad URL was taken");
  } catch (const lw::core::ConfigFileError& e) {
    STRCMP_CONTAINS(("config " + path + ", key 'notifications.webhooks[0].url'").c_str(), e.what());
  }
}

TEST_GROUP(NotifyMessages){};

TEST(NotifyMessages, TheWebhookBodyAndTheEmailSayWhatHappened) {
  NotificationConfig c = ParseNotificationConfig(
      {{"webhooks", {Hook()}},
       {"email", {{"smtp_url", "smtp://mail"}, {"from", "lw@example.com"}, {"to", {"ops@example.com"}}, {"events", {"raised"}}}},
       {"dashboard_url", "http://dash:8080/"}},
      "x");
  lw::server::AlarmRecord a = Alarm();
  a.id = 7;
  auto out = lw::server::MakeNotifications(c, a, {7, a.since_s, "raised", "server", a.detail}, 42);
  LONGS_EQUAL(2, out.size());
  const json body = json::parse(out[0].body);
  STRCMP_EQUAL("raised", body["event"].get<std::string>().c_str());
  LONGS_EQUAL(42, body["event_id"].get<int64_t>());
  LONGS_EQUAL(7, body["alarm"]["id"].get<int64_t>());
  STRCMP_EQUAL("http://dash:8080/#/c/cr1", body["dashboard"].get<std::string>().c_str());
  const std::string& mail = out[1].body;
  STRCMP_CONTAINS("Subject: [linerwatch] RAISED warning: gateway_offline on cr1 (gw1)\r\n", mail.c_str());
  STRCMP_CONTAINS("Message-ID: <linerwatch-event-42@example.com>\r\n", mail.c_str());
  STRCMP_CONTAINS("Value:      61.0 (threshold 30.0)\r\n", mail.c_str());
  STRCMP_CONTAINS("Dashboard:  http://dash:8080/#/c/cr1\r\n", mail.c_str());
  STRCMP_CONTAINS("POST /api/v1/crushers/cr1/alarms/7/ack", mail.c_str());
  // The e-mail wants raised only; the webhook every event.
  out = lw::server::MakeNotifications(c, a, {7, a.since_s, "cleared", "server", ""}, 43);
  LONGS_EQUAL(1, out.size());
  STRCMP_EQUAL("webhook", out[0].channel.c_str());
}

TEST_GROUP(NotifyDelivery) {
  lw::test::TempDirectory dir;
};

TEST(NotifyDelivery, EachEventIsQueuedOnceWhateverTheConnection) {
  const std::string db = dir.File("db.sqlite");
  lw::server::Store a(db), b(db);
  const NotificationConfig c = ParseNotificationConfig({{"webhooks", {Hook()}}}, "x");
  const auto make = [&](const lw::server::AlarmRecord& r, const lw::server::AlarmAuditEntry& e, int64_t id) {
    return lw::server::MakeNotifications(c, r, e, id);
  };
  const lw::server::AlarmRecord alarm = Alarm();
  const int64_t id = a.SaveAlarm(alarm, {0, alarm.since_s, "raised", "server", alarm.detail});
  LONGS_EQUAL(1, a.QueueNotifications(make));
  LONGS_EQUAL(0, b.QueueNotifications(make));
  LONGS_EQUAL(0, a.QueueNotifications(make));
  lw::server::AlarmRecord cleared = alarm;
  cleared.id = id;
  cleared.state = "cleared";
  cleared.cleared_s = alarm.since_s + 60;
  a.SaveAlarm(cleared, {0, alarm.since_s + 60, "cleared", "server", ""});
  LONGS_EQUAL(1, b.QueueNotifications(make));
  const auto rows = a.Notifications(10);
  LONGS_EQUAL(2, rows.size());
  STRCMP_EQUAL("raised", rows[0].event.c_str());
  STRCMP_EQUAL("cleared", rows[1].event.c_str());
  // Only the oldest pending one per receiver is offered: its events go in order.
  LONGS_EQUAL(1, a.PendingNotifications().size());
  LONGS_EQUAL(rows[0].id, a.PendingNotifications()[0].id);
}

TEST(NotifyDelivery, AFailingWebhookGetsTheEventOnceItAnswers2xxAndNotAgainAfterARestart) {
  const std::string db = dir.File("db.sqlite");
  lw::test::WebhookReceiver hook;
  hook.Answer(500);
  hook.Start();
  NotificationConfig c = ParseNotificationConfig(
      {{"webhooks", {{{"url", hook.url()}, {"secret", "k"}}}}, {"retry_initial_s", 1}, {"retry_max_s", 1}}, "x");
  std::vector<std::string> log;
  std::mutex log_mutex;
  const auto logger = [&](const std::string& line) {
    std::lock_guard<std::mutex> lock(log_mutex);
    log.push_back(line);
  };
  {
    lw::server::Store s(db);
    const lw::server::AlarmRecord alarm = Alarm();
    s.SaveAlarm(alarm, {0, alarm.since_s, "raised", "server", alarm.detail});
  }
  {
    lw::server::Notifier n(c, db, logger, nullptr);
    n.Start();
    for (int i = 0; i < 300 && hook.answered() < 2; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    CHECK(hook.answered() >= 2);
    LONGS_EQUAL(0, hook.Posts().size());
    hook.Answer(200);
    for (int i = 0; i < 300 && hook.Posts().empty(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    n.Stop();
  }
  LONGS_EQUAL(1, hook.Posts().size());
  const auto post = hook.Posts().front();
  STRCMP_EQUAL(("sha256=" + lw::core::HmacSha256Hex("k", post.body)).c_str(), post.headers.at("X-Linerwatch-Signature").c_str());
  lw::server::Store s(db);
  const auto rows = s.Notifications(10);
  LONGS_EQUAL(1, rows.size());
  STRCMP_EQUAL("delivered", rows[0].state.c_str());
  CHECK(rows[0].attempts >= 3);
  STRCMP_EQUAL(std::to_string(rows[0].id).c_str(), post.headers.at("X-Linerwatch-Delivery").c_str());
  {
    lw::server::Notifier again(c, db, logger, nullptr);  // a restart: nothing pending, nothing sent
    again.Start();
    std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  }
  LONGS_EQUAL(1, hook.Posts().size());
  for (const std::string& line : log) CHECK_TEXT(line.find("/hook") == std::string::npos, line.c_str());  // paths redacted
}

// A value from a radio or a broker message (a gateway id, a detail) cannot add lines to an e-mail
// or end it early; an address with a line break is refused at startup.
TEST(NotifyMessages, NoFieldCanAddALineToTheMail) {
  const NotificationConfig c =
      ParseNotificationConfig({{"email", {{"smtp_url", "smtp://mail"}, {"from", "a@b.c"}, {"to", {"ops@example.com"}}}}}, "x");
  lw::server::AlarmRecord a = Alarm();
  a.subject = "gw1)\r\n\r\nURGENT: acknowledge at http://evil.example/ack\n.\r\nX";
  const std::string mail =
      lw::server::MakeNotifications(c, a, {1, a.since_s, "raised", "server\r\nBcc: x@y", a.detail}, 1).at(0).body;
  CHECK_TEXT(mail.find("\r\nURGENT") == std::string::npos, mail.c_str());
  CHECK_TEXT(mail.find("\n.") == std::string::npos, mail.c_str());
  CHECK_TEXT(mail.find("\r\nBcc:") == std::string::npos, mail.c_str());
  CheckError(
      {{"email", {{"smtp_url", "smtp://mail"}, {"from", "a@b.c"}, {"to", {"ops@example.com\r\nBcc:evil@attacker.example"}}}}},
      "key 'notifications.email.to': 'ops@example.com");
}

// A receiver that has taken an event gets it once even when the database is busy right after its
// 2xx (a long commit, an operator's sqlite3 holding the write lock beyond the busy timeout).
TEST(NotifyDelivery, ABusyDatabaseAfterTheReceiversAnswerSendsNothingTwice) {
  const std::string db = dir.File("db.sqlite");
  {
    lw::server::Store s(db);
    const lw::server::AlarmRecord a = Alarm();
    s.SaveAlarm(a, {0, a.since_s, "raised", "server", a.detail});
  }
  std::atomic<int> posts{0};
  httplib::Server receiver;
  receiver.Post("/hook", [&](const httplib::Request&, httplib::Response& res) {
    ++posts;
    std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // the lock is taken meanwhile
    res.status = 200;
  });
  const int port = receiver.bind_to_any_port("127.0.0.1");
  std::thread serving([&] { receiver.listen_after_bind(); });
  std::vector<std::string> log;
  std::mutex log_mutex;
  {
    lw::server::Notifier n(
        ParseNotificationConfig(
            {{"webhooks", {Hook("http://127.0.0.1:" + std::to_string(port) + "/hook")}}, {"retry_initial_s", 1}}, "x"),
        db,
        [&](const std::string& l) {
          std::lock_guard<std::mutex> lock(log_mutex);
          log.push_back(l);
        },
        nullptr);
    n.Start();
    for (int i = 0; i < 300 && posts == 0; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    CHECK(posts == 1);
    sqlite3* h = nullptr;
    sqlite3_open(db.c_str(), &h);
    LONGS_EQUAL(SQLITE_OK, sqlite3_exec(h, "BEGIN IMMEDIATE", nullptr, nullptr, nullptr));
    std::this_thread::sleep_for(std::chrono::milliseconds(7000));  // beyond the store's 5 s busy timeout
    sqlite3_exec(h, "COMMIT", nullptr, nullptr, nullptr);
    sqlite3_close(h);
    std::this_thread::sleep_for(std::chrono::milliseconds(3000));  // time for a repeat, if there were one
    n.Stop();
  }
  receiver.stop();
  serving.join();
  LONGS_EQUAL(1, posts.load());
  lw::server::Store s(db);
  LONGS_EQUAL(0, s.CountPendingNotifications());
}
