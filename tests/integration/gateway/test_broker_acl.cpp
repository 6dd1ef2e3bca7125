// The broker accounts of docs/gateway.md with a real mosquitto on 127.0.0.1 enforcing
// packaging/mosquitto/linerwatch.acl (plus a read-only observer, as scripts/demo adds one):
// - the real linerwatch-gateway, logged in with its site's account, works: its retained status,
//   its readings and its stats get through, and the server's commit ack reaches it;
// - the same account cannot forge a commit ack (issue 15, finding 9: it would delete spooled
//   records the server never stored), cannot publish the wear, and cannot publish readings or
//   retained status for another site or read another site's commit acks (finding 16).
// - with the shipped single-site.conf's client-id and size settings, a gateway account cannot
//   take over the server's or another gateway's client id (issue 45, finding 2) nor park a
//   message larger than any linerwatch program accepts (finding 9).
// LW_IT_ACL=FILE runs the same checks against another ACL file (to see an older ACL fail);
// LW_IT_CONF=FILE takes the broker settings from another file.
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <mqtt/async_client.h>
#include <nlohmann/json.hpp>

#include "support/mosquitto_fixture.hpp"
#include "support/mqtt_recorder.hpp"
#include "unit/gateway/gateway_test_support.hpp"

// CppUTest last: its new/delete macros break standard headers included after it.
#include <CppUTest/TestHarness.h>

namespace pr = lw::protocol;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

const std::string kA = "linerwatch/v1/mine-a/cr1/";
const std::string kB = "linerwatch/v1/mine-b/cr1/";

using Client = lw::test::MqttRecorder;

}  // namespace

TEST_GROUP(BrokerAcl){};

TEST(BrokerAcl, AGatewayAccountServesItsOwnSiteAndCannotForgeAcksOrOtherSites) {
  lw::test::TempDirectory dir("lw-acl-it");
  const char* acl_override = std::getenv("LW_IT_ACL");
  const std::string acl_source = acl_override && *acl_override ? acl_override : LW_BROKER_ACL;
  {
    std::ifstream in(acl_source);
    CHECK_TRUE(in.good());
    std::ofstream out(dir.File("acl"));
    out << in.rdbuf() << "\nuser observer\ntopic read linerwatch/#\n";
  }
  lw::test::MosquittoFixture::Options o;
  o.username = "linerwatch-server";
  o.password = "server-pass";
  lw::test::MosquittoFixture::Access access;
  access.more_users = {{"mine-a", "a-pass"}, {"mine-b", "b-pass"}, {"observer", "o-pass"}};
  access.acl_file = dir.File("acl");
  lw::test::MosquittoFixture broker(o, access);
  broker.Start();

  Client observer(broker.uri(), "observer", "observer", "o-pass");
  observer.Subscribe("linerwatch/#");
  Client server(broker.uri(), "server", "linerwatch-server", "server-pass");

  // The real gateway with its site's account; its "serial port" is a file holding one frame.
  const auto frame =
      lw::gateway::test::ReadingsFrame(pr::ApiMode::kEscaped, 0x0013A20040000001ull, 1001, {lw::gateway::test::MakeRecord(1)});
  // The gateway writes its AT NP / EE queries to the "port" at start-up, at the file's offset 0:
  // 64 bytes of line noise in front of the frame take them (the decoder skips bytes before a
  // start delimiter), so the frame itself is read intact.
  {
    std::ofstream serial(dir.File("serial"), std::ios::binary);
    const std::string noise(64, '\0');
    serial.write(noise.data(), static_cast<std::streamsize>(noise.size()));
    serial.write(reinterpret_cast<const char*>(frame.data()), static_cast<std::streamsize>(frame.size()));
  }
  lw::test::ChildProcess gateway;
  gateway.Start({LW_GATEWAY_BIN,
                 "--serial",
                 dir.File("serial"),
                 "--broker",
                 broker.uri(),
                 "--site",
                 "mine-a",
                 "--crusher",
                 "cr1",
                 "--spool",
                 dir.File("spool.db"),
                 "--gateway-id",
                 "gw-a",
                 "--username",
                 "mine-a",
                 "--password",
                 "a-pass",
                 "--stats-interval",
                 "0.3",
                 "--republish-after",
                 "1"},
                dir.File("gateway.log"));
  const bool online = observer.WaitFor(kA + "gateway/status", "online");
  const bool reading = observer.WaitFor(kA + "sensors/1001/reading", "\"seq\":1");
  const bool registry = observer.WaitFor(kA + "gateway/devices/0013A20040000001", "1001");
  if (!online || !reading || !registry) FAIL(("gateway log: " + lw::test::FileTail(dir.File("gateway.log"))).c_str());
  // The server's commit ack reaches the gateway (its subscription is allowed): the spool drains.
  server.Publish(kA + "sensors/1001/committed", R"({"sensor": "1001", "seqs": [1]})");
  CHECK_TRUE(observer.WaitFor(kA + "gateway/stats", "\"spool_depth\":0"));
  CHECK_TRUE(observer.WaitFor(kA + "gateway/stats", "\"committed\":1"));

  // The same account, used by anyone who has the gateway's password.
  Client attacker(broker.uri(), "attacker", "mine-a", "a-pass");
  attacker.Publish(kA + "sensors/1001/committed", R"({"sensor": "1001", "seqs": [2, 3, 4]})");
  attacker.Publish(kA + "wear", R"({"forged": true})", true);
  attacker.Publish(kB + "sensors/2001/reading", R"({"sensor": "2001", "seq": 1, "forged": true})");
  attacker.Publish(kB + "gateway/status", R"({"state": "offline", "forged": true})", true);
  attacker.Publish(kB + "gateway/devices/0013A20099999999", R"({"forged": true})", true);
  attacker.Publish(kA + "gateway/stats", "control");  // allowed: arrives after all of the above
  CHECK_TRUE(observer.WaitFor(kA + "gateway/stats", "control"));
  CHECK_FALSE(observer.Saw(kA + "sensors/1001/committed", "[2, 3, 4]"));
  CHECK_FALSE(observer.Saw(kA + "wear", "forged"));
  CHECK_FALSE(observer.Saw(kB + "sensors/2001/reading", "forged"));
  CHECK_FALSE(observer.Saw(kB + "gateway/status", "forged"));
  CHECK_FALSE(observer.Saw(kB + "gateway/devices/0013A20099999999", "forged"));
  // Nothing forged was retained either: a new subscriber gets no retained message of site B.
  Client late(broker.uri(), "late", "observer", "o-pass");
  late.Subscribe("linerwatch/v1/mine-b/#");
  late.Subscribe(kA + "wear");
  // The broker sends a subscription's retained messages in the order of the subscriptions: the
  // gateway's own retained status, subscribed last, arrives after anything retained on the two
  // filters above, so once it is here nothing else can still be on its way (no fixed wait).
  late.Subscribe(kA + "gateway/status");
  CHECK_TRUE(late.WaitFor(kA + "gateway/status", "online"));
  const std::vector<lw::test::MqttRecorder::Message> retained = late.received();
  LONGS_EQUAL_TEXT(1, retained.size(), (retained.front().topic + ": " + retained.front().payload).c_str());

  // Another site's commit acks are not readable with site A's account; its own are.
  attacker.Subscribe(kB + "sensors/+/committed");
  attacker.Subscribe(kA + "sensors/+/committed");
  server.Publish(kB + "sensors/2001/committed", R"({"sensor": "2001", "seqs": [9]})");
  server.Publish(kA + "sensors/1001/committed", R"({"sensor": "1001", "seqs": [8]})");
  CHECK_TRUE(attacker.WaitFor(kA + "sensors/1001/committed", "[8]"));
  CHECK_FALSE(attacker.Saw(kB + "sensors/2001/committed"));

  gateway.Stop(SIGTERM);
  CHECK_TRUE(observer.WaitFor(kA + "gateway/status", "offline"));
}

namespace {
std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}
}  // namespace

TEST(BrokerAcl, AGatewayPasswordCannotTakeTheServersOrAnotherGatewaysClientId) {
  lw::test::TempDirectory dir("lw-acl-ids");
  const char* conf_override = std::getenv("LW_IT_CONF");
  const std::string shipped = ReadText(conf_override && *conf_override ? conf_override : LW_BROKER_CONF);
  lw::test::MosquittoFixture::Options o;
  o.username = "linerwatch-server";
  o.password = "server-pass";
  // The shipped settings that bind client ids and sizes (its listeners and files are the fixture's).
  for (const char* line : {"use_username_as_clientid true\n", "message_size_limit 1048576\n"}) {
    if (shipped.find(line) != std::string::npos) o.extra_config += line;
  }
  {
    std::ofstream out(dir.File("acl"));
    out << ReadText(LW_BROKER_ACL) << "\nuser observer\ntopic read linerwatch/#\n";
  }
  lw::test::MosquittoFixture::Access access;
  access.more_users = {{"mine-a", "a-pass"}, {"mine-b", "b-pass"}, {"mine-b/cr2", "b2-pass"}, {"observer", "o-pass"}};
  access.acl_file = dir.File("acl");
  lw::test::MosquittoFixture broker(o, access);
  broker.Start();

  // The server and site B's two gateways, with persistent sessions as they run.
  Client server(broker.uri(), "linerwatch-server", "linerwatch-server", "server-pass", "", false);
  server.Subscribe("linerwatch/v1/+/+/sensors/+/reading");
  Client gateway_b(broker.uri(), "gw-b", "mine-b", "b-pass", "", false);
  gateway_b.Subscribe(kB + "sensors/+/committed");
  Client gateway_b2(broker.uri(), "gw-b2", "mine-b/cr2", "b2-pass", "", false);
  gateway_b2.Subscribe("linerwatch/v1/mine-b/cr2/sensors/+/committed");
  // Site A's password, claiming each of their client ids in turn.
  for (const char* id : {"linerwatch-server", "gw-b", "mine-b", "mine-b/cr2"}) {
    Client claim(broker.uri(), id, "mine-a", "a-pass");
    claim.Publish(kA + "gateway/stats", id);
  }
  Client attacker(broker.uri(), "attacker", "mine-a", "a-pass");
  // All three still hold their sessions: what is published now reaches them.
  attacker.Publish(kA + "sensors/1001/reading", R"({"sensor": "1001", "seq": 1})");
  server.Publish(kB + "sensors/2001/committed", R"({"sensor": "2001", "seqs": [1]})");
  server.Publish("linerwatch/v1/mine-b/cr2/sensors/3001/committed", R"({"sensor": "3001", "seqs": [1]})");
  CHECK_TRUE(server.WaitFor(kA + "sensors/1001/reading", "\"seq\": 1"));
  CHECK_TRUE(gateway_b.WaitFor(kB + "sensors/2001/committed", "[1]"));
  CHECK_TRUE(gateway_b2.WaitFor("linerwatch/v1/mine-b/cr2/sensors/3001/committed", "[1]"));
  LONGS_EQUAL(0, server.lost());
  LONGS_EQUAL(0, gateway_b.lost());
  LONGS_EQUAL(0, gateway_b2.lost());
  // A per-crusher account reaches its own crusher only.
  gateway_b2.Publish("linerwatch/v1/mine-b/cr9/sensors/3001/reading", R"({"forged": true})");
  gateway_b2.Publish("linerwatch/v1/mine-b/cr2/sensors/3001/reading", R"({"seq": 2})");
  CHECK_TRUE(server.WaitFor("linerwatch/v1/mine-b/cr2/sensors/3001/reading", "\"seq\": 2"));
  CHECK_FALSE(server.Saw("linerwatch/v1/mine-b/cr9/sensors/3001/reading"));

  // A retained message larger than any linerwatch program accepts is not kept (nor forwarded).
  attacker.Publish(kA + "gateway/devices/0013A20040000001", std::string(1048577, 'x'), true);
  attacker.Publish(kA + "gateway/devices/0013A20040000002", R"({"small": true})", true);
  Client late(broker.uri(), "late", "observer", "o-pass");
  late.Subscribe(kA + "gateway/devices/0013A20040000001");
  late.Subscribe(kA + "gateway/devices/0013A20040000002");  // its retained message arrives after the first's
  CHECK_TRUE(late.WaitFor(kA + "gateway/devices/0013A20040000002", "small"));
  CHECK_FALSE(late.Saw(kA + "gateway/devices/0013A20040000001"));
}
