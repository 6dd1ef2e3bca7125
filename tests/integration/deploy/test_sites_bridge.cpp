// Many sites, one centre (docs/deploy.md), with real programs on 127.0.0.1:
//   site mine-a: mosquitto (linerwatch.acl) + the real linerwatch-gateway fed through a pty
//   site mine-b: the same
//   each site broker bridges to the central broker with packaging/mosquitto/site-bridge.conf
//   (mosquitto's own bridge, TLS, the site's own account), through a TCP relay the test can cut
//   the central broker: TLS, linerwatch.acl; the real linerwatch-server logged in there.
// Checks: readings of both sites are stored exactly once (the stored set equals the sent set) and
// the commit acks flow back (both spools drain); while site A's link is cut its new readings wait
// and site B's go on, and after the link is restored nothing is lost; a gateway of site A that
// publishes as site B is refused by the site broker (nothing of it reaches the centre or the
// database, its spool never drains), and so is site A's account publishing a site B reading
// straight at the central broker; site A's account on the central broker cannot read site B.
// LW_IT_VERBOSE=1 prints the logs at the end.
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <mqtt/async_client.h>
#include <nlohmann/json.hpp>

#include "server/store.hpp"
#include "sim/campaign.hpp"
#include "support/mosquitto_fixture.hpp"
#include "support/mqtt_recorder.hpp"
#include "support/raw_pty.hpp"
#include "unit/gateway/gateway_test_support.hpp"

#include <httplib.h>  // after Eigen (<resolv.h> defines _res)

// CppUTest last: its new/delete macros break standard headers included after it.
#include <CppUTest/TestHarness.h>

namespace pr = lw::protocol;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

int64_t NowMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Wall-clock time of day (UTC, ms) for the test's output: lines up with the brokers' and the
// programs' logs when a run is looked into.
std::string Utc() {
  const auto now = std::chrono::system_clock::now();
  const std::time_t t = std::chrono::system_clock::to_time_t(now);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::snprintf(buf, sizeof buf, "%02d:%02d:%02d.%03d", tm.tm_hour, tm.tm_min, tm.tm_sec,
                static_cast<int>(std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000));
  return buf;
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void ReplaceAll(std::string& s, const std::string& from, const std::string& to) {
  for (size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size())) s.replace(at, from.size(), to);
}

// A TCP relay 127.0.0.1:port() -> 127.0.0.1:target: the link between a site and the centre. Cut()
// closes every connection and stops listening until Restore(): a connection attempt meanwhile is
// refused (RST), as when the centre is unreachable.
//
// Not "accept, then close at once": then the site broker's bridge gets a TCP connection whose TLS
// handshake the peer ends, and mosquitto 2.0.11 (Debian 12) closes the bridge's socket in
// net__socket_connect_tls without taking its context out of the broker's socket hash; at the
// next reconnect the context is added a second time, the hash's list loops, and the broker spins
// in keepalive__check for good (100% CPU, no client served; docs/deploy.md). Whether that
// happens is a race (does the relay's close come before or after mosquitto's first SSL_connect),
// lost mostly on a loaded machine: it made this test fail in CI, the site broker frozen right
// after the link came back.
class LinkRelay {
 public:
  explicit LinkRelay(int target) : target_(target) {
    // An explicit port (not 0): the kernel keeps it for this socket while it does not listen.
    port_ = lw::test::FreeLoopbackPort();
    listener_ = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    const int one = 1;
    setsockopt(listener_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(static_cast<uint16_t>(port_));
    if (bind(listener_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || listen(listener_, 16) != 0) {
      throw std::runtime_error("LinkRelay: cannot listen on 127.0.0.1:" + std::to_string(port_));
    }
    thread_ = std::thread([this] { Run(); });
  }
  ~LinkRelay() {
    stop_ = true;
    thread_.join();
    for (auto& [a, b] : pairs_) {
      close(a);
      close(b);
    }
    close(listener_);
  }
  int port() const { return port_; }
  /// Returns once every connection is closed and new ones are refused.
  void Cut() {
    cut_done_ = false;
    cut_ = true;
    while (!cut_done_) std::this_thread::sleep_for(5ms);
  }
  /// Returns once the relay accepts connections again.
  void Restore() {
    restore_done_ = false;
    cut_ = false;
    while (!restore_done_) std::this_thread::sleep_for(5ms);
  }

 private:
  void Run() {
    char buf[16384];
    bool listening = true;
    while (!stop_) {
      if (cut_ && listening) {
        // Linux: shutdown(SHUT_RD) of a listening socket stops listening (queued and new
        // connection attempts are reset); the socket keeps its port and can listen() again.
        if (shutdown(listener_, SHUT_RD) != 0) std::perror("LinkRelay: shutdown of the listener");
        listening = false;
        // shutdown, not only close: a child forked meanwhile may hold a copy of a descriptor.
        for (auto& [a, b] : pairs_) {
          shutdown(a, SHUT_RDWR);
          shutdown(b, SHUT_RDWR);
          close(a);
          close(b);
        }
        pairs_.clear();
        cut_done_ = true;
      } else if (!cut_ && !listening) {
        if (listen(listener_, 16) != 0) std::perror("LinkRelay: listen again");
        listening = true;
        restore_done_ = true;
      }
      std::vector<pollfd> fds{{listening ? listener_ : -1, POLLIN, 0}};
      for (auto& [a, b] : pairs_) {
        fds.push_back({a, POLLIN, 0});
        fds.push_back({b, POLLIN, 0});
      }
      if (poll(fds.data(), fds.size(), 50) <= 0) continue;
      if (fds[0].revents & POLLIN) {
        const int c = accept4(listener_, nullptr, nullptr, SOCK_CLOEXEC);
        if (c >= 0) {
          const int u = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
          sockaddr_in a{};
          a.sin_family = AF_INET;
          a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
          a.sin_port = htons(static_cast<uint16_t>(target_));
          if (connect(u, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0) {
            pairs_.push_back({c, u});
          } else {
            close(c);
            close(u);
          }
        }
      }
      std::vector<size_t> dead;
      for (size_t i = 0; i < pairs_.size(); ++i) {
        for (int side = 0; side < 2; ++side) {
          const pollfd& p = fds[1 + 2 * i + static_cast<size_t>(side)];
          if (!(p.revents & (POLLIN | POLLHUP | POLLERR))) continue;
          const int from = side == 0 ? pairs_[i].first : pairs_[i].second;
          const int to = side == 0 ? pairs_[i].second : pairs_[i].first;
          const ssize_t n = read(from, buf, sizeof buf);
          bool ok = n > 0;
          for (ssize_t off = 0; ok && off < n;) {
            const ssize_t w = write(to, buf + off, static_cast<size_t>(n - off));
            if (w <= 0)
              ok = false;
            else
              off += w;
          }
          if (!ok) {
            dead.push_back(i);
            break;
          }
        }
      }
      for (auto it = dead.rbegin(); it != dead.rend(); ++it) {
        close(pairs_[*it].first);
        close(pairs_[*it].second);
        pairs_.erase(pairs_.begin() + static_cast<std::ptrdiff_t>(*it));
      }
    }
  }

  int target_;
  int listener_ = -1;
  int port_ = 0;
  std::atomic<bool> stop_{false};
  std::atomic<bool> cut_{false};
  std::atomic<bool> cut_done_{false};
  std::atomic<bool> restore_done_{false};
  std::vector<std::pair<int, int>> pairs_;
  std::thread thread_;
};

// A coordinator serial line on a pty: the test writes readings frames, the gateway's acks are read
// and thrown away (the records are sent once each: the gateway spools what it reads).
class Coordinator {
 public:
  const std::string& path() const { return pty_.slave_name(); }
  void Send(uint32_t sensor, uint32_t seq) {
    Drain();
    const auto frame = lw::gateway::test::ReadingsFrame(pr::ApiMode::kEscaped, 0x0013A20040000000ull + sensor, sensor,
                                                        {lw::gateway::test::MakeRecord(seq, static_cast<uint16_t>(1190 - seq))});
    if (write(pty_.master(), frame.data(), frame.size()) != static_cast<ssize_t>(frame.size())) {
      throw std::runtime_error("Coordinator: the pty took only part of a frame");
    }
  }
  void Drain() {
    char buf[4096];
    while (read(pty_.master(), buf, sizeof buf) > 0) {
    }
  }

 private:
  lw::test::RawPty pty_;
};

using Observer = lw::test::MqttRecorder;

// A crusher folder for one site: a small generated campaign, crusher.json bound to the site.
std::vector<uint32_t> MakeCrusher(const std::string& dir, const std::string& id, const std::string& site, uint64_t seed) {
  lw::sim::CampaignSpec spec;
  spec.crusher_id = id;
  spec.days = 5;
  spec.n_theta = 24;
  spec.n_z = 12;
  spec.write_scan = false;
  spec.write_operations = false;
  lw::sim::GenerateCampaign(spec, seed).WriteBundle(dir);
  json crusher = json::parse(ReadFile(dir + "/crusher.json"));
  crusher["site"] = site;
  std::ofstream(dir + "/crusher.json") << crusher.dump(1);
  std::vector<uint32_t> sensors;
  for (const auto& s : crusher["sensors"]) {
    if (sensors.size() < 2) sensors.push_back(static_cast<uint32_t>(std::stoul(s["id"].get<std::string>())));
  }
  return sensors;
}

struct Site {
  std::string id;
  std::string crusher;
  std::vector<uint32_t> sensors;
  std::string password;
};

}  // namespace

TEST_GROUP(SitesBridge){};

TEST(SitesBridge, TwoSitesThroughTlsBridgesStoredExactlyOnceLinkCutLosesNothingImpostorRefused) {
  const bool verbose = std::getenv("LW_IT_VERBOSE") != nullptr;
  lw::test::TempDirectory dir("lw-bridge-it");
  Site a{"mine-a", "cr-a", {}, "a-pass"};
  Site b{"mine-b", "cr-b", {}, "b-pass"};
  const std::string crushers = dir.File("crushers");
  a.sensors = MakeCrusher(crushers + "/cr-a", a.crusher, a.id, 3);
  b.sensors = MakeCrusher(crushers + "/cr-b", b.crusher, b.id, 4);
  LONGS_EQUAL(2, a.sensors.size());
  LONGS_EQUAL(2, b.sensors.size());

  // ACL: the shipped one plus a read-only observer account for the test.
  {
    std::ofstream out(dir.File("acl"));
    out << ReadFile(LW_BROKER_ACL) << "\nuser observer\ntopic read linerwatch/#\n";
  }

  // The central broker: TLS, the sites' accounts (user name = site id), the server's account.
  lw::test::MosquittoFixture::Options co;
  co.tls = true;
  co.username = "linerwatch-server";
  co.password = "server-pass";
  // The shipped central.conf's queue and in-flight settings (its listeners and files are the fixture's).
  const std::string central_conf = ReadFile(LW_CENTRAL_CONF);
  for (const char* line : {"max_queued_messages 100000\n", "max_inflight_messages 0\n"}) {
    CHECK_TEXT(central_conf.find(line) != std::string::npos, line);
    co.extra_config += line;
  }
  lw::test::MosquittoFixture::Access ca;
  ca.more_users = {{a.id, a.password}, {b.id, b.password}, {"observer", "o-pass"}};
  ca.acl_file = dir.File("acl");
  lw::test::MosquittoFixture central(co, ca);
  central.Start();

  // The links (cuttable) and the site brokers with the shipped bridge configuration.
  LinkRelay link_a(central.port()), link_b(central.port());
  const std::string bridge_example = ReadFile(LW_SITE_BRIDGE_CONF);
  CHECK_TRUE(bridge_example.find("connection ") != std::string::npos);
  auto bridge_for = [&](const Site& s, int port) {
    std::string conf = bridge_example;
    ReplaceAll(conf, "mine-a", s.id);
    ReplaceAll(conf, "central.example.com:8883", "127.0.0.1:" + std::to_string(port));
    ReplaceAll(conf, "/etc/mosquitto/certs/linerwatch-ca.pem", central.ca_file());
    ReplaceAll(conf, "CHANGE-ME", s.password);
    // The example's reconnect backoff grows to 60 s while a link is down; the test waits less.
    CHECK_TRUE(conf.find("restart_timeout 2 60") != std::string::npos);
    ReplaceAll(conf, "restart_timeout 2 60", "restart_timeout 1 3");
    return conf;
  };
  auto site_broker = [&](const Site& s, int link_port) {
    lw::test::MosquittoFixture::Options o;
    o.username = s.id;  // the site's gateways' account
    o.password = s.password;
    o.persistence = true;
    o.extra_config = bridge_for(s, link_port);
    lw::test::MosquittoFixture::Access acc;
    acc.more_users = {{"observer", "o-pass"}};
    acc.acl_file = dir.File("acl");
    return std::make_unique<lw::test::MosquittoFixture>(o, acc);
  };
  auto broker_a = site_broker(a, link_a.port());
  auto broker_b = site_broker(b, link_b.port());
  broker_a->Start();
  broker_b->Start();

  // The server on the central broker, over TLS.
  const int http_port = lw::test::FreeLoopbackPort();
  const std::string db = dir.File("server.sqlite");
  lw::test::ChildProcess server;
  server.Start({LW_SERVER_BIN, "--broker", central.uri(), "--tls-ca", central.ca_file(), "--username", "linerwatch-server",
                "--password", "server-pass", "--db", db, "--http", "127.0.0.1:" + std::to_string(http_port), "--crusher-dir",
                crushers, "--web-dir", "", "--wear-interval-ms", "500"},
               dir.File("server.log"));
  for (int i = 0; i < 1200 && !lw::test::PortAccepts(http_port) && server.Running(); ++i) std::this_thread::sleep_for(50ms);
  if (!lw::test::PortAccepts(http_port)) FAIL(("server did not come up: " + lw::test::FileTail(dir.File("server.log"))).c_str());

  Observer central_obs(central.uri(), "obs-central", "observer", "o-pass", central.ca_file());
  central_obs.Subscribe("linerwatch/#");
  Observer site_a_obs(broker_a->uri(), "obs-a", "observer", "o-pass");
  site_a_obs.Subscribe("linerwatch/#");
  Observer site_b_obs(broker_b->uri(), "obs-b", "observer", "o-pass");
  site_b_obs.Subscribe("linerwatch/#");
  // Site A's account on the central broker tries to read site B.
  Observer snoop(central.uri(), "snoop", a.id, a.password, central.ca_file());
  snoop.Subscribe("linerwatch/v1/" + b.id + "/#");
  snoop.Subscribe("linerwatch/#");

  // The gateways, one per site, each fed by its coordinator pty.
  Coordinator coord_a, coord_b, coord_imp;
  auto gateway_argv = [&](const Site& s, const std::string& site, const std::string& crusher, const Coordinator& c,
                          const std::string& broker, const std::string& name) {
    return std::vector<std::string>{LW_GATEWAY_BIN,
                                    "--serial",
                                    c.path(),
                                    "--broker",
                                    broker,
                                    "--site",
                                    site,
                                    "--crusher",
                                    crusher,
                                    "--spool",
                                    dir.File(name + ".db"),
                                    "--gateway-id",
                                    name,
                                    "--username",
                                    s.id,
                                    "--password",
                                    s.password,
                                    "--stats-interval",
                                    "0.5",
                                    "--republish-after",
                                    "5",
                                    "--reconnect-max",
                                    "2"};
  };
  lw::test::ChildProcess gw_a, gw_b;
  gw_a.Start(gateway_argv(a, a.id, a.crusher, coord_a, broker_a->uri(), "gw-a"), dir.File("gw-a.log"));
  gw_b.Start(gateway_argv(b, b.id, b.crusher, coord_b, broker_b->uri(), "gw-b"), dir.File("gw-b.log"));

  std::map<std::string, std::set<std::pair<std::string, int64_t>>> sent;  // crusher -> (sensor, seq)
  auto send = [&](const Site& s, Coordinator& c, uint32_t from, uint32_t to) {
    for (uint32_t seq = from; seq <= to; ++seq) {
      for (uint32_t sensor : s.sensors) {
        c.Send(sensor, seq);
        sent[s.crusher].insert({std::to_string(sensor), seq});
        std::this_thread::sleep_for(20ms);
      }
    }
  };
  httplib::Client http("127.0.0.1", http_port);
  auto stored = [&](const Site& s) -> long {
    auto res = http.Get("/api/v1/crushers/" + s.crusher + "/sensors");
    if (!res || res->status != 200) {
      if (std::getenv("LW_IT_VERBOSE"))
        std::printf("GET sensors: %s\n",
                    res ? (std::to_string(res->status) + " " + res->body).c_str() : httplib::to_string(res.error()).c_str());
      return -1;
    }
    long total = 0;
    const json body = json::parse(res->body);
    for (const auto& x : body["sensors"]) total += x.value("reading_count", 0L);
    return total;
  };
  auto wait_stored = [&](const Site& s, long n, std::chrono::seconds timeout) {
    const int64_t until = NowMs() + std::chrono::duration_cast<std::chrono::milliseconds>(timeout).count();
    while (NowMs() < until && stored(s) < n) {
      coord_a.Drain();
      coord_b.Drain();
      std::this_thread::sleep_for(100ms);
    }
    return stored(s);
  };
  auto logs = [&] {
    std::string s;
    for (const char* f : {"server.log", "gw-a.log", "gw-b.log", "gw-imp.log"}) {
      s += std::string("\n--- ") + f + "\n" + lw::test::FileTail(dir.File(f), 1500);
    }
    s += "\n--- site A broker\n" + lw::test::FileTail(broker_a->log_file(), 1500);
    s += "\n--- central broker\n" + lw::test::FileTail(central.log_file(), 1500);
    return s;
  };

  // 1. Both sites, link up: 8 records per sensor each.
  send(a, coord_a, 1, 8);
  send(b, coord_b, 1, 8);
  // The bounds (60-90 s) are only reached by a real failure: a reading is stored within a second
  // or two, more on a loaded machine (fsynced spool and database commits, two bridges).
  long got_a = wait_stored(a, 16, 60s), got_b = wait_stored(b, 16, 60s);
  std::printf("\n  %s both links up: stored %ld of 16 (site A), %ld of 16 (site B)\n", Utc().c_str(), got_a, got_b);
  if (got_a != 16 || got_b != 16) FAIL(("phase 1: not every reading stored" + logs()).c_str());

  // 2. Site A's link to the centre is cut: its new readings wait at the site, site B's go on.
  link_a.Cut();
  std::printf("  %s site A's link cut\n", Utc().c_str());
  send(a, coord_a, 9, 16);
  send(b, coord_b, 9, 16);
  got_b = wait_stored(b, 32, 60s);
  std::this_thread::sleep_for(2s);  // time for anything of site A to leak through (nothing may)
  got_a = stored(a);
  std::printf("  %s site A cut: stored %ld of 32 (site A, its 16 new readings wait at the site), %ld of 32 (site B)\n",
              Utc().c_str(), got_a, got_b);
  LONGS_EQUAL_TEXT(32, got_b, logs().c_str());
  LONGS_EQUAL_TEXT(16, got_a, "site A's readings arrived although its link was cut");

  // 3. The link is restored: nothing was lost.
  const int64_t restored_at = NowMs();
  link_a.Restore();
  std::printf("  %s site A's link restored\n", Utc().c_str());
  got_a = wait_stored(a, 32, 90s);
  std::printf("  %s site A restored: stored %ld of 32 after %.1f s\n", Utc().c_str(), got_a,
              static_cast<double>(NowMs() - restored_at) / 1000.0);
  LONGS_EQUAL_TEXT(32, got_a, logs().c_str());

  // Commit acks flowed back over both bridges: both spools drain.
  const auto drained = [&](Observer& obs, const Site& s) {
    const std::string stats = "linerwatch/v1/" + s.id + "/" + s.crusher + "/gateway/stats";
    // With --window 1 a sensor's records go one commit round trip at a time: ~0.1-0.3 s here
    // after the bridge is back (up to 3 s, restart_timeout 1 3), on a loaded machine too. The
    // spools drained 1.8-5.7 s after the restore in runs beside a debootstrap and a load of ~14.
    if (obs.WaitFor(stats, "\"spool_depth\":0,", 90s)) {
      std::printf("  %s site %s's spool drained (%.1f s after the restore)\n", Utc().c_str(), s.id.c_str(),
                  static_cast<double>(NowMs() - restored_at) / 1000.0);
      return;
    }
    FAIL(("site " + s.id + "'s spool did not drain; commit acks seen at the site: " +
          std::to_string(obs.Count("/" + s.crusher + "/sensors/", "\"seqs\"")) + ", last stats: " + obs.Last(stats) + logs())
             .c_str());
  };
  drained(site_a_obs, a);
  drained(site_b_obs, b);
  CHECK(site_a_obs.Count("/sensors/", "\"seqs\"") > 0);

  // 4. A gateway of site A (site A's account, on site A's broker) publishing as site B.
  lw::test::ChildProcess gw_imp;
  gw_imp.Start(gateway_argv(a, b.id, b.crusher, coord_imp, broker_a->uri(), "gw-imp"), dir.File("gw-imp.log"));
  coord_imp.Send(b.sensors[0], 9001);
  send(a, coord_a, 17, 18);  // the genuine gateway still works meanwhile
  got_a = wait_stored(a, 36, 60s);
  LONGS_EQUAL_TEXT(36, got_a, logs().c_str());
  std::this_thread::sleep_for(6s);  // beyond the impostor's --republish-after: it has published twice
  coord_imp.Drain();
  const std::string imp_log = lw::test::FileTail(dir.File("gw-imp.log"), 4000);
  const size_t seen_site_a = site_a_obs.Count("linerwatch/v1/" + b.id + "/");
  const size_t seen_central = central_obs.Count("/sensors/", "\"seq\":9001");
  got_b = stored(b);
  std::printf(
      "  impostor (site A's account as %s): %zu messages under %s on site A's broker, %zu at the centre, "
      "site B stored %ld of 32\n",
      b.id.c_str(), seen_site_a, b.id.c_str(), seen_central, got_b);
  CHECK_TEXT(gw_imp.Running(), imp_log.c_str());
  LONGS_EQUAL_TEXT(0, seen_site_a, imp_log.c_str());
  LONGS_EQUAL(0, seen_central);
  LONGS_EQUAL(32, got_b);
  LONGS_EQUAL(0, site_a_obs.Count("/" + b.crusher + "/gateway/stats"));  // not even its status or stats

  // The central broker refuses it too: site A's account (a bridge's credentials) publishing a
  // reading of site B directly at the centre gets nowhere (a control publication of its own
  // site's gateway stats, which the ACL allows, arrives after it).
  const std::string b_sensor = std::to_string(b.sensors[0]);
  snoop.Publish("linerwatch/v1/" + b.id + "/" + b.crusher + "/sensors/" + b_sensor + "/reading",
                R"({"sensor": ")" + b_sensor + R"(", "seq": 9002, "time": "2026-11-01T00:00:00Z", "thickness_mm": 100,
                    "loops_intact": 100, "flags": 0, "battery_mv": 3550})");
  snoop.Publish("linerwatch/v1/" + a.id + "/" + a.crusher + "/gateway/stats", "control");
  CHECK_TRUE(central_obs.WaitFor("linerwatch/v1/" + a.id + "/" + a.crusher + "/gateway/stats", "control", 60s));
  LONGS_EQUAL(0, central_obs.Count("/sensors/", "\"seq\": 9002"));

  // Site A's account read nothing of site B at the centre, though site B's traffic passed there.
  CHECK(central_obs.Count("linerwatch/v1/" + b.id + "/") > 0);
  LONGS_EQUAL(0, snoop.Count("linerwatch/v1/" + b.id + "/"));

  CHECK(gw_a.Stop(SIGTERM) == 0);
  CHECK(gw_b.Stop(SIGTERM) == 0);
  gw_imp.Stop(SIGTERM);
  CHECK(server.Stop(SIGTERM) == 0);

  // Stored exactly once: the database holds exactly the readings sent, each once.
  lw::server::Store store(db);
  for (const Site* s : {&a, &b}) {
    const auto rows = store.All(s->crusher);
    std::set<std::pair<std::string, int64_t>> keys;
    for (const auto& r : rows) keys.insert({r.sensor, r.seq});
    LONGS_EQUAL(sent[s->crusher].size(), rows.size());
    CHECK_TRUE(keys == sent[s->crusher]);
  }
  std::printf("  database: %zu + %zu readings, each stored once, none of the impostors'\n", sent[a.crusher].size(),
              sent[b.crusher].size());
  if (verbose) std::printf("%s\n", logs().c_str());
}
