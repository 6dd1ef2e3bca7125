// mqtt::MosquittoLink (the server's MQTT link) against a real mosquitto on 127.0.0.1: messages both
// ways, the persistent session keeping what was published while the link was away, reconnecting
// after the broker went down and after Reconnect(), a refused login reported and retried, TLS with
// the broker's CA and without it, Shutdown()'s final message, a URI it cannot use refused by name.
#include "mqtt/mosquitto_link.hpp"

#include <poll.h>

#include <chrono>
#include <functional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "support/link_poll.hpp"
#include "support/mosquitto_fixture.hpp"

#include <CppUTest/TestHarness.h>  // last

using lw::mqtt::LinkEvent;
using lw::mqtt::LinkOptions;
using lw::mqtt::MosquittoLink;

namespace {

LinkOptions Options(const std::string& uri, const std::string& id, std::vector<std::string> subscriptions = {}) {
  LinkOptions o;
  o.uri = uri;
  o.client_id = id;
  o.subscriptions = std::move(subscriptions);
  o.clean_session = false;
  o.reconnect_min_ms = 50;
  o.reconnect_max_ms = 400;
  return o;
}

/// Polls `link` as the server's loop does (waiting on wake_fd()) until `done` holds for the events
/// seen so far, at most `timeout_ms` (60 s: a bound only a real failure reaches, a starved broker
/// on a loaded machine can take seconds); returns them all.
std::vector<LinkEvent> PollUntil(MosquittoLink& link, const std::function<bool(const std::vector<LinkEvent>&)>& done,
                                 int64_t timeout_ms = 60'000) {
  return lw::test::PollLinkUntil(link, done, timeout_ms).events;
}

size_t Count(const std::vector<LinkEvent>& events, LinkEvent::Kind kind) {
  return lw::test::CountEvents(events, kind);
}

std::function<bool(const std::vector<LinkEvent>&)> Has(LinkEvent::Kind kind, size_t n = 1) {
  return [kind, n](const std::vector<LinkEvent>& e) { return Count(e, kind) >= n; };
}

/// Connects `link` and lets the broker take its subscriptions (SUBACK is not reported).
void Connect(MosquittoLink& link) {
  const auto events = PollUntil(link, Has(LinkEvent::Kind::kConnected));
  LONGS_EQUAL(1, Count(events, LinkEvent::Kind::kConnected));
  PollUntil(
      link, [](const auto&) { return false; }, 200);
}

std::string Text(const std::vector<LinkEvent>& events) {
  std::string out;
  for (const LinkEvent& e : events) out += e.payload + "\n";
  return out;
}

}  // namespace

TEST_GROUP(MosquittoLink){};

TEST(MosquittoLink, CarriesMessagesBothWaysInOrderWithTheirBytes) {
  lw::test::MosquittoFixture broker;
  broker.Start();
  MosquittoLink a(Options(broker.uri(), "link-a", {"to-a/#"}));
  MosquittoLink b(Options(broker.uri(), "link-b", {"to-b/#"}));
  Connect(a);
  Connect(b);
  CHECK(a.IsConnected());
  const std::string binary("x\0y\xff", 4);
  for (int i = 0; i < 100; ++i) CHECK(a.Publish({"to-b/" + std::to_string(i % 3), std::to_string(i), 1, false}));
  CHECK(b.Publish({"to-a/bin", binary, 1, false}));
  const auto got_b = PollUntil(b, Has(LinkEvent::Kind::kMessage, 100));
  LONGS_EQUAL(100, Count(got_b, LinkEvent::Kind::kMessage));
  int next = 0;
  for (const LinkEvent& e : got_b) {
    if (e.kind != LinkEvent::Kind::kMessage) continue;
    CHECK_EQUAL("to-b/" + std::to_string(next % 3), e.topic);
    CHECK_EQUAL(std::to_string(next), e.payload);
    ++next;
  }
  const auto got_a = PollUntil(a, Has(LinkEvent::Kind::kMessage));
  LONGS_EQUAL(1, Count(got_a, LinkEvent::Kind::kMessage));
  CHECK(got_a.back().payload == binary);
}

TEST(MosquittoLink, APersistentSessionReceivesEverythingPublishedWhileItWasAway) {
  lw::test::MosquittoFixture broker(
      {.persistence = false, .tls = false, .username = "", .password = "", .extra_config = "max_queued_messages 0\n"});
  broker.Start();
  // The publisher subscribes to what it publishes: once it has every message back, the broker has
  // taken them all (and queued each for the absent session) whatever the machine's speed. A fixed
  // 2 s of polling was not always enough on a loaded machine, and what the publisher had not yet
  // written then stayed in its queue, unpolled, while the server waited for it.
  MosquittoLink publisher(Options(broker.uri(), "publisher", {"readings/#"}));
  Connect(publisher);
  {
    MosquittoLink server(Options(broker.uri(), "server", {"readings/#"}));
    Connect(server);
  }  // gone: the broker keeps its session and queues for it
  constexpr int kMessages = 5000;
  for (int i = 0; i < kMessages; ++i) CHECK(publisher.Publish({"readings/s", std::to_string(i), 1, false}));
  const auto echoed = PollUntil(publisher, Has(LinkEvent::Kind::kMessage, kMessages));
  LONGS_EQUAL_TEXT(kMessages, Count(echoed, LinkEvent::Kind::kMessage), "the broker did not take every message");
  MosquittoLink server(Options(broker.uri(), "server", {"readings/#"}));
  const auto events = PollUntil(server, Has(LinkEvent::Kind::kMessage, kMessages));
  LONGS_EQUAL(kMessages, Count(events, LinkEvent::Kind::kMessage));
  int next = 0;
  for (const LinkEvent& e : events) {
    if (e.kind != LinkEvent::Kind::kMessage) continue;
    CHECK_EQUAL(std::to_string(next), e.payload);
    ++next;
  }
}

TEST(MosquittoLink, ABrokerThatWentDownIsReportedAndReconnectedWithBackoffKeepingTheSession) {
  lw::test::MosquittoFixture broker({.persistence = true, .tls = false, .username = "", .password = "", .extra_config = ""});
  broker.Start();
  MosquittoLink server(Options(broker.uri(), "server", {"readings/#"}));
  Connect(server);
  broker.Stop();
  auto events = PollUntil(server, Has(LinkEvent::Kind::kDisconnected));
  CHECK_FALSE(server.IsConnected());
  CHECK_FALSE(server.Publish({"x", "y", 1, false}));  // refused, not queued: the caller keeps it
  // Attempts against the stopped broker fail and are reported with their wait.
  events = PollUntil(server, Has(LinkEvent::Kind::kDisconnected, 2));
  const std::string text = Text(events);
  CHECK_TEXT(text.find("connect to " + broker.uri() + " failed") != std::string::npos, text.c_str());
  CHECK_TEXT(text.find("retrying in") != std::string::npos, text.c_str());
  broker.Start();
  Connect(server);
  MosquittoLink publisher(Options(broker.uri(), "publisher"));
  Connect(publisher);
  CHECK(publisher.Publish({"readings/s", "after", 1, false}));
  events = PollUntil(server, Has(LinkEvent::Kind::kMessage));
  LONGS_EQUAL(1, Count(events, LinkEvent::Kind::kMessage));
}

TEST(MosquittoLink, ReconnectReportsTheReasonAndTheSessionKeepsWhatCameMeanwhile) {
  lw::test::MosquittoFixture broker;
  broker.Start();
  MosquittoLink server(Options(broker.uri(), "server", {"readings/#"}));
  MosquittoLink publisher(Options(broker.uri(), "publisher"));
  Connect(server);
  Connect(publisher);
  server.Reconnect("the connection carried nothing");
  CHECK_FALSE(server.IsConnected());
  for (int i = 0; i < 10; ++i) CHECK(publisher.Publish({"readings/s", std::to_string(i), 1, false}));
  PollUntil(
      publisher, [](const auto&) { return false; }, 200);
  const auto events = PollUntil(server, Has(LinkEvent::Kind::kMessage, 10));
  CHECK(!events.empty());
  CHECK(events.front().kind == LinkEvent::Kind::kDisconnected);
  STRCMP_EQUAL("the connection carried nothing", events.front().payload.c_str());
  LONGS_EQUAL(1, Count(events, LinkEvent::Kind::kConnected));
  LONGS_EQUAL(10, Count(events, LinkEvent::Kind::kMessage));
}

TEST(MosquittoLink, ARefusedLoginIsReportedAndRetriedAndTheRightOneConnects) {
  lw::test::MosquittoFixture broker(
      {.persistence = false, .tls = false, .username = "server", .password = "right", .extra_config = ""});
  broker.Start();
  LinkOptions wrong = Options(broker.uri(), "server");
  wrong.username = "server";
  wrong.password = "wrong";
  MosquittoLink refused(wrong);
  const auto events = PollUntil(refused, Has(LinkEvent::Kind::kDisconnected, 2));
  LONGS_EQUAL(0, Count(events, LinkEvent::Kind::kConnected));
  const std::string text = Text(events);
  CHECK_TEXT(text.find("not authorised") != std::string::npos, text.c_str());
  CHECK_TEXT(text.find("retrying in 50 ms") != std::string::npos, text.c_str());
  CHECK_TEXT(text.find("retrying in 100 ms") != std::string::npos, text.c_str());
  LinkOptions right = wrong;
  right.password = "right";
  MosquittoLink accepted(right);
  Connect(accepted);
}

TEST(MosquittoLink, TlsConnectsWithTheBrokersCaAndIsRefusedWithoutIt) {
  lw::test::MosquittoFixture broker({.persistence = false, .tls = true, .username = "", .password = "", .extra_config = ""});
  broker.Start();
  CHECK(broker.uri().rfind("ssl://", 0) == 0);
  LinkOptions trusted = Options(broker.uri(), "server", {"readings/#"});
  trusted.tls_ca = broker.ca_file();
  MosquittoLink server(trusted);
  Connect(server);
  CHECK(server.Publish({"readings/s", "over tls", 1, false}));
  const auto events = PollUntil(server, Has(LinkEvent::Kind::kMessage));
  STRCMP_EQUAL("over tls", events.back().payload.c_str());

  MosquittoLink untrusted(Options(broker.uri(), "stranger"));  // the system's trust store: not this CA
  const auto refused = PollUntil(untrusted, Has(LinkEvent::Kind::kDisconnected));
  LONGS_EQUAL(0, Count(refused, LinkEvent::Kind::kConnected));
  // The handshake fails either in the connect call or on the first read after it, depending on
  // timing (a loaded machine): "connect to ... failed: ..." or "connection lost: ...".
  const std::string text = Text(refused);
  CHECK_TEXT(text.find("failed") != std::string::npos || text.find("connection lost") != std::string::npos, text.c_str());
}

TEST(MosquittoLink, ShutdownDeliversTheFinalMessage) {
  lw::test::MosquittoFixture broker;
  broker.Start();
  {
    MosquittoLink gateway(Options(broker.uri(), "gateway"));
    Connect(gateway);
    gateway.Shutdown({"status/g", "offline", 1, true}, 2000);
    CHECK_FALSE(gateway.IsConnected());
  }
  MosquittoLink observer(Options(broker.uri(), "observer", {"status/#"}));
  const auto events = PollUntil(observer, Has(LinkEvent::Kind::kMessage));
  LONGS_EQUAL(1, Count(events, LinkEvent::Kind::kMessage));
  STRCMP_EQUAL("offline", events.back().payload.c_str());
}

TEST(MosquittoLink, AUriItCannotUseIsRefusedByName) {
  const auto refused = [](const std::string& uri, const std::string& expected) {
    try {
      MosquittoLink link(Options(uri, "x"));
      FAIL(("accepted " + uri).c_str());
    } catch (const std::runtime_error& e) {
      const std::string what = e.what();
      CHECK_TEXT(what.find(expected) != std::string::npos, what.c_str());
    }
  };
  refused("wss://broker:443", "'wss://' is not supported");
  refused("127.0.0.1:1883", "no scheme");
  refused("tcp://:1883", "no host");
  refused("tcp://broker:99999", "port '99999'");
  refused("tcp://broker:x", "port 'x'");
}
