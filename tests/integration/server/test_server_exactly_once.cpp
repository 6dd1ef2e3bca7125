// The real linerwatch-server against a real mosquitto on 127.0.0.1: the test plays the gateway
// (publishes readings QoS 1, republishes what the server has not confirmed), SIGKILLs the server
// twice mid-stream and restarts it. Every reading must end up stored exactly once, confirmed, and
// the retained global wear must equal the reconstruction computed offline from the same readings
// (and the folder's laser scan). And a batch (docs/mqtt.md, *Batches*): stored record by record,
// acked with the server's announcement.
#include <mqtt/async_client.h>

#include <chrono>
#include <map>
#include <random>
#include <set>
#include <thread>

#include "core/reconstruction.hpp"
#include "mqtt/messages.hpp"
#include "server/store.hpp"
#include "support/mosquitto_fixture.hpp"
#include "unit/server/server_fixture.hpp"

#include <httplib.h>  // after Eigen (<resolv.h> defines _res)

#include <CppUTest/TestHarness.h>  // last

using nlohmann::json;

namespace {

int64_t NowMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

struct ServerProcess {
  lw::test::ChildProcess process;
  std::vector<std::string> argv;
  std::string log;
  std::string db;
  int http_port = 0;
  /// The server on `broker_uri` with `folder`'s crushers, its database and log in the folder.
  void Configure(const std::string& broker_uri, const lw::test::CrusherFolder& folder, const std::vector<std::string>& extra) {
    http_port = lw::test::FreeLoopbackPort();
    log = folder.dir.File("server.log");
    db = folder.dir.File("server.sqlite");
    argv = {LW_SERVER_BIN,   "--broker",      broker_uri,  "--db", db, "--http", "127.0.0.1:" + std::to_string(http_port),
            "--crusher-dir", folder.crushers, "--web-dir", ""};
    argv.insert(argv.end(), extra.begin(), extra.end());
  }
  void Start() {
    process.Start(argv, log);
    // Up to 60 s: the map model is built at start-up, slow on a loaded machine.
    for (int i = 0; i < 1200 && !lw::test::PortAccepts(http_port); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (!lw::test::PortAccepts(http_port)) FAIL(("server did not come up: " + lw::test::FileTail(log)).c_str());
  }
};

/// Connects `client` as a gateway would (a clean session) and subscribes to `root`'s commit acks.
void ConnectAsGateway(mqtt::async_client& client, const std::string& root) {
  mqtt::connect_options opts;
  opts.set_clean_session(true);
  client.start_consuming();
  client.connect(opts)->wait();
  client.subscribe(root + "sensors/+/committed", 1)->wait();
}

}  // namespace

TEST_GROUP(ServerExactlyOnce) {
  lw::test::MosquittoFixture broker;
  lw::test::CrusherFolder folder{30, 5};
  std::vector<lw::server::Incoming> messages = lw::test::Messages(folder.bundle, "site1");
  ServerProcess server;
  void setup() override {
    broker.Start();
  }
};

TEST(ServerExactlyOnce, SigkillMidStreamStoresEveryReadingOnceAndWearMatchesOffline) {
  server.Configure(broker.uri(), folder, {"--wear-interval-ms", "200"});
  const std::string db = server.db;
  server.Start();

  mqtt::async_client client(broker.uri(), "test-gateway", nullptr);
  const std::string root = "linerwatch/v1/site1/" + folder.id() + "/";
  ConnectAsGateway(client, root);
  client.subscribe(root + "wear", 1)->wait();

  std::set<std::pair<std::string, int64_t>> confirmed;
  std::map<size_t, int64_t> sent_at;  // message index -> last publish (ms)
  std::string last_wear;
  std::mt19937 rng(42);
  const size_t kill_at[2] = {messages.size() / 4 + rng() % (messages.size() / 8),
                             messages.size() / 2 + rng() % (messages.size() / 8)};
  int kills = 0;
  size_t next = 0;
  // 120 s for the stream itself; the restarts' start-ups (each waited for, up to 60 s, while the
  // map model is built) are added to it as they happen, so a slow start-up is not counted twice.
  int64_t deadline = NowMs() + 120'000;
  // Paho refuses a publish while too many are in flight ("No more messages can be buffered", seen
  // on a loaded machine): like the gateway, try again on a later round instead of failing the test.
  auto try_publish = [&](const lw::server::Incoming& m) {
    try {
      client.publish(m.topic, m.payload, 1, false);
      return true;
    } catch (const mqtt::exception& e) {
      if (e.get_return_code() != MQTTASYNC_MAX_BUFFERED_MESSAGES) throw;
      return false;
    }
  };
  while (confirmed.size() < messages.size() && NowMs() < deadline) {
    // Publish new readings at a steady pace, and republish any unconfirmed after 1.5 s.
    for (int burst = 0; burst < 40 && next < messages.size(); ++burst, ++next) {
      if (!try_publish(messages[next])) break;
      sent_at[next] = NowMs();
    }
    if (kills < 2 && confirmed.size() >= kill_at[kills]) {
      server.process.Kill();  // SIGKILL: no goodbye, mid-batch
      ++kills;
      std::this_thread::sleep_for(std::chrono::milliseconds(300));
      const int64_t restart = NowMs();
      server.Start();
      deadline += NowMs() - restart;
    }
    const int64_t now = NowMs();
    for (auto& [i, t] : sent_at) {
      const auto& m = messages[i];
      const json j = json::parse(m.payload);
      if (now - t > 1500 && !confirmed.count({m.sensor, j["seq"].get<int64_t>()}) && try_publish(m)) t = now;
    }
    mqtt::const_message_ptr msg;
    while (client.try_consume_message_for(&msg, std::chrono::milliseconds(20))) {
      if (!msg) continue;
      const json j = json::parse(msg->to_string(), nullptr, false);
      if (msg->get_topic() == root + "wear") {
        last_wear = msg->to_string();
        continue;
      }
      for (const auto& s : j["seqs"]) confirmed.insert({j["sensor"].get<std::string>(), s.get<int64_t>()});
    }
  }
  LONGS_EQUAL(2, kills);
  LONGS_EQUAL_TEXT(messages.size(), confirmed.size(), lw::test::FileTail(server.log).c_str());

  // Stored exactly once, with the content that was sent.
  {
    lw::server::Store store(db);
    const auto stored = store.All(folder.id());
    LONGS_EQUAL(messages.size(), stored.size());
    std::map<std::pair<std::string, int64_t>, const lw::server::StoredReading*> by_key;
    for (const auto& r : stored) by_key[{r.sensor, r.seq}] = &r;
    LONGS_EQUAL(messages.size(), by_key.size());
    for (const auto& m : messages) {
      const json j = json::parse(m.payload);
      const auto it = by_key.find({m.sensor, j["seq"].get<int64_t>()});
      CHECK(it != by_key.end());
      DOUBLES_EQUAL(j["thickness_mm"].get<double>(), it->second->thickness_mm, 0);
    }
  }

  // The REST view agrees with the store.
  httplib::Client http("127.0.0.1", server.http_port);
  auto res = http.Get("/api/v1/crushers/" + folder.id() + "/sensors");
  CHECK(res);
  LONGS_EQUAL_TEXT(200, res->status, res->body.c_str());
  long total = 0;
  const json sensors = json::parse(res->body);
  for (const auto& s : sensors["sensors"]) total += s["reading_count"].get<long>();
  LONGS_EQUAL(messages.size(), total);

  // Retained global wear (wait for the final publication) equals the offline reconstruction.
  const auto& b = folder.bundle;
  const auto last =
      std::max_element(b.readings.begin(), b.readings.end(), [](const auto& x, const auto& y) { return x.time < y.time; })->time;
  // The crusher folder has a laser scan: the server applies the newest one, so does the offline plan.
  CHECK_FALSE(b.scans.empty());
  const auto offline = lw::test::OfflineLiveWear(b, last);
  // Wait for the wear computed from every sensor's last reading: an earlier publication can
  // already carry the final time (another sensor's last reading) with one sensor still behind.
  std::map<std::string, int64_t> last_seq;
  for (const auto& m : messages) last_seq[m.sensor] = std::max(last_seq[m.sensor], json::parse(m.payload)["seq"].get<int64_t>());
  const auto complete = [&](const std::string& text) {
    if (text.empty()) return false;
    const json w = json::parse(text);
    std::map<std::string, int64_t> used;
    for (const auto& r : w["readings_used"]) used[r["sensor"].get<std::string>()] = r["seq"].get<int64_t>();
    return used == last_seq;
  };
  // Up to 60 s: the wear is recomputed every 200 ms, but a reconstruction on a loaded machine can
  // take seconds; only a wear that never comes reaches the bound.
  const int64_t wear_deadline = NowMs() + 60'000;
  while (NowMs() < wear_deadline && !complete(last_wear)) {
    mqtt::const_message_ptr msg;
    if (client.try_consume_message_for(&msg, std::chrono::milliseconds(100)) && msg && msg->get_topic() == root + "wear") {
      last_wear = msg->to_string();
    }
  }
  CHECK_TEXT(complete(last_wear), ("no wear from every sensor's last reading; last: " + last_wear).c_str());
  CHECK_FALSE(last_wear.empty());
  const json wear = json::parse(last_wear);
  STRCMP_EQUAL(lw::core::FormatIsoTime(last).c_str(), wear["time"].get<std::string>().c_str());
  DOUBLES_EQUAL(offline.min_thickness_mm, wear["min_thickness_mm"].get<double>(), 1e-3);
  STRCMP_EQUAL(b.map.sha256.c_str(), wear["map_sha256"].get<std::string>().c_str());
  for (size_t r = 0; r < offline.rows.size(); ++r) {
    DOUBLES_EQUAL(offline.rows[r].min_thickness_mm, wear["rows"][r]["min_thickness_mm"].get<double>(), 1e-3);
  }
  client.disconnect()->wait();
  CHECK(server.process.Stop(SIGTERM) == 0);
}

// The real server takes a batch of one sensor's records: each record is stored (or quarantined)
// on its own, one commit ack names every seq, and the ack announces batches ("batch": 64).
TEST(ServerExactlyOnce, ABatchIsStoredRecordByRecordAndAckedWithTheAnnouncement) {
  server.Configure(broker.uri(), folder, {});
  const std::string db = server.db;
  server.Start();
  mqtt::async_client client(broker.uri(), "test-gateway", nullptr);
  const std::string root = "linerwatch/v1/site1/" + folder.id() + "/";
  ConnectAsGateway(client, root);

  // Five records of the first sensor, in seq order, and one record whose time is not a time.
  const std::string sensor = messages.front().sensor;
  std::vector<std::string> texts;
  std::set<int64_t> expected;
  for (const auto& m : messages) {
    if (m.sensor != sensor || texts.size() == 5) continue;
    texts.push_back(m.payload);
    expected.insert(json::parse(m.payload)["seq"].get<int64_t>());
  }
  LONGS_EQUAL(5, texts.size());
  const int64_t bad_seq = *expected.rbegin() + 1000;
  texts.push_back(R"({"seq":)" + std::to_string(bad_seq) +
                  R"(,"time":"yesterday","thickness_mm":1,"loops_intact":1,"flags":0,"battery_mv":3000})");
  expected.insert(bad_seq);
  const std::string batch = lw::mqtt::EncodeReadingBatch(sensor, {texts.begin(), texts.end()});
  // Published again every 1.5 s until every seq is acked, as the gateway republishes: a server that
  // has only just connected may not have subscribed yet (seen once in CI on a loaded machine).
  int64_t published_at = 0;
  std::set<int64_t> acked;
  uint32_t announced = 0;
  const int64_t deadline = NowMs() + 90'000;
  while (acked != expected && NowMs() < deadline) {
    if (NowMs() - published_at > 1500) {
      client.publish(root + "sensors/" + sensor + "/reading", batch, 1, false)->wait();
      published_at = NowMs();
    }
    mqtt::const_message_ptr msg;
    if (!client.try_consume_message_for(&msg, std::chrono::milliseconds(100)) || !msg) continue;
    std::string error;
    const auto ack = lw::mqtt::DecodeCommitAck(msg->to_string(), sensor, &error);
    CHECK_TEXT(ack.has_value(), error.c_str());
    acked.insert(ack->seqs.begin(), ack->seqs.end());
    announced = ack->batch;
  }
  CHECK_TEXT(acked == expected, lw::test::FileTail(server.log).c_str());
  LONGS_EQUAL(lw::mqtt::kMaxReadingBatch, announced);
  {
    lw::server::Store store(db);
    const auto stored = store.All(folder.id());
    LONGS_EQUAL(5, stored.size());
    for (const auto& r : stored) CHECK(expected.count(r.seq) && r.seq != bad_seq);
    LONGS_EQUAL(1, store.CountRejected());
  }
  client.disconnect()->wait();
  CHECK(server.process.Stop(SIGTERM) == 0);
}
