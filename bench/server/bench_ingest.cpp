// Issue 4 benchmark (a): readings per second through mosquitto -> linerwatch-server -> committed
// in SQLite (counted when the server's `committed` ack for every reading has arrived), against a
// bare subscriber (mosquitto_sub -q 1 to /dev/null) on the same broker with the same publisher,
// alternated in one run (bare, server, bare, server, ...). Target (issue 16): server/bare >= 0.9.
//   lw_bench_ingest [--readings N] [--reps R] [--perf FILE] [--commit-delay-ms N[,N...]]
// --commit-delay-ms: the server's group-commit delay (default 5, the server's default); a list runs
// one server per value in each repetition (bare, server@a, server@b, bare, ...).
// --perf FILE: `perf record -e cpu-clock -g` attached to the server during the server's runs (FILE.N).
#include <mqtt/async_client.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <csignal>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <set>
#include <thread>

#include "core/time.hpp"
#include "sim/campaign.hpp"
#include "support/mosquitto_fixture.hpp"

namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

struct Message {
  std::string topic, payload, sensor;
  int64_t seq;
};

std::vector<Message> MakeMessages(const lw::core::CrusherConfig& c, long n) {
  std::vector<Message> out;
  const std::string root = "linerwatch/v1/bench/" + c.crusher_id + "/sensors/";
  for (long i = 0; i < n; ++i) {
    const auto& s = c.sensors[static_cast<size_t>(i) % c.sensors.size()];
    const int64_t seq = i / static_cast<long>(c.sensors.size()) + 1;
    const double thickness = std::max(0.0, s.thickness_new_mm - static_cast<double>(seq / 50));
    const json j = {{"sensor", s.id},
                    {"seq", seq},
                    {"time", lw::core::FormatIsoTime(c.installed_at + std::chrono::seconds(60 * seq))},
                    {"thickness_mm", thickness},
                    {"loops_intact", static_cast<int>(thickness)},
                    {"flags", 0},
                    {"battery_mv", 3500}};
    out.push_back({root + s.id + "/reading", j.dump(), s.id, seq});
  }
  return out;
}

void PublishAll(mqtt::async_client& client, const std::vector<Message>& msgs) {
  for (const Message& m : msgs) {
    while (true) {
      try {
        client.publish(m.topic, m.payload, 1, false);
        break;
      } catch (const mqtt::exception&) {
        std::this_thread::sleep_for(std::chrono::microseconds(200));  // in-flight window full
      }
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  long n = 20000;
  int reps = 5;
  std::string perf, commit_delay = "5";
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--readings"))
      n = std::atol(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--reps"))
      reps = std::atoi(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--perf"))
      perf = argv[i + 1];
    else if (!std::strcmp(argv[i], "--commit-delay-ms"))
      commit_delay = argv[i + 1];
    else {
      std::fprintf(stderr, "usage: lw_bench_ingest [--readings N] [--reps R] [--perf FILE] [--commit-delay-ms N]\n");
      return 2;
    }
  }
  lw::test::MosquittoFixture broker({.persistence = false,
                                     .tls = false,
                                     .username = "",
                                     .password = "",
                                     .extra_config = "max_queued_messages 0\nmax_inflight_messages 0\n"});
  broker.Start();
  lw::test::TempDirectory dir("lw-bench-ingest");
  lw::sim::CampaignSpec spec;
  spec.days = 2;
  const auto campaign = lw::sim::GenerateCampaign(spec, 1);
  campaign.WriteBundle(dir.File("crushers/bench"));
  const lw::core::CrusherConfig crusher = lw::core::LoadCrusherConfig(dir.File("crushers/bench/crusher.json"));
  const auto msgs = MakeMessages(crusher, n);

  mqtt::async_client pub(broker.uri(), "bench-publisher", 100000, nullptr);
  mqtt::connect_options po;
  po.set_clean_session(true);
  po.set_max_inflight(1000);
  pub.connect(po)->wait();

  std::vector<std::string> delays;
  for (size_t a = 0; a <= commit_delay.size();) {
    const size_t b = std::min(commit_delay.find(',', a), commit_delay.size());
    delays.push_back(commit_delay.substr(a, b - a));
    a = b + 1;
  }
  std::vector<double> t_bare;
  std::vector<std::vector<double>> t_servers(delays.size());
  for (int r = 0; r < reps; ++r) {
    // Bare subscriber.
    {
      lw::test::ChildProcess sub;
      sub.Start({"mosquitto_sub", "-h", "127.0.0.1", "-p", std::to_string(broker.port()), "-q", "1", "-t",
                 "linerwatch/v1/bench/#", "-C", std::to_string(n), "-i", "bench-sub-" + std::to_string(r)},
                "/dev/null");
      std::this_thread::sleep_for(std::chrono::milliseconds(500));
      const auto t0 = Clock::now();
      PublishAll(pub, msgs);
      const int rc = sub.Wait(std::chrono::seconds(300));
      t_bare.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
      if (rc != 0) std::fprintf(stderr, "mosquitto_sub exited with %d\n", rc);
    }
    // The server, fresh database.
    for (size_t d = 0; d < delays.size(); ++d) {
      std::vector<double>& t_server = t_servers[d];
      const std::string run = std::to_string(r) + "-" + std::to_string(d);
      const int http = lw::test::FreeLoopbackPort();
      const std::string db = dir.File("server-" + run + ".sqlite");
      lw::test::ChildProcess server;
      server.Start(
          {LW_SERVER_BIN, "--broker", broker.uri(), "--db", db, "--http", "127.0.0.1:" + std::to_string(http), "--crusher-dir",
           dir.File("crushers"), "--client-id", "bench-server-" + run, "--web-dir", "", "--commit-delay-ms", delays[d]},
          dir.File("server.log"));
      mqtt::async_client acks(broker.uri(), "bench-acks-" + run, nullptr);
      acks.start_consuming();
      acks.connect(po)->wait();
      acks.subscribe("linerwatch/v1/bench/+/sensors/+/committed", 1)->wait();
      for (int i = 0; i < 100 && !lw::test::PortAccepts(http); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
      std::this_thread::sleep_for(std::chrono::milliseconds(800));  // MQTT connect and subscribe
      lw::test::ChildProcess profiler;
      if (!perf.empty()) {
        profiler.Start({"perf", "record", "-e", "cpu-clock", "-g", "-p", std::to_string(server.pid()), "-o", perf + "." + run},
                       dir.File("perf.log"));
        std::this_thread::sleep_for(std::chrono::milliseconds(300));
      }
      std::set<std::pair<std::string, int64_t>> confirmed;
      const auto t0 = Clock::now();
      std::thread publisher([&] { PublishAll(pub, msgs); });
      const auto deadline = t0 + std::chrono::seconds(300);
      while (confirmed.size() < static_cast<size_t>(n) && Clock::now() < deadline) {
        mqtt::const_message_ptr m;
        if (!acks.try_consume_message_for(&m, std::chrono::milliseconds(100)) || !m) continue;
        const json j = json::parse(m->to_string());
        for (const auto& s : j["seqs"]) confirmed.insert({j["sensor"].get<std::string>(), s.get<int64_t>()});
      }
      t_server.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
      publisher.join();
      if (confirmed.size() < static_cast<size_t>(n)) {
        std::fprintf(stderr, "server confirmed only %zu of %ld:\n%s\n", confirmed.size(), n,
                     lw::test::FileTail(dir.File("server.log")).c_str());
        return 1;
      }
      acks.disconnect()->wait();
      if (!perf.empty()) profiler.Stop(SIGINT, std::chrono::seconds(30));
      server.Stop(SIGTERM);
    }
    std::fprintf(stderr, "rep %d: bare %.2f s", r + 1, t_bare.back());
    for (size_t d = 0; d < delays.size(); ++d) {
      std::fprintf(stderr, ", server (commit delay %s ms) %.2f s, ratio %.2f", delays[d].c_str(), t_servers[d].back(),
                   t_bare.back() / t_servers[d].back());
    }
    std::fprintf(stderr, "\n");
  }
  const double bare = Median(t_bare);
  std::printf("readings per run              %ld (10 sensors, QoS 1)\n", n);
  std::printf("bare subscriber (mosquitto_sub) %.0f readings/s  (median of %d)\n", n / bare, reps);
  for (size_t d = 0; d < delays.size(); ++d) {
    const double srv = Median(t_servers[d]);
    std::vector<double> ratios;
    for (size_t r = 0; r < t_bare.size(); ++r) ratios.push_back(t_bare[r] / t_servers[d][r]);
    std::printf("server, committed and acked     %.0f readings/s  (median of %d; --commit-delay-ms %s)\n", n / srv, reps,
                delays[d].c_str());
    std::printf(
        "ratio server/bare               %.2f   (of the medians; paired ratios: median %.2f, range %.2f-%.2f; target >= 0.9)   "
        "%s\n",
        bare / srv, Median(ratios), *std::min_element(ratios.begin(), ratios.end()),
        *std::max_element(ratios.begin(), ratios.end()), bare / srv >= 0.9 ? "MET" : "MISSED");
  }
  return 0;
}
