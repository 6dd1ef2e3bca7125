// Alarm notifications of the real linerwatch-server (docs/alarms.md, *Notifications*) with a real
// mosquitto, a webhook receiver in this process and a real SMTP sink (aiosmtpd): a gateway's last
// will raises gateway_offline, which reaches the receiver once as a POST with a valid signature and
// the sink once as an e-mail a person can act on; with both receivers down at the raise and the
// server restarted while they are, each event reaches each receiver once after they come up.
#include <chrono>
#include <fstream>
#include <map>
#include <thread>

#include "core/hmac.hpp"
#include "core/time.hpp"
#include "support/mqtt_recorder.hpp"
#include "unit/server/server_fixture.hpp"
#include "support/notify_receivers.hpp"  // after Eigen: it includes httplib (<resolv.h> defines _res)

#include <CppUTest/TestHarness.h>  // last

using nlohmann::json;

namespace {

constexpr const char* kSecret = "whsec-test-1";

struct Server {
  lw::test::ChildProcess process;
  std::string log;
  int port = 0;
  void Start(const std::string& broker, const lw::test::CrusherFolder& folder, const std::string& config) {
    if (port == 0) port = lw::test::FreeLoopbackPort();
    log = folder.dir.File("server.log");
    process.Start({LW_SERVER_BIN, "--broker", broker, "--db", folder.dir.File("server.sqlite"), "--http",
                   "127.0.0.1:" + std::to_string(port), "--crusher-dir", folder.crushers, "--web-dir", "", "--config", config},
                  log);
    for (int i = 0; i < 1200 && !lw::test::PortAccepts(port); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (!lw::test::PortAccepts(port)) FAIL(("server did not come up: " + lw::test::FileTail(log)).c_str());
  }
};

/// `email_extra`: more keys of "email" (starttls, ca_file).
std::string WriteConfig(const lw::test::CrusherFolder& folder, const std::string& hook, const std::string& smtp,
                        const json& email_extra = json::object()) {
  const std::string path = folder.dir.File("server.json");
  json email{{"smtp_url", smtp}, {"from", "linerwatch@example.com"}, {"to", {"ops@example.com"}}};
  email.update(email_extra);
  std::ofstream(path) << json{{"notifications",
                               {{"webhooks", {{{"url", hook}, {"secret", kSecret}}}},
                                {"email", email},
                                {"dashboard_url", "http://dashboard.example:8080/"},
                                {"retry_initial_s", 1},
                                {"retry_max_s", 2},
                                {"timeout_s", 5}}}};
  return path;
}

/// The gateway_offline POSTs taken by `hook`.
std::vector<lw::test::WebhookReceiver::Post> GatewayPosts(const lw::test::WebhookReceiver& hook) {
  std::vector<lw::test::WebhookReceiver::Post> out;
  for (const auto& p : hook.Posts()) {
    const json j = json::parse(p.body, nullptr, false);
    if (j.is_object() && j["alarm"]["rule"] == "gateway_offline") out.push_back(p);
  }
  return out;
}

std::vector<std::string> GatewayMails(const lw::test::SmtpSink& smtp) {
  std::vector<std::string> out;
  for (const std::string& m : smtp.Messages())
    if (m.find("gateway_offline on ") != std::string::npos) out.push_back(m);
  return out;
}

/// A self-signed certificate for 127.0.0.1 and its key, by Debian's openssl: the sink's, and the
/// server's ca_file (a site's private CA in miniature).
lw::test::SmtpSink::Tls MakeCertificate(const lw::test::CrusherFolder& folder) {
  const lw::test::SmtpSink::Tls tls{folder.dir.File("smtp-cert.pem"), folder.dir.File("smtp-key.pem")};
  const std::string command =
      "openssl req -x509 -newkey rsa:2048 -nodes -days 2 -subj /CN=127.0.0.1 -addext "
      "subjectAltName=IP:127.0.0.1 -keyout '" +
      tls.key + "' -out '" + tls.cert + "' >'" + folder.dir.File("openssl.log") + "' 2>&1";
  if (std::system(command.c_str()) != 0) FAIL(("openssl: " + lw::test::FileTail(folder.dir.File("openssl.log"))).c_str());
  return tls;
}

bool WaitUntil(const std::function<bool()>& ok) {
  for (int i = 0; i < 600; ++i) {
    if (ok()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return false;
}

/// Every event (X-Linerwatch-Event) reached the receiver at most once.
void CheckNoEventTwice(const lw::test::WebhookReceiver& hook) {
  std::map<std::string, int> seen;
  for (const auto& p : hook.Posts()) {
    const std::string& id = p.headers.at("X-Linerwatch-Event");
    CHECK_TEXT(++seen[id] == 1, ("event " + id + " posted twice").c_str());
  }
}

}  // namespace

TEST_GROUP(ServerNotifications) {
  lw::test::MosquittoFixture broker;
  lw::test::CrusherFolder folder{10, 5};
  Server server;
  std::string root;
  void setup() override {
    broker.Start();
    root = "linerwatch/v1/site1/" + folder.id() + "/";
  }
  void RaiseGatewayOffline() {
    lw::test::MqttRecorder mqtt(broker.uri(), "gateway-sim", "test", "x");
    const auto messages = lw::test::Messages(folder.bundle);
    mqtt.Publish(messages.front().topic, messages.front().payload);
    const std::string hour_ago = lw::core::FormatIsoTime(
        std::chrono::time_point_cast<std::chrono::seconds>(std::chrono::system_clock::now()) - std::chrono::hours(1));
    mqtt.Publish(root + "gateway/status", json{{"state", "offline"}, {"gateway", "gw1"}, {"time", hour_ago}}.dump(), true);
  }
};

TEST(ServerNotifications, ARaisedAlarmIsPostedSignedAndMailedOnce) {
  lw::test::WebhookReceiver hook;
  lw::test::SmtpSink smtp(folder.dir.File("smtp"));
  hook.Start();
  smtp.Start();
  server.Start(broker.uri(), folder, WriteConfig(folder, hook.url(), smtp.url()));
  RaiseGatewayOffline();
  const bool both = WaitUntil([&] { return !GatewayPosts(hook).empty() && !GatewayMails(smtp).empty(); });
  CHECK_TEXT(both, lw::test::FileTail(server.log).c_str());
  const auto post = GatewayPosts(hook).front();
  STRCMP_EQUAL("application/json", post.headers.at("Content-Type").c_str());
  STRCMP_EQUAL(("sha256=" + lw::core::HmacSha256Hex(kSecret, post.body)).c_str(),
               post.headers.at("X-Linerwatch-Signature").c_str());
  const json body = json::parse(post.body);
  STRCMP_EQUAL("raised", body["event"].get<std::string>().c_str());
  STRCMP_EQUAL(folder.id().c_str(), body["crusher"].get<std::string>().c_str());
  STRCMP_EQUAL("gw1", body["alarm"]["subject"].get<std::string>().c_str());
  STRCMP_EQUAL(post.headers.at("X-Linerwatch-Event").c_str(), std::to_string(body["event_id"].get<int64_t>()).c_str());
  STRCMP_EQUAL(("http://dashboard.example:8080/#/c/" + folder.id()).c_str(), body["dashboard"].get<std::string>().c_str());

  const std::string mail = GatewayMails(smtp).front();
  CHECK_TEXT(mail.find("Subject: [linerwatch] RAISED ") != std::string::npos, mail.c_str());
  CHECK_TEXT(mail.find("gateway gw1 offline since") != std::string::npos, mail.c_str());
  CHECK_TEXT(mail.find("Dashboard:  http://dashboard.example:8080/#/c/" + folder.id()) != std::string::npos, mail.c_str());
  CHECK_TEXT(mail.find("/alarms/" + std::to_string(body["alarm"]["id"].get<int64_t>()) + "/ack") != std::string::npos,
             mail.c_str());

  // Acknowledged over REST: one more POST, of that event.
  httplib::Client http("127.0.0.1", server.port);
  const auto res =
      http.Post("/api/v1/crushers/" + folder.id() + "/alarms/" + std::to_string(body["alarm"]["id"].get<int64_t>()) + "/ack", "",
                "application/json");
  CHECK(res);
  LONGS_EQUAL(200, res->status);
  CHECK(WaitUntil([&] { return GatewayPosts(hook).size() == 2; }));
  STRCMP_EQUAL("acknowledged", json::parse(GatewayPosts(hook).back().body)["event"].get<std::string>().c_str());
  std::this_thread::sleep_for(std::chrono::seconds(3));  // time for a repeat, if there were one
  LONGS_EQUAL(2, GatewayPosts(hook).size());
  CheckNoEventTwice(hook);
}

TEST(ServerNotifications, ReceiversDownAtTheRaiseGetEachEventOnceAfterTheyComeUpAcrossARestart) {
  lw::test::WebhookReceiver hook;  // not started: its port is closed
  lw::test::SmtpSink smtp(folder.dir.File("smtp"));
  const std::string config = WriteConfig(folder, hook.url(), smtp.url());
  server.Start(broker.uri(), folder, config);
  RaiseGatewayOffline();
  const bool failed = WaitUntil([&] {
    const std::string log = lw::test::FileTail(server.log, 200'000);
    return log.find("to webhook http://127.0.0.1:") != std::string::npos && log.find("attempt 2 failed") != std::string::npos &&
           log.find("to email smtp://127.0.0.1:") != std::string::npos;
  });
  CHECK_TEXT(failed, lw::test::FileTail(server.log).c_str());
  CHECK_TEXT(lw::test::FileTail(server.log, 200'000).find(kSecret) == std::string::npos, "the secret is in the log");
  server.process.Stop(SIGTERM);

  // Up, but answering 500: not taken, retried.
  hook.Answer(500);
  hook.Start();
  server.Start(broker.uri(), folder, config);
  CHECK(WaitUntil([&] { return hook.answered() >= 2; }));
  LONGS_EQUAL(0, hook.Posts().size());
  hook.Answer(200);
  smtp.Start();
  const bool both = WaitUntil([&] { return GatewayPosts(hook).size() == 1 && GatewayMails(smtp).size() == 1; });
  CHECK_TEXT(both, lw::test::FileTail(server.log).c_str());
  const auto post = GatewayPosts(hook).front();
  STRCMP_EQUAL(("sha256=" + lw::core::HmacSha256Hex(kSecret, post.body)).c_str(),
               post.headers.at("X-Linerwatch-Signature").c_str());
  // Every event queued before the restart is delivered, none twice (the sensors' alarms too).
  std::this_thread::sleep_for(std::chrono::seconds(3));
  LONGS_EQUAL(1, GatewayPosts(hook).size());
  LONGS_EQUAL(1, GatewayMails(smtp).size());
  CheckNoEventTwice(hook);
  LONGS_EQUAL(hook.Posts().size(), smtp.Messages().size());
}

// "starttls": true with the site's CA: the mail goes over TLS to a relay that refuses MAIL before
// STARTTLS. The same setting against a relay that offers no STARTTLS sends nothing in clear text:
// the attempt fails, the mail stays queued.
TEST(ServerNotifications, EmailGoesOverStartTlsAndNeverInClearText) {
  const lw::test::SmtpSink::Tls tls = MakeCertificate(folder);
  lw::test::WebhookReceiver hook;
  lw::test::SmtpSink secure(folder.dir.File("smtp-tls"), 0, tls);
  hook.Start();
  secure.Start();
  server.Start(broker.uri(), folder, WriteConfig(folder, hook.url(), secure.url(), {{"starttls", true}, {"ca_file", tls.cert}}));
  RaiseGatewayOffline();
  CHECK_TEXT(WaitUntil([&] { return GatewayMails(secure).size() == 1; }), lw::test::FileTail(server.log).c_str());
  CHECK(GatewayMails(secure).front().find("gateway gw1 offline since") != std::string::npos);
  server.process.Stop(SIGTERM);

  // A relay without STARTTLS (plain aiosmtpd): refused by the server, not sent in clear text.
  lw::test::SmtpSink plain(folder.dir.File("smtp-plain"));
  plain.Start();
  lw::test::CrusherFolder other{10, 5};  // the same crusher, a new database
  Server second;
  second.Start(broker.uri(), other, WriteConfig(other, hook.url(), plain.url(), {{"starttls", true}, {"ca_file", tls.cert}}));
  RaiseGatewayOffline();
  const bool refused = WaitUntil([&] {
    const std::string log = lw::test::FileTail(second.log, 200'000);
    return log.find("to email smtp://127.0.0.1:") != std::string::npos && log.find("attempt 1 failed") != std::string::npos;
  });
  CHECK_TEXT(refused, lw::test::FileTail(second.log).c_str());
  LONGS_EQUAL(0, plain.Messages().size());
  second.process.Stop(SIGTERM);
}
