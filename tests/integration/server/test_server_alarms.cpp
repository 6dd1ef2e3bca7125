// Alarms of the real linerwatch-server with a real mosquitto on loopback (docs/alarms.md): a
// gateway's retained offline status raises gateway_offline, which reaches the retained
// `.../alarms` and the SSE `alarm` event; an acknowledgement over REST is published; a restart on
// the same database keeps the alarm (same id, acknowledged) and raises it no second time; the
// gateway back online clears it.
#include <atomic>
#include <chrono>
#include <functional>
#include <thread>

#include "core/time.hpp"
#include "support/mosquitto_fixture.hpp"
#include "support/mqtt_recorder.hpp"
#include "unit/server/server_fixture.hpp"

#include <httplib.h>  // after Eigen (<resolv.h> defines _res)

#include <CppUTest/TestHarness.h>  // last

using nlohmann::json;

namespace {

struct Server {
  lw::test::ChildProcess process;
  std::string log;
  int port = 0;
  void Start(const std::string& broker, const lw::test::CrusherFolder& folder) {
    if (port == 0) port = lw::test::FreeLoopbackPort();
    log = folder.dir.File("server.log");
    process.Start({LW_SERVER_BIN, "--broker", broker, "--db", folder.dir.File("server.sqlite"), "--http",
                   "127.0.0.1:" + std::to_string(port), "--crusher-dir", folder.crushers, "--web-dir", ""},
                  log);
    for (int i = 0; i < 1200 && !lw::test::PortAccepts(port); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (!lw::test::PortAccepts(port)) FAIL(("server did not come up: " + lw::test::FileTail(log)).c_str());
  }
};

/// The gateway_offline alarms of the newest retained `.../alarms` message on `topic`.
std::vector<json> GatewayAlarms(lw::test::MqttRecorder& mqtt, const std::string& topic) {
  std::vector<json> out;
  const std::string last = mqtt.Last(topic);
  if (last.empty()) return out;
  const json message = json::parse(last);  // held: a range-for over a temporary's member dangles
  for (const json& a : message["alarms"])
    if (a["rule"] == "gateway_offline") out.push_back(a);
  return out;
}

/// Waits (bounded) until `ok` holds for GatewayAlarms.
bool WaitFor(lw::test::MqttRecorder& mqtt, const std::string& topic, const std::function<bool(const std::vector<json>&)>& ok) {
  for (int i = 0; i < 600; ++i) {
    if (ok(GatewayAlarms(mqtt, topic))) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return false;
}

}  // namespace

TEST_GROUP(ServerAlarms) {
  lw::test::MosquittoFixture broker;
  lw::test::CrusherFolder folder{10, 5};
  Server server;
  void setup() override {
    broker.Start();
  }
};

TEST(ServerAlarms, AGatewaysLastWillRaisesOneAlarmPublishedRetainedAndOverSseKeptAcrossARestart) {
  server.Start(broker.uri(), folder);
  const std::string root = "linerwatch/v1/site1/" + folder.id() + "/";
  lw::test::MqttRecorder mqtt(broker.uri(), "observer", "test", "x");
  mqtt.Subscribe(root + "alarms");
  // One reading binds the crusher to site1 (where its retained topics go).
  const auto messages = lw::test::Messages(folder.bundle);
  mqtt.Publish(messages.front().topic, messages.front().payload);
  httplib::Client http("127.0.0.1", server.port);
  http.set_read_timeout(60, 0);
  const std::string base = "/api/v1/crushers/" + folder.id() + "/alarms";
  // The SSE stream, read on its own thread until an `alarm` event comes.
  std::atomic<bool> saw_event{false};
  std::thread sse([&] {
    httplib::Client stream("127.0.0.1", server.port);
    stream.set_read_timeout(60, 0);
    std::string text;
    stream.Get("/api/v1/crushers/" + folder.id() + "/events", [&](const char* data, size_t n) {
      text.append(data, n);
      saw_event = text.find("event: alarm") != std::string::npos && text.find("gateway_offline") != std::string::npos;
      return !saw_event;
    });
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // the stream is open before the alarm
  const std::string hour_ago = lw::core::FormatIsoTime(
      std::chrono::time_point_cast<std::chrono::seconds>(std::chrono::system_clock::now()) - std::chrono::hours(1));
  mqtt.Publish(root + "gateway/status", json{{"state", "offline"}, {"gateway", "gw1"}, {"time", hour_ago}}.dump(), true);
  const bool raised_one = WaitFor(mqtt, root + "alarms", [](const auto& a) { return a.size() == 1; });
  CHECK_TEXT(raised_one, (mqtt.Last(root + "alarms") + "\n" + lw::test::FileTail(server.log)).c_str());
  const json raised = GatewayAlarms(mqtt, root + "alarms").front();
  STRCMP_EQUAL("active", raised["state"].get<std::string>().c_str());
  STRCMP_EQUAL("gw1", raised["subject"].get<std::string>().c_str());
  sse.join();
  CHECK_TRUE(saw_event.load());

  const std::string ack = base + "/" + std::to_string(raised["id"].get<int64_t>()) + "/ack";
  auto res = http.Post(ack, "", "application/json");
  CHECK(res);
  LONGS_EQUAL_TEXT(200, res->status, res->body.c_str());
  CHECK(WaitFor(mqtt, root + "alarms", [](const auto& a) { return a.size() == 1 && a[0]["state"] == "acknowledged"; }));

  server.process.Stop(SIGTERM);
  lw::test::MqttRecorder after(broker.uri(), "observer2", "test", "x");
  after.Subscribe(root + "alarms");
  server.Start(broker.uri(), folder);
  // The restarted server publishes the stored set again (and the broker's retained gateway status
  // comes back to it): the same alarm, acknowledged, and no second one.
  CHECK(WaitFor(after, root + "alarms", [&](const auto& a) {
    return after.Count(root + "alarms") >= 2 && a.size() == 1 && a[0]["id"] == raised["id"] && a[0]["state"] == "acknowledged";
  }));
  std::this_thread::sleep_for(std::chrono::seconds(1));
  res = http.Get(base);
  CHECK(res);
  size_t gateway_alarms = 0;
  const json listed = json::parse(res->body);
  for (const json& a : listed["alarms"]) gateway_alarms += a["rule"] == "gateway_offline";
  LONGS_EQUAL(1, gateway_alarms);

  mqtt.Publish(root + "gateway/status", json{{"state", "online"}, {"gateway", "gw1"}, {"time", hour_ago}}.dump(), true);
  CHECK(WaitFor(after, root + "alarms", [](const auto& a) { return a.empty(); }));
  res = http.Post(ack, "", "application/json");
  CHECK(res);
  LONGS_EQUAL(409, res->status);
}
