// lw_bench_chaos: the chaos soak of docs/reliability.md. The real pipeline (`linerwatch-sim run`
// with radio loss and duplicates -> `linerwatch-gateway` -> mosquitto -> `linerwatch-server`) runs
// a campaign while broker, gateway and server are SIGKILLed at random virtual times, one at a time
// or all three at the same instant (a whole-site power cut: the sensor boards on the liner run on
// their batteries and keep polling and queueing, everything on site power dies). Then every
// reading of the simulator's ledger must be stored exactly once.
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "core/bundle.hpp"
#include "core/cmdline.hpp"
#include "server/store.hpp"
#include "support/mosquitto_fixture.hpp"
#include "support/pipeline_ledger.hpp"

namespace {

namespace fs = std::filesystem;
using lw::core::UsageError;

using lw::core::NumberRange;
using lw::core::Option;

const lw::core::OptionTable& Table() {
  static const lw::core::OptionTable table{{
      Option::Whole("kills", "N", 0, 10'000'000, "SIGKILLs to deliver, counting each program of a site cut (default 1000)"),
      Option::Whole("site-cuts", "M", 0, 10'000'000,
                    "of which whole-site power cuts: broker, gateway and server killed at the same\ninstant (default 100)"),
      Option::Number("days", "D", NumberRange{5, 3650, false, false},
                     "virtual days of a campaign (default 95); kills fall at random virtual times\n"
                     "from day 0.5 to day D - 3, another campaign follows if the kills are not done"),
      Option::Number("loss", "P", NumberRange{0, 1, false, true}, "radio loss per transmission attempt (default 0.2)"),
      Option::Number("dup", "P", NumberRange{0, 1, false, true},
                     "probability that a delivered packet arrives twice (default 0.05)"),
      Option::Whole("seed", "S", 0, UINT32_MAX, "seed of the fault schedule and the radio (default: random, printed)"),
      Option::Number("speed", "X", NumberRange{0, std::numeric_limits<double>::infinity(), false, true},
                     "virtual seconds per wall second (default: D days / (1.5 s per fault))"),
      Option::Whole("max-down-ms", "MS", 0, 60000, "a killed program stays down 0..MS wall ms (default 1000)"),
      Option::Text("out", "DIR",
                   "logs, databases and ledgers (default /tmp/lw-chaos-PID); removed after a\nclean run unless --keep"),
      Option::Switch("keep", "keep DIR"),
      Option::Text("data-dir", "DIR",
                   "the server's database and the gateway's spool live here (default: in --out);\n"
                   "meant for a small file system of their own (a tmpfs or a loop mount)"),
      Option::Whole("fills", "F", 0, 100000,
                    "F times per campaign, at random virtual times, fill --data-dir's file system\n"
                    "to the last byte (a filler file written until ENOSPC), keep it full for\n"
                    "--full-s wall seconds, then delete the filler: the disk-full run"),
      Option::Number("full-s", "S", NumberRange{0, 600, true, false}, "seconds --data-dir stays full (default 5)"),
  }};
  return table;
}

std::string Help() {
  return "lw_bench_chaos: chaos soak of the real pipeline (docs/reliability.md).\n\nUsage: lw_bench_chaos " +
         Table().Synopsis(22, 100) + "\n\n" + Table().Help(20) + "\n" + R"(Prints progress every 15 s and a last line
  chaos: kills K (broker B, gateway G, server S; C site cuts), produced P, stored T, lost L, duplicated D, ...
Exit status 0 when every reading was stored exactly once, 1 otherwise, 2 on bad usage.
)";
}

constexpr const char* kUser = "linerwatch-chaos";
constexpr const char* kPassword = "chaos-broker-secret";

struct Options {
  long kills = 1000;
  long site_cuts = 100;
  double days = 95;
  double loss = 0.2;
  double dup = 0.05;
  unsigned seed = std::random_device{}();
  double speed = 0;  // 0: derived
  int max_down_ms = 1000;
  std::string out;
  bool keep = false;
  std::string data_dir;
  long fills = 0;
  double full_s = 5;
};

Options Parse(const std::vector<std::string>& args, bool* help) {
  Options o;
  const lw::core::ParsedOptions p = lw::core::ParseOptions(Table(), args);
  *help = p.help();
  if (*help) return o;
  o.kills = p.Integer<long>("kills", o.kills);
  o.site_cuts = p.Integer<long>("site-cuts", o.site_cuts);
  o.days = p.Number("days", o.days);
  o.loss = p.Number("loss", o.loss);
  o.dup = p.Number("dup", o.dup);
  o.seed = p.Integer<unsigned>("seed", o.seed);
  o.speed = p.Number("speed", o.speed);
  o.max_down_ms = p.Integer<int>("max-down-ms", o.max_down_ms);
  o.out = p.Text("out");
  o.keep = p.Switch("keep");
  o.data_dir = p.Text("data-dir");
  o.fills = p.Integer<long>("fills", o.fills);
  o.full_s = p.Number("full-s", o.full_s);
  if (o.kills < 0 || o.site_cuts < 0) throw UsageError("--kills and --site-cuts must be 0 or more");
  if (3 * o.site_cuts > o.kills) throw UsageError("--kills must be at least 3 x --site-cuts (a site cut kills three programs)");
  if (!(o.days >= 5 && o.days <= 3650)) throw UsageError("--days: must be in [5, 3650]");
  if (o.speed < 0) throw UsageError("--speed: must be positive");
  if (o.max_down_ms < 0 || o.max_down_ms > 60000) throw UsageError("--max-down-ms: must be 0..60000");
  if (o.fills < 0 || (o.fills > 0 && o.data_dir.empty())) throw UsageError("--fills needs --data-dir (and must be 0 or more)");
  if (!(o.full_s > 0 && o.full_s <= 600)) throw UsageError("--full-s: must be in (0, 600]");
  return o;
}

void SleepMs(int ms) {
  std::this_thread::sleep_for(std::chrono::milliseconds(ms));
}

double WallS(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// A program of the pipeline that the soak kills and starts again with the same arguments.
struct Program {
  const char* name;
  lw::test::ChildProcess process;
  std::vector<std::string> argv;
  std::string log;
  bool down = false;  // killed on purpose, not restarted yet
  std::chrono::steady_clock::time_point started{};
  void Start() {
    process.Start(argv, log);
    down = false;
    started = std::chrono::steady_clock::now();
  }
};

struct Totals {
  long kills = 0, broker = 0, gateway = 0, server = 0, site_cuts = 0, unexpected_exits = 0;
  long fills = 0, server_db_errors = 0, gateway_spool_errors = 0;
  size_t produced = 0, stored = 0, lost = 0, duplicated = 0, mismatched = 0;
  unsigned long long air_sent = 0, air_lost = 0, air_dup = 0;
  int rounds = 0;
};

// "air: 1502 sent, 301 lost, 70 duplicated" of the simulator's last progress line.
void AddAirCounters(const std::string& sim_log, Totals* t) {
  const size_t at = sim_log.rfind("air: ");
  if (at == std::string::npos) return;
  unsigned long long s = 0, l = 0, d = 0;
  if (std::sscanf(sim_log.c_str() + at, "air: %llu sent, %llu lost, %llu duplicated", &s, &l, &d) == 3) {
    t->air_sent += s;
    t->air_lost += l;
    t->air_dup += d;
  }
}

// Writes `path` until the file system is full (ENOSPC); returns the bytes written.
long long FillFileSystem(const std::string& path) {
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) throw std::runtime_error("cannot create filler " + path);
  std::vector<char> block(4096, 'x');
  long long n = 0;
  std::setvbuf(f, nullptr, _IONBF, 0);
  while (std::fwrite(block.data(), 1, block.size(), f) == block.size()) n += static_cast<long long>(block.size());
  for (int i = 0; i < 4096 && std::fwrite(block.data(), 1, 1, f) == 1; ++i) ++n;  // the last partial block
  std::fclose(f);
  return n;
}

long CountLines(const std::string& path, const std::string& needle) {
  const std::string text = lw::test::FileTail(path, 1 << 26);
  long n = 0;
  for (size_t at = text.find(needle); at != std::string::npos; at = text.find(needle, at + 1)) ++n;
  return n;
}

class Soak {
 public:
  Soak(const Options& o, const std::string& crushers, const lw::core::Bundle& folder)
      : o_(o), crushers_(crushers), folder_(folder), rng_(o.seed), t0_(std::chrono::steady_clock::now()) {}

  const Totals& totals() const { return t_; }
  bool Done() const { return t_.kills >= o_.kills && t_.site_cuts >= o_.site_cuts; }

  /// One campaign with faults; adds its counts to the totals. Throws on a setup failure.
  void Round(double speed) {
    const int round = ++t_.rounds;
    const std::string dir = o_.out + "/round-" + std::to_string(round);
    fs::create_directories(dir);
    const std::string crusher = folder_.crusher.crusher_id;
    // A fresh broker per campaign: a new campaign's boards reuse seqs from 0.
    lw::test::MosquittoFixture::Options bo;
    bo.persistence = true;
    bo.username = kUser;
    bo.password = kPassword;
    lw::test::MosquittoFixture broker(bo);
    broker.Start();
    const int http_port = lw::test::FreeLoopbackPort();
    const std::string data = o_.data_dir.empty() ? dir : o_.data_dir + "/round-" + std::to_string(round);
    fs::create_directories(data);
    if (fs::exists(data + "/server.sqlite") || fs::exists(data + "/spool.db")) {
      throw std::runtime_error(data + " holds a database of an earlier run: give an empty --data-dir / --out");
    }
    const std::string clock = dir + "/clock", db = data + "/server.sqlite", ledger = dir + "/ledger.csv";
    const std::string filler = o_.data_dir + "/filler";
    Program server{"server",
                   {},
                   {LW_SERVER_BIN, "--broker", broker.uri(), "--db", db, "--http", "127.0.0.1:" + std::to_string(http_port),
                    "--crusher-dir", crushers_, "--username", kUser, "--password", kPassword, "--clock-file", clock,
                    "--wear-interval-ms", "1000", "--web-dir", ""},
                   dir + "/server.log"};
    Program sim{"sim",
                {},
                {LW_SIM_BIN,      "run",
                 "--crusher-dir", crushers_,
                 "--serial-out",  dir + "/tty",
                 "--days",        std::to_string(o_.days),
                 "--speed",       std::to_string(speed),
                 "--loss",        std::to_string(o_.loss),
                 "--dup",         std::to_string(o_.dup),
                 "--api-mode",    "2",
                 "--clock-out",   clock,
                 "--ledger",      ledger,
                 "--drain-days",  "3",
                 "--seed",        std::to_string((o_.seed + round) % 1000000)},
                dir + "/sim.log"};
    Program gateway{"gateway",
                    {},
                    {LW_GATEWAY_BIN,
                     "--serial",
                     dir + "/tty",
                     "--api-mode",
                     "2",
                     "--broker",
                     broker.uri(),
                     "--site",
                     "chaos-site",
                     "--crusher",
                     crusher,
                     "--spool",
                     data + "/spool.db",
                     "--clock-file",
                     clock,
                     "--gateway-id",
                     "gw-chaos",
                     "--username",
                     kUser,
                     "--password",
                     kPassword,
                     "--republish-after",
                     "1"},
                    dir + "/gateway.log"};
    server.Start();
    sim.Start();
    struct stat st {};
    for (int i = 0; i < 300 && ::lstat((dir + "/tty").c_str(), &st) != 0; ++i) SleepMs(100);
    if (::lstat((dir + "/tty").c_str(), &st) != 0)
      throw std::runtime_error("the simulator made no pty: " + lw::test::FileTail(sim.log));
    gateway.Start();

    // The fault times, in virtual days, for the kills still to deliver.
    const long cuts_left = std::max(0L, o_.site_cuts - t_.site_cuts);
    const long singles_left = std::max(0L, o_.kills - t_.kills - 3 * cuts_left);
    std::uniform_real_distribution<double> when(0.5, o_.days - 3);
    std::vector<std::pair<double, bool>> faults;  // (day, site cut)
    for (long i = 0; i < cuts_left; ++i) faults.push_back({when(rng_), true});
    for (long i = 0; i < singles_left; ++i) faults.push_back({when(rng_), false});
    std::sort(faults.begin(), faults.end());
    std::vector<double> fills;  // virtual days the file system fills up
    for (long i = 0; i < o_.fills; ++i) fills.push_back(when(rng_));
    std::sort(fills.begin(), fills.end());
    size_t next_fill = 0;
    double full_until = -1;  // wall time the filler goes (-1: not full)

    auto down_ms = [&] { return o_.max_down_ms ? static_cast<int>(rng_() % static_cast<unsigned>(o_.max_down_ms + 1)) : 0; };
    size_t next = 0;
    double last_progress = WallS(t0_);
    double day = 0;
    while (sim.process.Running()) {
      // A program that died without being killed is a finding: count it, log it, start it again.
      for (Program* p : {&server, &gateway}) {
        if (!p->down && WallS(p->started) > 1 && !p->process.Running()) {
          ++t_.unexpected_exits;
          std::fprintf(stderr, "chaos: %s exited by itself (status %d): %s\n", p->name, p->process.status(),
                       lw::test::FileTail(p->log, 400).c_str());
          p->Start();
        }
      }
      if (!broker.running()) {
        ++t_.unexpected_exits;
        std::fprintf(stderr, "chaos: the broker exited by itself: %s\n", lw::test::FileTail(broker.log_file(), 400).c_str());
        broker.Start();
      }
      day = lw::test::VirtualDay(clock, folder_.crusher.installed_at);
      if (full_until < 0 && next_fill < fills.size() && day >= fills[next_fill]) {
        const long long bytes = FillFileSystem(filler);
        std::fprintf(stderr, "chaos: round %d, day %.1f: %s full (filler of %lld bytes) for %.0f s\n", round, day,
                     o_.data_dir.c_str(), bytes, o_.full_s);
        full_until = WallS(t0_) + o_.full_s;
        ++next_fill;
        ++t_.fills;
      } else if (full_until >= 0 && WallS(t0_) >= full_until) {
        fs::remove(filler);
        full_until = -1;
        std::fprintf(stderr, "chaos: round %d, day %.1f: space is back\n", round, day);
      }
      if (next < faults.size() && day >= faults[next].first) {
        if (faults[next].second) {
          // Site power cut: the three die at the same instant (signals first, reaping after).
          broker.Signal(SIGKILL);
          gateway.process.Signal(SIGKILL);
          server.process.Signal(SIGKILL);
          broker.Kill();
          gateway.process.Kill();
          server.process.Kill();
          gateway.down = server.down = true;
          SleepMs(down_ms());
          server.Start();  // power returns: everything boots together
          gateway.Start();
          broker.Start();
          ++t_.site_cuts;
          t_.kills += 3;
          ++t_.broker;
          ++t_.gateway;
          ++t_.server;
        } else {
          switch (rng_() % 3) {
            case 0:
              broker.Kill();
              SleepMs(down_ms());
              broker.Start();
              ++t_.broker;
              break;
            case 1:
              gateway.process.Kill();
              gateway.down = true;
              SleepMs(down_ms());
              gateway.Start();
              ++t_.gateway;
              break;
            default:
              server.process.Kill();
              server.down = true;
              SleepMs(down_ms());
              server.Start();
              ++t_.server;
              break;
          }
          ++t_.kills;
        }
        ++next;
      }
      if (WallS(t0_) - last_progress >= 15) {
        last_progress = WallS(t0_);
        Progress(round, day);
      }
      SleepMs(10);
    }
    if (full_until >= 0) fs::remove(filler);
    Progress(round, day);
    if (next < faults.size()) {
      std::fprintf(stderr, "chaos: round %d ended with %zu faults not delivered (the campaign outran them)\n", round,
                   faults.size() - next);
    }
    const std::string sim_log = lw::test::FileTail(sim.log, 1 << 20);
    AddAirCounters(sim_log, &t_);
    if (!WIFEXITED(sim.process.status()) || WEXITSTATUS(sim.process.status()) != 0) {
      throw std::runtime_error("the simulator failed: " + lw::test::FileTail(sim.log));
    }
    const std::vector<lw::test::Produced> produced = lw::test::LoadLedger(ledger);

    // The gateway publishes what it holds until the server has committed it all.
    long stored = -1;
    for (const double deadline = WallS(t0_) + 180; WallS(t0_) < deadline; SleepMs(500)) {
      stored = lw::test::StoredCount(http_port, crusher);
      if (stored >= static_cast<long>(produced.size())) break;
    }
    SleepMs(2000);  // anything late (a duplicate) has time to show
    gateway.process.Stop(SIGTERM);
    server.process.Stop(SIGTERM);
    broker.Stop();
    t_.server_db_errors += CountLines(server.log, "database error");
    t_.gateway_spool_errors += CountLines(gateway.log, "not stored (not acked)");
    lw::server::Store store(db);
    const lw::test::LedgerCheck check = lw::test::CompareLedger(produced, store.All(crusher));
    t_.produced += check.produced;
    t_.stored += check.stored;
    t_.lost += check.lost;
    t_.duplicated += check.duplicated;
    t_.mismatched += check.mismatched;
    std::fprintf(stderr, "chaos: round %d: produced %zu, stored %zu, lost %zu, duplicated %zu, mismatched %zu%s%s\n", round,
                 check.produced, check.stored, check.lost, check.duplicated, check.mismatched,
                 check.first_problem.empty() ? "" : "; first: ", check.first_problem.c_str());
    const size_t last_line = sim_log.rfind("linerwatch-sim: ");
    if (last_line != std::string::npos) std::fprintf(stderr, "chaos: %s", sim_log.substr(last_line).c_str());
  }

  void Progress(int round, double day) const {
    std::fprintf(stderr,
                 "chaos: round %d, day %.1f/%.0f: kills %ld (broker %ld, gateway %ld, server %ld; %ld site cuts), "
                 "unexpected exits %ld, disk full %ld times; wall %.0f s\n",
                 round, day, o_.days, t_.kills, t_.broker, t_.gateway, t_.server, t_.site_cuts, t_.unexpected_exits, t_.fills,
                 WallS(t0_));
  }

  double wall_s() const { return WallS(t0_); }

 private:
  const Options& o_;
  std::string crushers_;
  const lw::core::Bundle& folder_;
  std::mt19937 rng_;
  std::chrono::steady_clock::time_point t0_;
  Totals t_;
};

}  // namespace

int main(int argc, char** argv) {
  Options o;
  try {
    bool help = false;
    o = Parse(std::vector<std::string>(argv + 1, argv + argc), &help);
    if (help) {
      std::fputs(Help().c_str(), stdout);
      return 0;
    }
  } catch (const UsageError& e) {
    std::fprintf(stderr, "lw_bench_chaos: %s\n", e.what());
    return 2;
  }
  std::signal(SIGPIPE, SIG_IGN);
  if (o.out.empty()) o.out = "/tmp/lw-chaos-" + std::to_string(::getpid());
  const long events = (o.kills - 3 * o.site_cuts) + o.site_cuts;
  const double speed = o.speed > 0 ? o.speed : std::clamp(o.days * 86400.0 / (std::max(1L, events) * 1.5), 200.0, 400000.0);
  int rc = 1;
  try {
    fs::create_directories(o.out);
    const std::string crushers = o.out + "/crushers";
    fs::create_directories(crushers);
    if (!fs::exists(crushers + "/chaos/crusher.json") &&
        lw::test::RunCommand({LW_SIM_BIN, "campaign", "--out", crushers + "/chaos", "--preset", "paper", "--days",
                              std::to_string(o.days), "--no-scan", "--seed", "7"},
                             o.out + "/campaign.log") != 0) {
      throw std::runtime_error("linerwatch-sim campaign failed: " + lw::test::FileTail(o.out + "/campaign.log"));
    }
    const lw::core::Bundle folder = lw::core::LoadBundle(crushers + "/chaos");
    std::fprintf(stderr,
                 "chaos: seed %u; %ld kills incl. %ld site cuts over %.0f-day campaigns, radio loss %.2f, dup %.2f, "
                 "speed %.0f, down up to %d ms; out %s\n",
                 o.seed, o.kills, o.site_cuts, o.days, o.loss, o.dup, speed, o.max_down_ms, o.out.c_str());
    Soak soak(o, crushers, folder);
    do {
      soak.Round(speed);
    } while (!soak.Done());
    const Totals& t = soak.totals();
    std::printf(
        "chaos: kills %ld (broker %ld, gateway %ld, server %ld; %ld site cuts), produced %zu, stored %zu, lost %zu, "
        "duplicated %zu, mismatched %zu; unexpected exits %ld; disk full %ld times (server 'database error' lines %ld, "
        "gateway 'not stored (not acked)' lines %ld, both rate limited); campaigns %d of %.0f days; radio %llu sent, "
        "%llu lost, %llu duplicated; seed %u; wall %.0f s\n",
        t.kills, t.broker, t.gateway, t.server, t.site_cuts, t.produced, t.stored, t.lost, t.duplicated, t.mismatched,
        t.unexpected_exits, t.fills, t.server_db_errors, t.gateway_spool_errors, t.rounds, o.days, t.air_sent, t.air_lost,
        t.air_dup, o.seed, soak.wall_s());
    std::fflush(stdout);
    rc = (t.lost == 0 && t.duplicated == 0 && t.mismatched == 0 && t.produced > 0) ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lw_bench_chaos: %s\n", e.what());
    rc = 1;
  }
  if (rc == 0 && !o.keep) {
    std::error_code ec;
    fs::remove_all(o.out, ec);
  } else {
    std::fprintf(stderr, "chaos: logs in %s\n", o.out.c_str());
  }
  return rc;
}
