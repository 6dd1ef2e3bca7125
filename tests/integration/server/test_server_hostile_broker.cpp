// The real linerwatch-server against a hostile broker (support/fake_broker.hpp, a plain TCP
// listener on 127.0.0.1): on its first connection the "broker" sends a reading that is not JSON,
// one that is not UTF-8, messages on topics the server never subscribed to, a valid reading and
// then a QoS 3 PUBLISH (not MQTT); on the second, another valid reading. The server must store the
// two valid readings and nothing else, quarantine the two bad ones, say in its log what was wrong
// with each message and with the connection, connect again, and acknowledge the valid readings
// (the first one's ack waiting for the second connection).
#include <chrono>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "support/fake_broker.hpp"
#include "support/mosquitto_fixture.hpp"
#include "unit/server/server_fixture.hpp"

#include <httplib.h>  // after Eigen (<resolv.h> defines _res)

#include <CppUTest/TestHarness.h>  // last

using lw::test::BrokerConnection;
using lw::test::FakeBroker;
using lw::test::Publish;
using nlohmann::json;

namespace {

int64_t NowMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::string ReadFile(const std::string& path) {
  return lw::test::FileTail(path, 1 << 20);
}

/// Every line of `text` that holds `what`.
int Lines(const std::string& text, const std::string& what) {
  int n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

}  // namespace

TEST_GROUP(ServerHostileBroker){};

TEST(ServerHostileBroker, InvalidMessagesAreNotStoredAndNamedInTheLogAndABrokenConnectionIsReconnected) {
  lw::test::CrusherFolder folder{30, 5};
  const std::vector<lw::server::Incoming> messages = lw::test::Messages(folder.bundle, "site1");
  const std::string root = "linerwatch/v1/site1/" + folder.id() + "/";
  std::mutex mutex;
  std::vector<std::string> acks;  // payloads of the commit acks the server published
  const auto collect_acks = [&mutex, &acks](BrokerConnection& c) {
    while (auto p = c.ReadUntil(3, 60'000)) {
      const std::string& b = p->body;
      const size_t topic_len = (static_cast<uint8_t>(b[0]) << 8) | static_cast<uint8_t>(b[1]);
      const size_t header = 2 + topic_len + ((p->header & 0x06) ? 2 : 0);
      std::lock_guard<std::mutex> lock(mutex);
      acks.push_back(b.substr(2, topic_len) + " " + b.substr(header));
    }
  };
  FakeBroker broker([&](int index, BrokerConnection& c) {
    if (!c.Handshake()) return;
    if (index == 0) {
      c.Send(Publish(messages[0].topic, "this is not json", 1, 1) +
             Publish(messages[1].topic, "{\"sensor\":\"" + messages[1].sensor + "\",\"seq\":1,\"note\":\"\xff\xfe\"}", 1, 2) +
             Publish("elsewhere/x", "unsolicited", 1, 3) + Publish(root + "wear", "{}", 0) +
             Publish(messages[2].topic, messages[2].payload, 1, 4));
      // Every QoS 1 message is acknowledged as it is read: then the PUBLISH that is not MQTT. Up to
      // 90 s each: the server may be building its map model (tens of seconds on a loaded machine).
      for (int acked = 0; acked < 4;) {
        auto p = c.ReadUntil(4, 90'000);
        if (!p) return;
        ++acked;
      }
      c.Send(Publish(messages[3].topic, messages[3].payload, 3, 5));
      c.Hold(60'000);
      return;
    }
    c.Send(Publish(messages[4].topic, messages[4].payload, 1, 6));
    collect_acks(c);
  });

  lw::test::ChildProcess server;
  const int http_port = lw::test::FreeLoopbackPort();
  const std::string log = folder.dir.File("server.log");
  server.Start({LW_SERVER_BIN, "--broker", broker.uri(), "--db", folder.dir.File("server.sqlite"), "--http",
                "127.0.0.1:" + std::to_string(http_port), "--crusher-dir", folder.crushers, "--web-dir", ""},
               log);
  httplib::Client http("127.0.0.1", http_port);
  const auto acked = [&](const lw::server::Incoming& m) {
    const json j = json::parse(m.payload);
    const std::string seq = std::to_string(j["seq"].get<int64_t>());
    std::lock_guard<std::mutex> lock(mutex);
    for (const std::string& a : acks) {
      if (a.rfind(root + "sensors/" + m.sensor + "/committed ", 0) == 0 &&
          json::parse(a.substr(a.find(' ') + 1))["seqs"].dump().find(seq) != std::string::npos) {
        return true;
      }
    }
    return false;
  };
  json health = json::object();
  for (const int64_t end = NowMs() + 90'000; NowMs() < end;) {
    if (auto r = http.Get("/healthz"); r && r->status == 200) health = json::parse(r->body);
    if (health.value("readings_stored", 0) == 2 && health.value("rejected", 0) == 2 && acked(messages[2]) && acked(messages[4]) &&
        Lines(ReadFile(log), "ignored") == 2) {
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  const std::string text = ReadFile(log);
  // Stored: the two valid readings, nothing of the others; the two bad readings quarantined.
  LONGS_EQUAL_TEXT(2, health.value("readings_stored", -1), (health.dump() + "\n" + text).c_str());
  LONGS_EQUAL_TEXT(2, health.value("rejected", -1), (health.dump() + "\n" + text).c_str());
  for (const size_t i : {size_t{2}, size_t{4}}) {
    const auto r = http.Get("/api/v1/crushers/" + folder.id() + "/sensors/" + messages[i].sensor + "/readings");
    CHECK(r && r->status == 200);
    const json page = json::parse(r->body);
    const json sent = json::parse(messages[i].payload);
    bool found = false;
    for (const json& reading : page["readings"]) found = found || reading["seq"] == sent["seq"];
    CHECK_TEXT(found, r->body.c_str());
    CHECK_TEXT(acked(messages[i]), ("no commit ack for message " + std::to_string(i)).c_str());
  }
  // The QoS 3 message is not stored.
  {
    const auto r = http.Get("/api/v1/crushers/" + folder.id() + "/sensors/" + messages[3].sensor + "/readings");
    CHECK(r && r->status == 200);
    const json sent = json::parse(messages[3].payload);
    for (const json& reading : json::parse(r->body)["readings"]) {
      CHECK_TEXT(!(reading["seq"] == sent["seq"] && reading["time"] == sent["time"]), r->body.c_str());
    }
  }
  // The log says what was wrong with each message and with the connection.
  CHECK_TEXT(Lines(text, "rejected " + messages[0].topic + ": malformed JSON\n") == 1, text.c_str());
  CHECK_TEXT(Lines(text, "rejected " + messages[1].topic + ": malformed JSON: text that is not UTF-8 at byte ") == 1,
             text.c_str());
  CHECK_TEXT(Lines(text, "broker: message on 'elsewhere/x' ignored (11 bytes): not a reading topic") == 1, text.c_str());
  CHECK_TEXT(Lines(text, "broker: message on '" + root + "wear' ignored (2 bytes): not a reading topic") == 1, text.c_str());
  CHECK_TEXT(Lines(text, "broker: connection lost: A network protocol error") == 1, text.c_str());
  CHECK_TEXT(Lines(text, "connected to " + broker.uri()) == 2, text.c_str());
  LONGS_EQUAL_TEXT(2, broker.connections(), text.c_str());
  server.Signal(SIGTERM);
  LONGS_EQUAL_TEXT(0, server.Wait(), lw::test::FileTail(log).c_str());
}

// Finding (Low): a second server started on the same --db and ran beside the first (both acking
// readings and publishing the wear). It now stops at once with the reason; the first runs on.
TEST(ServerHostileBroker, ASecondServerOnTheSameDatabaseIsRefused) {
  lw::test::CrusherFolder folder{5, 3};
  const std::string broker = "tcp://127.0.0.1:" + std::to_string(lw::test::FreeLoopbackPort());  // nothing listens
  const auto start = [&](lw::test::ChildProcess& p, int http_port, const std::string& log) {
    p.Start({LW_SERVER_BIN, "--broker", broker, "--db", folder.dir.File("server.sqlite"), "--http",
             "127.0.0.1:" + std::to_string(http_port), "--crusher-dir", folder.crushers, "--web-dir", ""},
            log);
  };
  lw::test::ChildProcess first, second;
  const int first_port = lw::test::FreeLoopbackPort();
  start(first, first_port, folder.dir.File("first.log"));
  httplib::Client http("127.0.0.1", first_port);
  bool up = false;
  for (const int64_t end = NowMs() + 90'000; !up && NowMs() < end;) {
    const auto r = http.Get("/healthz");
    up = r && (r->status == 200 || r->status == 503);
    if (!up) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  CHECK_TEXT(up, lw::test::FileTail(folder.dir.File("first.log")).c_str());
  start(second, lw::test::FreeLoopbackPort(), folder.dir.File("second.log"));
  LONGS_EQUAL_TEXT(1, second.Wait(), lw::test::FileTail(folder.dir.File("second.log")).c_str());
  const std::string said = ReadFile(folder.dir.File("second.log"));
  CHECK_TEXT(said.find("is in use by another linerwatch-server") != std::string::npos, said.c_str());
  const auto r = http.Get("/healthz");
  CHECK(r && (r->status == 200 || r->status == 503));
  first.Signal(SIGTERM);
  LONGS_EQUAL(0, first.Wait());
}
