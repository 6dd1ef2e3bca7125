// mqtt::MosquittoLink (the server's MQTT link) against a hostile broker: a plain TCP listener on
// 127.0.0.1 (support/fake_broker.hpp) that answers the link's CONNECT with refusals, malformed and
// truncated packets, packets that promise more than they hold, floods and silence. For each, the
// link must neither crash nor hang: it reports what was wrong (a kDisconnected event naming it),
// connects again with its backoff, and the next, well-behaved connection carries its message. A
// malformed packet's content is never reported as a message.
#include <poll.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include "mqtt/mosquitto_link.hpp"
#include "support/fake_broker.hpp"
#include "support/link_poll.hpp"

#include <CppUTest/TestHarness.h>  // last

using lw::mqtt::LinkEvent;
using lw::mqtt::LinkOptions;
using lw::mqtt::MosquittoLink;
using lw::test::BrokerConnection;
using lw::test::FakeBroker;
using lw::test::Publish;

namespace {

LinkOptions Options(const std::string& uri) {
  LinkOptions o;
  o.uri = uri;
  o.client_id = "server";
  o.subscriptions = {"readings/#"};
  o.clean_session = false;
  o.reconnect_min_ms = 50;
  o.reconnect_max_ms = 400;
  o.keep_alive_s = 5;  // libmosquitto's least: a silent broker is found within one to two of these
  return o;
}

using Run = lw::test::LinkRun;

Run PollUntil(MosquittoLink& link, const std::function<bool(const std::vector<LinkEvent>&)>& done, int64_t timeout_ms) {
  return lw::test::PollLinkUntil(link, done, timeout_ms);
}

size_t Count(const std::vector<LinkEvent>& events, LinkEvent::Kind kind) {
  return lw::test::CountEvents(events, kind);
}

std::string Text(const std::vector<LinkEvent>& events) {
  std::string out;
  for (const LinkEvent& e : events) {
    out += e.kind == LinkEvent::Kind::kConnected      ? "connected"
           : e.kind == LinkEvent::Kind::kDisconnected ? "disconnected: " + e.payload
                                                      : "message " + e.topic + ": " + e.payload.substr(0, 80);
    out += "\n";
  }
  return out;
}

bool HasMessage(const std::vector<LinkEvent>& events, const std::string& payload) {
  for (const LinkEvent& e : events) {
    if (e.kind == LinkEvent::Kind::kMessage && e.payload == payload) return true;
  }
  return false;
}

/// The process's resident memory in KiB (/proc/self/status VmRSS).
long RssKib() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  }
  return -1;
}

/// What a well-behaved broker sends on every connection after the hostile one: one reading.
void Behave(BrokerConnection& c) {
  if (!c.Handshake()) return;
  c.Send(Publish("readings/s", "good", 1, 7));
  c.Hold();
}

/// The first connection is accepted (CONNACK, SUBACK) and then gets `hostile`; it is closed when
/// `close` is set, else held open (reading what the link sends) until the link closes it. Every
/// later connection behaves. Returns what the link reported until the good message arrived.
Run AfterConnect(const std::string& hostile, bool close, int64_t timeout_ms = 60'000, FakeBroker** broker_out = nullptr) {
  FakeBroker broker([&hostile, close](int index, BrokerConnection& c) {
    if (index > 0) return Behave(c);
    if (!c.Handshake()) return;
    c.Send(hostile);
    if (!close) c.Hold();
  });
  if (broker_out) *broker_out = &broker;
  MosquittoLink link(Options(broker.uri()));
  Run run = PollUntil(
      link, [](const auto& e) { return HasMessage(e, "good"); }, timeout_ms);
  CHECK_TEXT(HasMessage(run.events, "good"), Text(run.events).c_str());
  LONGS_EQUAL_TEXT(2, broker.connections(), Text(run.events).c_str());
  return run;
}

/// The hostile connection was reported once, as lost (or dropped by the link, `prefix`) with
/// `reason` in its text, before the link connected again; the only message reported is the good one.
void CheckLostThenRecovered(const Run& run, const std::string& reason, const std::string& prefix = "connection lost: ") {
  const std::string text = Text(run.events);
  LONGS_EQUAL_TEXT(2, Count(run.events, LinkEvent::Kind::kConnected), text.c_str());
  LONGS_EQUAL_TEXT(1, Count(run.events, LinkEvent::Kind::kDisconnected), text.c_str());
  LONGS_EQUAL_TEXT(1, Count(run.events, LinkEvent::Kind::kMessage), text.c_str());
  CHECK_TEXT(run.events.at(0).kind == LinkEvent::Kind::kConnected, text.c_str());
  CHECK_TEXT(run.events.at(1).kind == LinkEvent::Kind::kDisconnected, text.c_str());
  CHECK_TEXT(run.events.at(1).payload.find(prefix) == 0, text.c_str());
  CHECK_TEXT(run.events.at(1).payload.find(reason) != std::string::npos, (reason + " not in:\n" + text).c_str());
}

}  // namespace

TEST_GROUP(MosquittoLinkHostileBroker){};

TEST(MosquittoLinkHostileBroker, ARefusingConnackIsReportedWithItsCodeAndRetriedWithBackoff) {
  // 5 is MQTT 3.1.1's "not authorised"; 0x42 is no code of the protocol at all.
  for (const uint8_t code : {uint8_t{5}, uint8_t{0x42}}) {
    FakeBroker broker([code](int index, BrokerConnection& c) {
      if (index >= 3) return Behave(c);
      c.Handshake(code);
      c.Hold(5000);
    });
    MosquittoLink link(Options(broker.uri()));
    const Run run = PollUntil(
        link, [](const auto& e) { return HasMessage(e, "good"); }, 60'000);
    const std::string text = Text(run.events);
    CHECK_TEXT(HasMessage(run.events, "good"), text.c_str());
    LONGS_EQUAL_TEXT(4, broker.connections(), text.c_str());
    LONGS_EQUAL_TEXT(1, Count(run.events, LinkEvent::Kind::kConnected), text.c_str());
    LONGS_EQUAL_TEXT(3, Count(run.events, LinkEvent::Kind::kDisconnected), text.c_str());
    for (size_t i = 0; i < 3; ++i) {
      const std::string& why = run.events.at(i).payload;
      CHECK_TEXT(why.find("connect to " + broker.uri() + " failed: ") == 0, text.c_str());
      CHECK_TEXT(why.find("(code " + std::to_string(code) + ")") != std::string::npos, text.c_str());
    }
    CHECK_TEXT(text.find("retrying in 50 ms") != std::string::npos, text.c_str());
    CHECK_TEXT(text.find("retrying in 100 ms") != std::string::npos, text.c_str());
    CHECK_TEXT(text.find("retrying in 200 ms") != std::string::npos, text.c_str());
    if (code == 5) CHECK_TEXT(text.find("not authorised") != std::string::npos, text.c_str());
  }
}

TEST(MosquittoLinkHostileBroker, ATruncatedPacketThenCloseIsALostConnection) {
  // A PUBLISH that declares 20 bytes and sends 5 of them.
  const std::string truncated("\x30\x14\x00\x0areadi", 7);
  CheckLostThenRecovered(AfterConnect(truncated, true), "the broker closed the connection in the middle of a packet");
  // The same with a pause before the close, so that the link has read the first bytes and waits
  // for the rest when the close comes: reported at once, no spinning on the closed socket until
  // the keep-alive (that would be hundreds of polls).
  FakeBroker broker([&truncated](int index, BrokerConnection& c) {
    if (index > 0) return Behave(c);
    if (!c.Handshake()) return;
    c.Send(truncated);
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  });
  MosquittoLink link(Options(broker.uri()));
  const Run run = PollUntil(
      link, [](const auto& e) { return HasMessage(e, "good"); }, 60'000);
  CHECK_TEXT(HasMessage(run.events, "good"), Text(run.events).c_str());
  CheckLostThenRecovered(run, "the broker closed the connection in the middle of a packet");
  // About 25 polls in the pause (the test waits 20 ms on the socket between them) and a few more.
  CHECK_TEXT(run.polls < 200, ("polls: " + std::to_string(run.polls)).c_str());
}

TEST(MosquittoLinkHostileBroker, ARemainingLengthOfFourContinuedBytesIsFoundByTheKeepAlive) {
  // 0xFF 0xFF 0xFF 0xFF: four bytes all saying "more follows", which MQTT forbids. libmosquitto
  // waits for a fifth byte, so the silence after it is what ends the connection: its PINGREQ goes
  // unanswered (keep-alive 5 s: within two of them).
  const Run run = AfterConnect("\x30\xff\xff\xff\xff", false);
  CheckLostThenRecovered(run, "no answer from the broker within the keep-alive (5 s)");
  // With the fifth byte, at once: a protocol error.
  const Run fifth = AfterConnect("\x30\xff\xff\xff\xff\x01", false);
  CheckLostThenRecovered(fifth, "protocol error");
}

TEST(MosquittoLinkHostileBroker, APublishDeclaringHugeLengthCostsOnlyWhatArrivesAndIsDroppedByTheKeepAlive) {
  // 268,435,455 bytes declared (MQTT's largest), 1 MiB sent, then silence.
  const long before = RssKib();
  std::atomic<long> during{0};
  FakeBroker broker([&during](int index, BrokerConnection& c) {
    if (index > 0) return Behave(c);
    if (!c.Handshake()) return;
    c.Send("\x30\xff\xff\xff\x7f" + std::string(1 << 20, 'x'));
    std::this_thread::sleep_for(std::chrono::seconds(2));  // read by the link meanwhile
    during = RssKib();
    c.Hold();
  });
  MosquittoLink link(Options(broker.uri()));
  const Run run = PollUntil(
      link, [](const auto& e) { return HasMessage(e, "good"); }, 60'000);
  CHECK_TEXT(HasMessage(run.events, "good"), Text(run.events).c_str());
  CheckLostThenRecovered(run, "no answer from the broker within the keep-alive (5 s)");
  // libmosquitto allocates the declared length at once (up to MQTT's 256 MiB; docs/security.md) but
  // only the pages that the received bytes fill become resident.
  CHECK_TEXT(during - before < 32 * 1024, ("VmRSS grew by " + std::to_string(during - before) + " KiB").c_str());
}

TEST(MosquittoLinkHostileBroker, APublishWhoseTopicLengthExceedsThePacketIsAProtocolError) {
  // Topic length 0x00FF, 5 bytes follow.
  const Run run = AfterConnect(std::string("\x30\x07\x00\xff"
                                           "abcde",
                                           9),
                               true);
  CheckLostThenRecovered(run, "protocol error");
}

TEST(MosquittoLinkHostileBroker, AQos3PublishIsAProtocolError) {
  const Run run = AfterConnect(Publish("readings/s", "qos3", 3, 9), false);
  CheckLostThenRecovered(run, "protocol error");
}

TEST(MosquittoLinkHostileBroker, ASecondConnackIsRefusedNotReportedAsANewConnection) {
  // Found by fuzz_mqtt_link_broker: libmosquitto calls the connect callback again.
  const Run run = AfterConnect(lw::test::Connack(0), false);
  CheckLostThenRecovered(run, "the broker sent a second CONNACK, which MQTT forbids", "connection dropped: ");
}

TEST(MosquittoLinkHostileBroker, ATopicThatIsNotUtf8IsAnError) {
  const Run run = AfterConnect(Publish(std::string("readings/\xff\xfe", 11), "bad topic", 1, 9), false);
  CheckLostThenRecovered(run, "UTF-8");
}

TEST(MosquittoLinkHostileBroker, PayloadsThatAreNotJsonOrUtf8AndUnsubscribedTopicsAreReportedAsTheyCame) {
  // The link carries bytes; judging them is its owner's (the server quarantines such readings and
  // logs messages on topics that are not readings: test_server_hostile_broker).
  const std::string binary("\xff\xfe\x00{\"seq\":", 9);
  FakeBroker broker([&binary](int, BrokerConnection& c) {
    if (!c.Handshake()) return;
    c.Send(Publish("readings/s", "not json", 1, 1) + Publish("readings/s", binary, 1, 2) +
           Publish("elsewhere/x", "unsolicited", 0) + Publish("readings/s", "good", 1, 3));
    c.Hold();
  });
  MosquittoLink link(Options(broker.uri()));
  const Run run = PollUntil(
      link, [](const auto& e) { return HasMessage(e, "good"); }, 60'000);
  const std::string text = Text(run.events);
  LONGS_EQUAL_TEXT(0, Count(run.events, LinkEvent::Kind::kDisconnected), text.c_str());
  LONGS_EQUAL_TEXT(4, Count(run.events, LinkEvent::Kind::kMessage), text.c_str());
  CHECK(run.events.at(1).payload == "not json");
  CHECK(run.events.at(2).payload == binary);
  CHECK(run.events.at(3).topic == "elsewhere/x");
  CHECK(run.events.at(4).topic == "readings/s");
  CHECK(link.IsConnected());
}

TEST(MosquittoLinkHostileBroker, AFloodOfPingrespsNeitherDropsTheLinkNorHoldsBackTheMessageAfterIt) {
  constexpr int kPingresps = 200'000;
  std::string flood;
  for (int i = 0; i < kPingresps; ++i) flood += std::string("\xd0\x00", 2);
  FakeBroker broker([&flood](int, BrokerConnection& c) {
    if (!c.Handshake()) return;
    c.Send(flood + Publish("readings/s", "good", 1, 3));
    c.Hold();
  });
  MosquittoLink link(Options(broker.uri()));
  const Run run = PollUntil(
      link, [](const auto& e) { return HasMessage(e, "good"); }, 60'000);
  const std::string text = Text(run.events);
  CHECK_TEXT(HasMessage(run.events, "good"), text.c_str());
  LONGS_EQUAL_TEXT(0, Count(run.events, LinkEvent::Kind::kDisconnected), text.c_str());
  // Each Poll() reads up to 4096 packets, PINGRESPs too: the flood takes about 50 of them, not one
  // Poll() per PINGRESP (200,000, which starved the server's loop before).
  CHECK_TEXT(run.polls < 1000, ("polls: " + std::to_string(run.polls)).c_str());
}

TEST(MosquittoLinkHostileBroker, ABrokerStreamingLargeMessagesIsReadInBoundedSlicesPerPoll) {
  // 96 messages of 1 MiB as fast as the link takes them: what one Poll() returns must stay bounded
  // (else the owner's memory grows with whatever a broker manages to send during one Poll()).
  constexpr int kMessages = 96;
  const std::string mib(1 << 20, 'm');
  FakeBroker broker([&mib](int, BrokerConnection& c) {
    if (!c.Handshake()) return;
    for (int i = 1; i <= kMessages; ++i) {
      if (!c.Send(Publish("readings/s", mib, 1, static_cast<uint16_t>(i)))) return;
    }
    c.Send(Publish("readings/s", "good", 1, 1000));
    c.Hold();
  });
  MosquittoLink link(Options(broker.uri()));
  size_t most = 0, messages = 0;
  bool good = false;
  for (const int64_t end = lw::test::SteadyMs() + 60'000; !good && lw::test::SteadyMs() < end;) {
    size_t bytes = 0;
    for (const LinkEvent& e : link.Poll(lw::test::SteadyMs())) {
      bytes += e.payload.size();
      messages += e.kind == LinkEvent::Kind::kMessage;
      good = good || e.payload == "good";
    }
    most = std::max(most, bytes);
    pollfd p{link.wake_fd(), POLLIN, 0};
    (void)::poll(&p, 1, 20);
  }
  CHECK(good);
  LONGS_EQUAL(kMessages + 1, messages);
  CHECK_TEXT(most <= (16u << 20) + (1u << 20), ("one Poll() returned " + std::to_string(most) + " bytes").c_str());
}

TEST(MosquittoLinkHostileBroker, ABrokerThatAcceptsAndNeverAnswersIsAFailedConnectRetried) {
  FakeBroker broker([](int index, BrokerConnection& c) {
    if (index > 0) return Behave(c);
    c.Hold();  // reads the CONNECT, says nothing
  });
  MosquittoLink link(Options(broker.uri()));
  const Run run = PollUntil(
      link, [](const auto& e) { return HasMessage(e, "good"); }, 60'000);
  const std::string text = Text(run.events);
  CHECK_TEXT(HasMessage(run.events, "good"), text.c_str());
  LONGS_EQUAL_TEXT(2, broker.connections(), text.c_str());
  LONGS_EQUAL_TEXT(1, Count(run.events, LinkEvent::Kind::kConnected), text.c_str());
  LONGS_EQUAL_TEXT(1, Count(run.events, LinkEvent::Kind::kDisconnected), text.c_str());
  CHECK_TEXT(run.events.at(0).payload.find("connect to " + broker.uri() + " failed: ") == 0, text.c_str());
  CHECK_TEXT(run.events.at(0).payload.find("no answer from the broker within the keep-alive (5 s)") != std::string::npos,
             text.c_str());
}

TEST(MosquittoLinkHostileBroker, AQos2PublishIsRefusedAndWhatLibmosquittoHeldForItFreed) {
  // The link subscribes with QoS 1, so a QoS 2 message is a broker breaking MQTT. libmosquitto
  // would keep each until a PUBREL that never comes: 50,000 of 1 KiB grew the process by 59 MB.
  const long before = RssKib();
  FakeBroker broker([](int index, BrokerConnection& c) {
    if (index > 0) return Behave(c);
    if (!c.Handshake()) return;
    for (int i = 1; i <= 50'000; ++i) {
      if (!c.Send(Publish("readings/s", std::string(1024, 'q'), 2, static_cast<uint16_t>(i)))) return;
    }
    c.Hold();
  });
  MosquittoLink link(Options(broker.uri()));
  const Run run = PollUntil(
      link, [](const auto& e) { return HasMessage(e, "good"); }, 60'000);
  const long grown = RssKib() - before;
  CHECK_TEXT(HasMessage(run.events, "good"), Text(run.events).c_str());
  LONGS_EQUAL_TEXT(2, broker.connections(), Text(run.events).c_str());
  const std::string text = Text(run.events);
  LONGS_EQUAL_TEXT(2, Count(run.events, LinkEvent::Kind::kConnected), text.c_str());
  LONGS_EQUAL_TEXT(1, Count(run.events, LinkEvent::Kind::kDisconnected), text.c_str());
  LONGS_EQUAL_TEXT(1, Count(run.events, LinkEvent::Kind::kMessage), text.c_str());
  CHECK_TEXT(run.events.at(1).payload.find("connection dropped: the broker sent a QoS 2 message") == 0, text.c_str());
  CHECK_TEXT(grown < 16 * 1024, ("VmRSS grew by " + std::to_string(grown) + " KiB").c_str());
}
