// Issue 4 benchmark (a): readings per second through mosquitto -> linerwatch-server -> committed
// in SQLite (counted when the server's `committed` ack for every reading has arrived), against a
// bare subscriber (mosquitto_sub -q 1 to /dev/null) on the same broker with the same publisher,
// alternated in one run (bare, server, bare, server, ...). Target (issue 47; issue 16 asked 0.9): server/bare >= 0.95.
//   lw_bench_ingest [--readings N] [--reps R] [--batch N[,N...]] [--perf FILE] [--commit-delay-ms N[,N...]]
//                   [--server BIN[,BIN...]]   (--help: every option; an unknown one is an error)
// --batch: the readings go as messages of up to N records of one sensor (docs/mqtt.md, *Batches*:
// what the gateway sends once the server announced batches); 1 (default) is one message per
// reading. A list runs each form in every repetition, each with its own bare run (bare@1,
// server@1, bare@64, server@64, bare@1, ...); the bare subscriber receives the same messages and
// is timed until it has received all of them, i.e. all N readings.
// --commit-delay-ms: the server's group-commit delay (default 5, the server's default); a list runs
// one server per value in each repetition (bare, server@a, server@b, bare, ...).
// --server: the server binaries to compare (default: this build's linerwatch-server); each runs in
// every repetition (with every delay), so two builds are compared side by side in one run.
// --perf FILE: `perf record -e cpu-clock -g` attached to the server during the server's runs
// (FILE.REP-FORM-VARIANT). --perf-call-graph MODE: perf's --call-graph instead of -g (frame
// pointers): `dwarf` unwinds the whole chain of code built without frame pointers (larger files).
// Besides wall time, it reports CPU time (user + system, from /proc/PID/stat) per 10,000 readings
// of the server, the broker and the bare subscriber: on a loaded machine the ratio moves with
// what else runs, CPU per reading much less. A server run that does not confirm every reading
// within 300 s fails the bench with the server's log.
#include <mqtt/async_client.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <csignal>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include <sys/resource.h>
#include <unistd.h>

#include "core/cmdline.hpp"
#include "core/time.hpp"
#include "mqtt/messages.hpp"
#include "mqtt/topics.hpp"
#include "server/ingest.hpp"
#include "server/registry.hpp"
#include "server/store.hpp"
#include "sim/campaign.hpp"
#include "support/mosquitto_fixture.hpp"
#include "../bench_stats.hpp"

namespace {

using lw::bench::Median;

using nlohmann::json;
using Clock = std::chrono::steady_clock;

/// CPU seconds (user + system) a running process has used: /proc/PID/stat fields 14 and 15.
/// utime + stime of a /proc stat file (a process's or one thread's), in seconds; `comm` gets its name.
double StatCpuSeconds(const std::string& path, std::string* comm = nullptr) {
  std::ifstream in(path);
  std::string text;
  std::getline(in, text);                // one line
  const size_t close = text.rfind(')');  // the command name may hold spaces
  if (close == std::string::npos) return 0;
  if (comm) {
    const size_t open = text.find('(');
    *comm = open < close ? text.substr(open + 1, close - open - 1) : std::string();
  }
  std::istringstream rest(text.substr(close + 2));
  std::string field;
  unsigned long long utime = 0, stime = 0;
  for (int i = 3; i <= 15 && rest >> field; ++i) {
    if (i == 14) utime = std::stoull(field);
    if (i == 15) stime = std::stoull(field);
  }
  return static_cast<double>(utime + stime) / static_cast<double>(::sysconf(_SC_CLK_TCK));
}

double ProcessCpuSeconds(pid_t pid) {
  return StatCpuSeconds("/proc/" + std::to_string(pid) + "/stat");
}

/// The server's CPU by thread, summed by the thread's name: Paho C's receive thread
/// ("MQTTAsync_rcv": every message's receive and PUBACK), its send thread ("MQTTAsync_send"), the
/// wear worker ("lw-wear") and the rest ("linerwatch-serv": the main loop that ingests, the HTTP
/// threads).
std::map<std::string, double> ThreadCpuSeconds(pid_t pid) {
  std::map<std::string, double> out;
  const std::filesystem::path tasks = "/proc/" + std::to_string(pid) + "/task";
  std::error_code ec;
  for (const auto& t : std::filesystem::directory_iterator(tasks, ec)) {
    std::string comm;
    const double cpu = StatCpuSeconds((t.path() / "stat").string(), &comm);
    out[comm] += cpu;
  }
  return out;
}

/// CPU seconds this thread has used.
double ThreadCpuSeconds() {
  timespec t{};
  ::clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + static_cast<double>(t.tv_nsec) / 1e9;
}

/// CPU seconds of the children this process has reaped so far.
double ReapedChildrenCpuSeconds() {
  rusage u{};
  ::getrusage(RUSAGE_CHILDREN, &u);
  const auto s = [](const timeval& t) { return static_cast<double>(t.tv_sec) + static_cast<double>(t.tv_usec) / 1e6; };
  return s(u.ru_utime) + s(u.ru_stime);
}

/// 1-minute load average (printed with the figures: they move with it).
double LoadAverage() {
  double load[1] = {0};
  return ::getloadavg(load, 1) == 1 ? load[0] : -1;
}

/// One MQTT message: one record (`{"sensor": ..., "seq": ...}`) or a batch of `records` records of
/// one sensor (docs/mqtt.md, *Batches*), seqs `seq` .. `seq + records - 1`.
struct Message {
  std::string topic, payload, sensor;
  int64_t seq;
  size_t records;
};

/// The same `n` readings (10 sensors, reading i of sensor i % 10 with seq i / 10 + 1) as messages
/// of up to `batch` records of one sensor, as the gateway sends them once the server announced
/// batches: per sensor in seq order, the sensors taken in turn (one message each); a message of
/// one record is the one-record form, as the gateway's. `batch` 1: one message per reading, in
/// reading order (the form before the announcement).
std::vector<Message> MakeMessages(const lw::core::CrusherConfig& c, long n, size_t batch) {
  const std::string root = "linerwatch/v1/bench/" + c.crusher_id + "/sensors/";
  const size_t sensors = c.sensors.size();
  std::vector<std::vector<std::pair<int64_t, std::string>>> per_sensor(sensors);  // (seq, record text)
  for (long i = 0; i < n; ++i) {
    const auto& s = c.sensors[static_cast<size_t>(i) % sensors];
    const int64_t seq = i / static_cast<long>(sensors) + 1;
    const double thickness = std::max(0.0, s.thickness_new_mm - static_cast<double>(seq / 50));
    const json j = {{"sensor", s.id},
                    {"seq", seq},
                    {"time", lw::core::FormatIsoTime(c.installed_at + std::chrono::seconds(60 * seq))},
                    {"thickness_mm", thickness},
                    {"loops_intact", static_cast<int>(thickness)},
                    {"flags", 0},
                    {"battery_mv", 3500}};
    per_sensor[static_cast<size_t>(i) % sensors].emplace_back(seq, j.dump());
  }
  std::vector<Message> out;
  for (size_t first = 0, more = 1; more; first += batch) {
    more = 0;
    for (size_t k = 0; k < sensors; ++k) {
      const auto& records = per_sensor[k];
      if (first >= records.size()) continue;
      more = 1;
      const size_t count = std::min(batch, records.size() - first);
      const std::string& id = c.sensors[k].id;
      std::string payload;
      if (count == 1) {
        payload = records[first].second;
      } else {
        std::vector<std::string_view> texts;
        for (size_t r = first; r < first + count; ++r) texts.push_back(records[r].second);
        payload = lw::mqtt::EncodeReadingBatch(id, texts);
      }
      out.push_back({root + id + "/reading", std::move(payload), id, records[first].first, count});
    }
  }
  return out;
}

/// What the server's own code costs without MQTT: the messages ingested in this process through
/// lw::server::Ingestor (decode, validate, one SQLite transaction with synchronous=FULL, acks; no
/// live state, no broker) about 1000 readings per transaction, then the readings it stored
/// committed again into another fresh database through Store::Commit alone (the SQLite part).
struct InProcess {
  double ingest_s, ingest_cpu_s, store_s, store_cpu_s;
};
InProcess IngestInProcess(const std::vector<Message>& msgs, const lw::server::Registry& registry, const std::string& db_prefix) {
  InProcess out{};
  std::vector<lw::server::StoredReading> stored;
  {
    lw::server::Store store(db_prefix + "-ingest.sqlite");
    lw::server::Ingestor ingestor(store, registry, [] {
      return std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
    });
    const double cpu0 = ThreadCpuSeconds();
    const auto t0 = Clock::now();
    std::vector<lw::server::Incoming> part;
    size_t records = 0;
    for (size_t i = 0; i < msgs.size(); ++i) {
      const auto t = lw::mqtt::Topics::ParseAny(msgs[i].topic);
      part.push_back({t->site, t->crusher, t->id, msgs[i].topic, msgs[i].payload});
      records += msgs[i].records;
      if (records >= 1000 || i + 1 == msgs.size()) {
        lw::server::IngestResult r = ingestor.Ingest(std::move(part));
        for (auto& reading : r.new_readings) stored.push_back(std::move(reading));
        part.clear();
        records = 0;
      }
    }
    out.ingest_s = std::chrono::duration<double>(Clock::now() - t0).count();
    out.ingest_cpu_s = ThreadCpuSeconds() - cpu0;
  }
  lw::server::Store store(db_prefix + "-store.sqlite");
  const double cpu0 = ThreadCpuSeconds();
  const auto t0 = Clock::now();
  for (size_t a = 0; a < stored.size(); a += 1000) {
    const std::vector<lw::server::StoredReading> part(
        stored.begin() + static_cast<std::ptrdiff_t>(a),
        stored.begin() + static_cast<std::ptrdiff_t>(std::min(stored.size(), a + 1000)));
    store.Commit(part, {});
  }
  out.store_s = std::chrono::duration<double>(Clock::now() - t0).count();
  out.store_cpu_s = ThreadCpuSeconds() - cpu0;
  return out;
}

/// Publishes every message at QoS 1 with at most kWindow unacknowledged (PUBACK) at a time, and
/// publishes again any whose delivery failed (said on stderr), instead of handing Paho all of
/// them at once. Runs on this loaded machine lost readings both ways ("server confirmed only
/// 11648 of 20000", the server idle and its broker holding nothing for it); the cause was not
/// found: a run that loses any fails with the server's log.
void PublishAll(mqtt::async_client& client, const std::vector<Message>& msgs) {
  constexpr size_t kWindow = 500;
  std::deque<std::pair<size_t, mqtt::delivery_token_ptr>> pending;
  const auto publish = [&](size_t i) {
    while (true) {
      try {
        pending.emplace_back(i, client.publish(msgs[i].topic, msgs[i].payload, 1, false));
        return;
      } catch (const mqtt::exception&) {
        std::this_thread::sleep_for(std::chrono::microseconds(200));  // in-flight window full
      }
    }
  };
  const auto settle_oldest = [&] {
    auto [i, token] = pending.front();
    pending.pop_front();
    bool ok = false;
    try {
      ok = token->wait_for(std::chrono::seconds(30)) && token->get_return_code() == 0;
    } catch (const mqtt::exception&) {
    }
    if (!ok) {
      std::fprintf(stderr, "publish of %s seq %lld (%zu records) failed: publishing it again\n", msgs[i].sensor.c_str(),
                   static_cast<long long>(msgs[i].seq), msgs[i].records);
      publish(i);
    }
  };
  for (size_t i = 0; i < msgs.size(); ++i) {
    while (pending.size() >= kWindow) settle_oldest();
    publish(i);
  }
  while (!pending.empty()) settle_oldest();
}

const lw::core::OptionTable& Table() {
  using lw::core::Option;
  static const lw::core::OptionTable table{{
      Option::Whole("readings", "N", 10, 100'000'000, "readings published per run (default 20000; 10 sensors, QoS 1)"),
      Option::Whole("reps", "R", 1, 1000, "repetitions, each form and server alternated within each (default 5)"),
      Option::Text("batch", "N[,N...]",
                   "messages of up to N records of one sensor (1..64; default 1: one message per\n"
                   "reading); a list runs every form in every repetition, each with its own bare run"),
      Option::Text("commit-delay-ms", "N[,N...]", "the server's --commit-delay-ms (default 5); a list runs one server per value"),
      Option::Text("server", "BIN[,BIN...]",
                   "server binaries compared side by side in every repetition (default: this\nbuild's linerwatch-server)"),
      Option::Text("perf", "FILE", "perf record -e cpu-clock attached to each server run (FILE.REP-FORM-VARIANT)"),
      Option::Text("perf-call-graph", "MODE", "perf's --call-graph instead of -g (dwarf: whole chains without frame pointers)"),
  }};
  return table;
}

std::string Help() {
  return "lw_bench_ingest: readings/s through mosquitto -> linerwatch-server -> SQLite (committed and acked)\n"
         "against a bare mosquitto_sub on the same broker, alternated in one run (docs/performance.md, *Ingest*).\n\n"
         "usage: lw_bench_ingest " +
         Table().Synopsis(24, 100) + "\n\n" + Table().Help(28);
}

}  // namespace

int main(int argc, char** argv) {
  long n = 20000;
  int reps = 5;
  std::string perf, perf_call_graph, commit_delay = "5", servers = LW_SERVER_BIN, batches = "1";
  try {
    const lw::core::ParsedOptions p = lw::core::ParseOptions(Table(), std::vector<std::string>(argv + 1, argv + argc));
    if (p.help()) {
      std::fputs(Help().c_str(), stdout);
      return 0;
    }
    n = p.Integer<long>("readings", n);
    reps = p.Integer<int>("reps", reps);
    batches = p.Text("batch", batches);
    commit_delay = p.Text("commit-delay-ms", commit_delay);
    servers = p.Text("server", servers);
    perf = p.Text("perf");
    perf_call_graph = p.Text("perf-call-graph");
  } catch (const lw::core::UsageError& e) {
    std::fprintf(stderr, "lw_bench_ingest: %s\n", e.what());
    return 2;
  }
  const auto split = [](const std::string& list) {
    std::vector<std::string> out;
    for (size_t a = 0; a <= list.size();) {
      const size_t b = std::min(list.find(',', a), list.size());
      out.push_back(list.substr(a, b - a));
      a = b + 1;
    }
    return out;
  };
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
  std::vector<std::string> registry_errors;
  const auto registry = lw::server::Registry::Load(dir.File("crushers"), &registry_errors);
  if (registry->All().empty()) {
    std::fprintf(stderr, "lw_bench_ingest: the bench crusher did not load: %s\n",
                 registry_errors.empty() ? "" : registry_errors.front().c_str());
    return 1;
  }

  mqtt::async_client pub(broker.uri(), "bench-publisher", 100000, nullptr);
  mqtt::connect_options po;
  po.set_clean_session(true);
  po.set_max_inflight(1000);
  pub.connect(po)->wait();

  // One variant per (server binary, commit delay), each run in every repetition after the bare one.
  struct Variant {
    std::string bin, delay, label;
    std::vector<double> seconds, cpu, broker_cpu;
    std::vector<size_t> ack_messages;
    std::vector<std::map<std::string, double>> thread_cpu;  // per run, by thread name
  };
  // One form per --batch value: the same readings as messages of up to `batch` records; its own
  // bare run and server runs in every repetition (bare, server..., bare, server..., per form).
  struct Form {
    size_t batch;
    std::vector<Message> msgs;
    std::vector<double> t_bare, cpu_bare, broker_cpu_bare;
    std::vector<Variant> variants;
    std::vector<InProcess> in_process;
  };
  std::vector<Form> forms;
  const std::vector<std::string> bins = split(servers), delays = split(commit_delay);
  for (const std::string& b : split(batches)) {
    const long batch = std::atol(b.c_str());
    if (batch < 1 || batch > static_cast<long>(lw::mqtt::kMaxReadingBatch)) {
      std::fprintf(stderr, "lw_bench_ingest: --batch %s is outside [1, %zu]\n", b.c_str(), lw::mqtt::kMaxReadingBatch);
      return 2;
    }
    Form f{static_cast<size_t>(batch), MakeMessages(crusher, n, static_cast<size_t>(batch)), {}, {}, {}, {}, {}};
    for (size_t k = 0; k < bins.size(); ++k) {
      for (const std::string& d : delays) {
        std::string label = "--commit-delay-ms " + d;
        if (bins.size() > 1) label = "server " + std::string(1, static_cast<char>('A' + k)) + " (" + bins[k] + "), " + label;
        f.variants.push_back({bins[k], d, label, {}, {}, {}, {}, {}});
      }
    }
    forms.push_back(std::move(f));
  }
  std::vector<double> loads;
  const double per10k = 10000.0 / static_cast<double>(n);
  for (int r = 0; r < reps; ++r) {
    loads.push_back(LoadAverage());
    std::fprintf(stderr, "rep %d (load %.1f):", r + 1, loads.back());
    for (size_t fi = 0; fi < forms.size(); ++fi) {
      Form& f = forms[fi];
      // Bare subscriber: mosquitto_sub at QoS 1 receives every message that carries the readings
      // (the same bytes the server receives: -C counts messages, so a batch counts once) and
      // writes it to /dev/null; it parses nothing. Its time is the time to receive all n readings.
      {
        lw::test::ChildProcess sub;
        const double reaped0 = ReapedChildrenCpuSeconds();
        sub.Start(
            {"mosquitto_sub", "-h", "127.0.0.1", "-p", std::to_string(broker.port()), "-q", "1", "-t", "linerwatch/v1/bench/#",
             "-C", std::to_string(f.msgs.size()), "-i", "bench-sub-" + std::to_string(r) + "-" + std::to_string(fi)},
            "/dev/null");
        std::this_thread::sleep_for(std::chrono::milliseconds(500));
        const double broker0 = ProcessCpuSeconds(broker.pid());
        const auto t0 = Clock::now();
        PublishAll(pub, f.msgs);
        const int rc = sub.Wait(std::chrono::seconds(300));
        f.t_bare.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
        f.broker_cpu_bare.push_back(ProcessCpuSeconds(broker.pid()) - broker0);
        f.cpu_bare.push_back(ReapedChildrenCpuSeconds() - reaped0);  // the subscriber's whole life
        if (rc != 0) {
          std::fprintf(stderr, "\nmosquitto_sub exited with %d (batch %zu)\n", rc, f.batch);
          return 1;
        }
      }
      // Each server variant, fresh database.
      for (size_t d = 0; d < f.variants.size(); ++d) {
        Variant& v = f.variants[d];
        const std::string run = std::to_string(r) + "-" + std::to_string(fi) + "-" + std::to_string(d);
        const int http = lw::test::FreeLoopbackPort();
        const std::string db = dir.File("server-" + run + ".sqlite"), log = dir.File("server-" + run + ".log");
        lw::test::ChildProcess server;
        server.Start({v.bin, "--broker", broker.uri(), "--db", db, "--http", "127.0.0.1:" + std::to_string(http), "--crusher-dir",
                      dir.File("crushers"), "--client-id", "bench-server-" + run, "--web-dir", "", "--commit-delay-ms", v.delay},
                     log);
        mqtt::async_client acks(broker.uri(), "bench-acks-" + run, nullptr);
        acks.start_consuming();
        acks.connect(po)->wait();
        acks.subscribe("linerwatch/v1/bench/+/sensors/+/committed", 1)->wait();
        // Up once it is connected to the broker (loading the crusher's map takes seconds, more on a
        // loaded machine); then a moment for its subscription.
        for (int i = 0; i < 1200 && lw::test::FileTail(log).find("connected to ") == std::string::npos; ++i) {
          std::this_thread::sleep_for(std::chrono::milliseconds(100));
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(800));
        lw::test::ChildProcess profiler;
        if (!perf.empty()) {
          std::vector<std::string> args = {"perf", "record", "-e", "cpu-clock"};
          if (perf_call_graph.empty()) {
            args.push_back("-g");
          } else {
            args.push_back("--call-graph");
            args.push_back(perf_call_graph);
          }
          for (const std::string& a : {std::string("-p"), std::to_string(server.pid()), std::string("-o"), perf + "." + run})
            args.push_back(a);
          profiler.Start(args, dir.File("perf.log"));
          std::this_thread::sleep_for(std::chrono::milliseconds(300));
        }
        // Counted by (sensor, seq): a reading is confirmed when a commit ack names it.
        std::set<std::pair<std::string, int64_t>> confirmed;
        size_t ack_messages = 0;
        const double cpu0 = ProcessCpuSeconds(server.pid()), broker0 = ProcessCpuSeconds(broker.pid());
        const std::map<std::string, double> threads0 = ThreadCpuSeconds(server.pid());
        const auto t0 = Clock::now();
        std::thread publisher([&] { PublishAll(pub, f.msgs); });
        const auto deadline = t0 + std::chrono::seconds(300);
        while (confirmed.size() < static_cast<size_t>(n) && Clock::now() < deadline) {
          mqtt::const_message_ptr m;
          if (!acks.try_consume_message_for(&m, std::chrono::milliseconds(100)) || !m) continue;
          const json j = json::parse(m->to_string());
          ++ack_messages;
          for (const auto& s : j["seqs"]) confirmed.insert({j["sensor"].get<std::string>(), s.get<int64_t>()});
        }
        v.seconds.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
        v.cpu.push_back(ProcessCpuSeconds(server.pid()) - cpu0);
        std::map<std::string, double> threads = ThreadCpuSeconds(server.pid());
        for (auto& [name, cpu] : threads) {
          const auto before = threads0.find(name);
          if (before != threads0.end()) cpu -= before->second;
        }
        v.thread_cpu.push_back(std::move(threads));
        v.broker_cpu.push_back(ProcessCpuSeconds(broker.pid()) - broker0);
        v.ack_messages.push_back(ack_messages);
        publisher.join();
        if (!perf.empty()) profiler.Stop(SIGINT, std::chrono::seconds(30));
        if (confirmed.size() < static_cast<size_t>(n)) {
          std::fprintf(stderr, "\nserver confirmed only %zu of %ld (batch %zu):\n%s\n", confirmed.size(), n, f.batch,
                       lw::test::FileTail(log).c_str());
          return 1;
        }
        acks.disconnect()->wait();
        server.Stop(SIGTERM);
      }
      f.in_process.push_back(
          IngestInProcess(f.msgs, *registry, dir.File("in-process-" + std::to_string(r) + "-" + std::to_string(fi))));
      std::fprintf(stderr, " batch %zu: bare %.2f s (subscriber CPU %.2f s, broker %.2f s)", f.batch, f.t_bare.back(),
                   f.cpu_bare.back(), f.broker_cpu_bare.back());
      for (const Variant& v : f.variants) {
        std::fprintf(stderr, "; %s: %.2f s, ratio %.2f, server CPU %.2f s (", v.label.c_str(), v.seconds.back(),
                     f.t_bare.back() / v.seconds.back(), v.cpu.back());
        const char* sep = "";
        for (const auto& [name, cpu] : v.thread_cpu.back()) {
          std::fprintf(stderr, "%s%s %.2f", sep, name.c_str(), cpu);
          sep = ", ";
        }
        std::fprintf(stderr, "), broker %.2f s", v.broker_cpu.back());
      }
      std::fprintf(stderr, "; in process: ingest %.2f s (CPU %.2f s), store alone %.2f s (CPU %.2f s)",
                   f.in_process.back().ingest_s, f.in_process.back().ingest_cpu_s, f.in_process.back().store_s,
                   f.in_process.back().store_cpu_s);
      std::fprintf(stderr, fi + 1 < forms.size() ? ";" : "\n");
    }
  }
  std::printf("readings per run              %ld (10 sensors, QoS 1); load average %.1f-%.1f\n", n,
              *std::min_element(loads.begin(), loads.end()), *std::max_element(loads.begin(), loads.end()));
  for (const Form& f : forms) {
    const double bare = Median(f.t_bare);
    std::printf("--batch %zu: %zu messages (up to %zu records of one sensor each)\n", f.batch, f.msgs.size(), f.batch);
    std::printf(
        "  bare subscriber (mosquitto_sub) %.0f readings/s  (median of %d); CPU per 10k readings: subscriber %.0f ms, broker "
        "%.0f ms\n",
        static_cast<double>(n) / bare, reps, Median(f.cpu_bare) * per10k * 1000, Median(f.broker_cpu_bare) * per10k * 1000);
    for (const Variant& v : f.variants) {
      const double srv = Median(v.seconds);
      std::vector<double> ratios, acks;
      for (size_t r = 0; r < f.t_bare.size(); ++r) ratios.push_back(f.t_bare[r] / v.seconds[r]);
      for (const size_t a : v.ack_messages) acks.push_back(static_cast<double>(a));
      std::printf("  server, committed and acked     %.0f readings/s  (median of %d; %s)\n", static_cast<double>(n) / srv, reps,
                  v.label.c_str());
      std::printf("    CPU per 10k readings          server %.0f ms (range %.0f-%.0f), broker %.0f ms\n",
                  Median(v.cpu) * per10k * 1000, *std::min_element(v.cpu.begin(), v.cpu.end()) * per10k * 1000,
                  *std::max_element(v.cpu.begin(), v.cpu.end()) * per10k * 1000, Median(v.broker_cpu) * per10k * 1000);
      std::map<std::string, std::vector<double>> by_thread;
      for (const auto& run : v.thread_cpu)
        for (const auto& [name, cpu] : run) by_thread[name].push_back(cpu);
      std::printf("      by thread (median)          ");
      const char* sep = "";
      for (auto& [name, cpus] : by_thread) {
        std::printf("%s%s %.0f ms", sep, name.c_str(), Median(cpus) * per10k * 1000);
        sep = ", ";
      }
      std::printf("\n");
      std::printf("    confirmed                     every reading in every run (%ld of %ld; %.0f commit-ack messages, median)\n",
                  n, n, Median(acks));
      std::printf(
          "    ratio server/bare             %.2f   (of the medians; paired ratios: median %.2f, range %.2f-%.2f; target >= "
          "0.95)   %s\n",
          bare / srv, Median(ratios), *std::min_element(ratios.begin(), ratios.end()),
          *std::max_element(ratios.begin(), ratios.end()), bare / srv >= 0.95 ? "MET" : "MISSED");
    }
    std::vector<double> ingest_s, ingest_cpu, store_s, store_cpu;
    for (const InProcess& p : f.in_process) {
      ingest_s.push_back(p.ingest_s);
      ingest_cpu.push_back(p.ingest_cpu_s);
      store_s.push_back(p.store_s);
      store_cpu.push_back(p.store_cpu_s);
    }
    std::printf("  in process, no MQTT (this build's code, ~1000 readings a transaction):\n");
    std::printf(
        "    Ingestor::Ingest              %.0f readings/s  (median of %d); CPU per 10k readings %.0f ms; ratio to bare %.2f\n",
        static_cast<double>(n) / Median(ingest_s), reps, Median(ingest_cpu) * per10k * 1000, bare / Median(ingest_s));
    std::printf(
        "    Store::Commit alone           %.0f readings/s  (median of %d); CPU per 10k readings %.0f ms; ratio to bare %.2f\n",
        static_cast<double>(n) / Median(store_s), reps, Median(store_cpu) * per10k * 1000, bare / Median(store_s));
  }
  return 0;
}
