// linerwatch-sim run: boards running the real firmware, the virtual XBee network and the
// coordinator, whose serial side is a pty the real gateway opens (docs/sim.md, "run").
#include "run.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "core/atomic_file.hpp"
#include "core/bundle.hpp"
#include "core/cmdline.hpp"
#include "core/time.hpp"
#include "sim/fleet.hpp"
#include "sim/truth.hpp"

namespace lw::sim {
namespace {

namespace fs = std::filesystem;
using WallClock = std::chrono::steady_clock;

using core::NumberRange;
using core::Option;

const core::OptionTable& RunTable() {
  static const core::OptionTable table{{
      Option::Text("crusher-dir", "DIR", "folder of crusher folders (crusher.json + wear_map.vtk), or one crusher folder")
          .Required(),
      Option::Text("crusher", "ID", "which sub-folder of DIR (needed when it holds several)"),
      Option::Text("serial-out", "PATH", "symlink to create to the coordinator's pty (replaced if it is a symlink)").Required(),
      Option::Number("days", "N", NumberRange{0, 3650, true, false},
                     "campaign length in virtual days (default: the campaign's, else 95)"),
      Option::Number("speed", "X", NumberRange{0, std::numeric_limits<double>::infinity(), false, true},
                     "virtual seconds per wall second (default 400000: 95 days in ~20 s;\n0: as fast as the gateway acks)"),
      Option::Whole("api-mode", "1|2", 1, 2, "coordinator API mode, must match the gateway's (default 1)"),
      Option::Whole("radio-np", "N", 1, 255,
                    "what every virtual radio answers to AT NP (default 255: an XBee 3 in API\nmode); "
                    "a frame above the payload limit it implies is refused, not sent"),
      Option::Whole("radio-ee", "0|1", 0, 1, "what every virtual radio answers to AT EE (default 0)"),
      Option::Text("clock-out", "PATH", "keep the virtual time (Unix ms) in PATH for the gateway's --clock-file"),
      Option::Number("loss", "P", NumberRange{0, 1, false, true},
                     "probability that a radio transmission attempt is lost (default 0)"),
      Option::Number("dup", "P", NumberRange{0, 1, false, true}, "probability that a delivered packet arrives twice (default 0)"),
      Option::Number("latency-ms", "MS", NumberRange{0, 60000, false, false},
                     "mean one-way radio latency in virtual ms (default 50)"),
      Option::Unsigned("seed", "N", "seed of the network (default 1); the same seed gives the same run"),
      Option::Number("ack-wait", "S", NumberRange{0, 60, true, false},
                     "wall seconds to wait for the gateway's acks before virtual time moves\non (default 2)"),
      Option::Number("drain-days", "N", NumberRange{0, 30, false, false},
                     "after the campaign, keep boards with unacked records running up to N\nvirtual days (default 1)"),
      Option::Text("ledger", "FILE", "CSV sensor_id,seq,time,thickness_mm of every reading the sensors produced"),
      Option::Text("bundle-out", "DIR",
                   "campaign bundle of the run (crusher.json, wear_map.vtk, readings.csv,\n"
                   "operations.csv) for `linerwatch diagnose`; DIR must not exist or be empty"),
      Option::Switch("quiet", "no progress lines"),
  }};
  return table;
}

std::string RunHelp() {
  return "linerwatch-sim run: a virtual site through the real firmware, into the real gateway.\n\n"
         "Usage: linerwatch-sim run " +
         RunTable().Synopsis(26, 100) + "\n\n" +
         R"(One virtual sensor board per sensor of the crusher runs the real firmware on the host HAL; its
wear ladder breaks as the truth says (the campaign generator's truth when the crusher folder was
made by `linerwatch-sim campaign`, else wear proportional to the map intensity). The boards talk
over a virtual XBee network to a coordinator whose serial side is a pty: PATH becomes a symlink
to it; start `linerwatch-gateway --serial PATH --api-mode M --clock-file CLOCK` on it.
)" + "\n" +
         RunTable().Help(25);
}

volatile std::sig_atomic_t g_stop = 0;
void OnSignal(int) {
  g_stop = 1;
}

struct RunOptions {
  std::string crusher_dir, crusher, serial_out, clock_out, ledger, bundle_out;
  double days = -1;
  double speed = 400000;
  int api_mode = 1;
  int radio_np = 255, radio_ee = 0;
  double loss = 0, dup = 0, latency_ms = 50;
  uint64_t seed = 1;
  double ack_wait_s = 2;
  double drain_days = 1;
  bool quiet = false;
};

using core::UsageError;

/// Returns false for --help.
bool Parse(const std::vector<std::string>& args, RunOptions* o) {
  const core::ParsedOptions p = core::ParseOptions(RunTable(), args);
  if (p.help()) return false;
  o->crusher_dir = p.Text("crusher-dir");
  o->crusher = p.Text("crusher");
  o->serial_out = p.Text("serial-out");
  o->clock_out = p.Text("clock-out");
  o->ledger = p.Text("ledger");
  o->bundle_out = p.Text("bundle-out");
  o->days = p.Number("days", o->days);
  o->speed = p.Number("speed", o->speed);
  o->api_mode = p.Integer<int>("api-mode", o->api_mode);
  o->radio_np = p.Integer<int>("radio-np", o->radio_np);
  o->radio_ee = p.Integer<int>("radio-ee", o->radio_ee);
  o->loss = p.Number("loss", o->loss);
  o->dup = p.Number("dup", o->dup);
  o->latency_ms = p.Number("latency-ms", o->latency_ms);
  o->seed = p.Integer<uint64_t>("seed", o->seed);
  o->ack_wait_s = p.Number("ack-wait", o->ack_wait_s);
  o->drain_days = p.Number("drain-days", o->drain_days);
  o->quiet = p.Switch("quiet");
  return true;
}

fs::path FindCrusherFolder(const RunOptions& o) {
  const fs::path dir = o.crusher_dir;
  if (!fs::is_directory(dir)) throw UsageError("--crusher-dir: '" + o.crusher_dir + "' is not a directory");
  if (fs::exists(dir / "crusher.json")) {
    if (!o.crusher.empty() && dir.filename() != o.crusher) {
      throw UsageError("--crusher: '" + o.crusher + "' given but --crusher-dir is itself the crusher folder " + dir.string());
    }
    return dir;
  }
  if (!o.crusher.empty()) {
    if (!fs::exists(dir / o.crusher / "crusher.json"))
      throw UsageError("--crusher: no " + (dir / o.crusher / "crusher.json").string());
    return dir / o.crusher;
  }
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.is_directory() && fs::exists(e.path() / "crusher.json")) names.push_back(e.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  if (names.empty()) throw UsageError("--crusher-dir: no crusher folder (with crusher.json) in " + dir.string());
  if (names.size() > 1) {
    std::string list;
    for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
    throw UsageError("--crusher-dir holds several crushers (" + list + "): choose one with --crusher ID");
  }
  return dir / names[0];
}

std::string Mm(double mm) {
  std::ostringstream os;
  os << mm;
  return os.str();
}

std::string LedgerCsv(const std::vector<LedgerEntry>& ledger) {
  std::string s = "sensor_id,seq,time,thickness_mm\n";
  for (const LedgerEntry& e : ledger)
    s += e.sensor_id + "," + std::to_string(e.seq) + "," + core::FormatIsoSeconds(e.time_s) + "," + Mm(e.thickness_mm) + "\n";
  return s;
}

void WriteBundle(const fs::path& out, const CrusherFolder& folder, const Fleet& fleet, int64_t end_s) {
  lw::core::WriteFolderAtomically(
      out,
      [&](const fs::path& tmp) {
        fs::copy_file(folder.dir / "crusher.json", tmp / "crusher.json");
        fs::copy_file(folder.dir / "wear_map.vtk", tmp / "wear_map.vtk");
        if (fs::exists(folder.dir / kCampaignMarker)) fs::copy_file(folder.dir / kCampaignMarker, tmp / kCampaignMarker);
        std::vector<LedgerEntry> sorted = fleet.ledger();
        std::stable_sort(sorted.begin(), sorted.end(),
                         [](const LedgerEntry& a, const LedgerEntry& b) { return a.time_s < b.time_s; });
        std::vector<core::Reading> readings;
        for (const LedgerEntry& e : sorted) readings.push_back({core::FromUnixSeconds(e.time_s), e.sensor_id, e.thickness_mm});
        lw::core::WriteFileAtomically(tmp / "readings.csv", core::ReadingsCsv(readings));
        std::vector<core::OperationsSample> ops;
        const auto truth_ops = folder.truth->Operations();
        for (const auto& x : truth_ops) {
          if (x.time.time_since_epoch().count() > end_s) break;
          ops.push_back(x);
        }
        // The map model wears at a constant rate: constant nominal tonnage, daily.
        if (truth_ops.empty())
          for (int64_t t = fleet.start_s(); t <= end_s; t += 86400) ops.push_back({core::FromUnixSeconds(t), 3500.0, {}, {}});
        lw::core::WriteFileAtomically(tmp / "operations.csv", core::OperationsCsv(ops));
      },
      "--bundle-out");
}

/// The coordinator's pty: the master end is ours, PATH is a symlink to the slave end. While no
/// process has the slave open (no gateway), the master polls POLLHUP.
class Pty {
 public:
  explicit Pty(const std::string& link) : link_(link) {
    master_ = ::posix_openpt(O_RDWR | O_NOCTTY);
    if (master_ < 0 || ::grantpt(master_) != 0 || ::unlockpt(master_) != 0)
      throw std::runtime_error(std::string("pty: ") + std::strerror(errno));
    const char* name = ::ptsname(master_);
    if (!name) throw std::runtime_error(std::string("pty: ") + std::strerror(errno));
    slave_name_ = name;
    {
      // Raw from the start (the setting stays with the pty while the master is open).
      const int slave = OpenSlave();
      if (slave < 0) throw std::runtime_error("pty: cannot open " + slave_name_ + ": " + std::strerror(errno));
      termios t{};
      ::tcgetattr(slave, &t);
      ::cfmakeraw(&t);
      ::tcsetattr(slave, TCSANOW, &t);
      ::close(slave);
    }
    ::fcntl(master_, F_SETFL, ::fcntl(master_, F_GETFL) | O_NONBLOCK);
    struct stat st {};
    if (::lstat(link.c_str(), &st) == 0 && !S_ISLNK(st.st_mode)) {
      throw UsageError("--serial-out: '" + link + "' exists and is not a symlink (refusing to replace it)");
    }
    const std::string tmp = link + ".tmp-" + std::to_string(::getpid());
    ::unlink(tmp.c_str());
    if (::symlink(slave_name_.c_str(), tmp.c_str()) != 0 || ::rename(tmp.c_str(), link.c_str()) != 0) {
      ::unlink(tmp.c_str());
      throw UsageError("--serial-out: cannot create symlink '" + link + "': " + std::strerror(errno));
    }
    linked_ = true;
  }
  ~Pty() {
    if (linked_) {
      char target[256] = {};
      const ssize_t n = ::readlink(link_.c_str(), target, sizeof target - 1);
      if (n > 0 && slave_name_ == std::string(target, static_cast<size_t>(n))) ::unlink(link_.c_str());
    }
    if (master_ >= 0) ::close(master_);
  }
  Pty(const Pty&) = delete;
  Pty& operator=(const Pty&) = delete;
  int master() const { return master_; }
  const std::string& slave_name() const { return slave_name_; }
  /// True while some process (the gateway) has the slave end open.
  bool ReaderPresent() const {
    pollfd p{master_, POLLIN, 0};
    return ::poll(&p, 1, 0) >= 0 && !(p.revents & POLLHUP);
  }
  /// Bytes written that the gateway has not read yet.
  int Unread() const {
    const int slave = OpenSlave();
    int n = 0;
    if (slave < 0 || ::ioctl(slave, FIONREAD, &n) != 0) n = 0;
    if (slave >= 0) ::close(slave);
    return n;
  }
  /// Drops what the gateway has not read (a later reader must not see stale frames).
  void DropUnread() {
    const int slave = OpenSlave();
    if (slave < 0) return;
    ::tcflush(slave, TCIFLUSH);
    ::close(slave);
  }

 private:
  int OpenSlave() const { return ::open(slave_name_.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC); }
  std::string link_;
  std::string slave_name_;
  int master_ = -1;
  bool linked_ = false;
};

class Runner {
 public:
  Runner(const RunOptions& o, CrusherFolder& folder, Fleet& fleet, Pty& pty)
      : o_(o), folder_(folder), fleet_(fleet), pty_(pty), wall0_(WallClock::now()) {}

  /// Runs until `end_s` (plus the drain) or a signal; returns true when stopped by a signal.
  bool Run(int64_t end_s) {
    const double start = static_cast<double>(fleet_.start_s());
    const double drain_end = static_cast<double>(end_s) + o_.drain_days * 86400.0;
    WriteClock(start);
    double next_progress = start + 86400.0;
    while (!g_stop) {
      const bool sampling = fleet_.now() < static_cast<double>(end_s);
      const double te = fleet_.NextEventTime(sampling);
      if (!sampling && (fleet_.queued_records() == 0 || te > drain_end)) break;
      if (sampling && te > static_cast<double>(end_s)) {
        fleet_.AdvanceTo(static_cast<double>(end_s));
        continue;
      }
      if (!std::isfinite(te)) break;
      // Pace: virtual time runs at most `speed` times wall time; gateway input is read meanwhile.
      if (o_.speed > 0) {
        const double due_wall = (te - start) / o_.speed;
        const double ahead = due_wall - WallSeconds();
        if (ahead > 0) {
          ReadInput(static_cast<int>(std::min(ahead * 1000.0, 50.0)));
          continue;
        }
      }
      ReadInput(0);
      // The coordinator hands the gateway what arrived within one virtual second at once (the
      // clock file then holds the second's first event: stamps keep whole-second accuracy).
      const double window_end = std::min(std::floor(te) + 0.999, sampling ? static_cast<double>(end_s) : drain_end);
      fleet_.AdvanceTo(std::max(te, window_end), sampling);
      std::vector<uint8_t> out = fleet_.TakeSerialOutput();
      if (!out.empty()) {
        WriteClock(te);
        if (WriteSerial(out)) Hold();
      }
      if (te >= next_progress) {
        Progress(te, end_s);
        WriteClock(te);
        while (next_progress <= te) next_progress += 86400.0;
      }
    }
    ReadInput(0);
    Progress(fleet_.now(), end_s);
    return g_stop != 0;
  }

  uint64_t serial_dropped() const { return serial_dropped_; }
  uint64_t hold_timeouts() const { return hold_timeouts_; }

  /// Waits until a gateway opens the pty; false when stopped by a signal first.
  bool WaitForGateway() {
    if (pty_.ReaderPresent()) return true;
    if (!o_.quiet) std::fprintf(stderr, "linerwatch-sim: waiting for a gateway to open %s\n", o_.serial_out.c_str());
    while (!g_stop && !pty_.ReaderPresent()) ::poll(nullptr, 0, 50);
    wall0_ = WallClock::now();  // virtual time starts now
    return !g_stop;
  }

 private:
  double WallSeconds() const { return std::chrono::duration<double>(WallClock::now() - wall0_).count(); }

  void WriteClock(double t) {
    if (o_.clock_out.empty()) return;
    const long long ms = std::llround(t * 1000.0);
    if (ms == last_clock_ms_) return;
    lw::core::WriteFileAtomically(o_.clock_out, std::to_string(ms) + "\n", lw::core::Durability::kAtomic);
    last_clock_ms_ = ms;
  }

  void ReadInput(int timeout_ms) {
    pollfd p{pty_.master(), POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return;
    if (!(p.revents & POLLIN)) {  // no gateway (POLLHUP): nothing to read, wait anyway
      if (timeout_ms > 0) ::poll(nullptr, 0, timeout_ms);
      return;
    }
    uint8_t buf[4096];
    for (;;) {
      const ssize_t n = ::read(pty_.master(), buf, sizeof buf);
      if (n <= 0) break;
      fleet_.OnSerialInput(buf, static_cast<size_t>(n));
    }
  }

  /// Writes frames for the gateway; returns false when none is there (the frames are lost, as
  /// on a coordinator whose host does not read its serial port: the boards retransmit).
  bool WriteSerial(const std::vector<uint8_t>& out) {
    if (!pty_.ReaderPresent()) {
      if (!absent_) pty_.DropUnread();  // what the gone gateway left unread is stale now
      absent_ = true;
      serial_dropped_ += out.size();
      fleet_.ForgetUnacked();
      return false;
    }
    absent_ = false;
    size_t done = 0;
    const double deadline = WallSeconds() + o_.ack_wait_s;
    while (done < out.size()) {
      const ssize_t n = ::write(pty_.master(), out.data() + done, out.size() - done);
      if (n > 0) {
        done += static_cast<size_t>(n);
        continue;
      }
      if (n < 0 && errno != EAGAIN && errno != EINTR) throw std::runtime_error(std::string("pty write: ") + std::strerror(errno));
      if (WallSeconds() > deadline) {  // the gateway does not read: what is not written is lost
        pty_.DropUnread();
        serial_dropped_ += out.size() - done;
        fleet_.ForgetUnacked();
        return false;
      }
      ReadInput(5);
    }
    return true;
  }

  /// Keeps virtual time still until the gateway has acked every record just written (it stamps a
  /// reading with the clock file's time when it reads the frame), or gives up after --ack-wait.
  void Hold() {
    const double deadline = WallSeconds() + o_.ack_wait_s;
    while (fleet_.unacked_serial_records() > 0 && WallSeconds() < deadline && !g_stop && pty_.ReaderPresent()) ReadInput(2);
    if (fleet_.unacked_serial_records() == 0) return;
    // No ack in time: a gateway that reads these frames later must not stamp them with a later time.
    if (pty_.Unread() > 0) pty_.DropUnread();
    ++hold_timeouts_;
    fleet_.ForgetUnacked();
  }

  void Progress(double t, int64_t end_s) {
    if (o_.quiet) return;
    const FleetCounters c = fleet_.counters();
    const NetworkCounters& n = fleet_.network_counters();
    std::fprintf(stderr,
                 "linerwatch-sim: day %.1f/%.1f: %llu readings produced, %llu acked to the sensors, %llu queued; "
                 "air: %llu sent, %llu lost, %llu duplicated; wall %.1f s\n",
                 (t - static_cast<double>(fleet_.start_s())) / 86400.0, static_cast<double>(end_s - fleet_.start_s()) / 86400.0,
                 static_cast<unsigned long long>(c.readings_produced), static_cast<unsigned long long>(c.readings_acked),
                 static_cast<unsigned long long>(fleet_.queued_records()), static_cast<unsigned long long>(n.attempts),
                 static_cast<unsigned long long>(n.lost), static_cast<unsigned long long>(n.duplicated), WallSeconds());
  }

  const RunOptions& o_;
  CrusherFolder& folder_;
  Fleet& fleet_;
  Pty& pty_;
  WallClock::time_point wall0_;
  long long last_clock_ms_ = -1;
  bool absent_ = false;
  uint64_t serial_dropped_ = 0;
  uint64_t hold_timeouts_ = 0;
};

int Fail(const std::string& why, int code) {
  std::fprintf(stderr, "linerwatch-sim: run: %s\n", why.c_str());
  return code;
}

}  // namespace

int RunCommand(const std::vector<std::string>& args) {
  RunOptions o;
  CrusherFolder folder;
  try {
    if (!Parse(args, &o)) {
      std::cout << RunHelp();
      return 0;
    }
    folder = LoadCrusherFolder(FindCrusherFolder(o));
    if (!o.bundle_out.empty() && fs::exists(o.bundle_out) && !(fs::is_directory(o.bundle_out) && fs::is_empty(o.bundle_out))) {
      throw UsageError("--bundle-out: '" + o.bundle_out + "' exists and is not an empty directory");
    }
  } catch (const UsageError& e) {
    return Fail(e.what(), 2);
  } catch (const std::exception& e) {
    return Fail(e.what(), 2);
  }
  try {
    double days = o.days;
    if (days <= 0) {
      const auto* c = dynamic_cast<const CampaignTruth*>(folder.truth.get());
      days = c ? c->campaign().spec().days : 95;
    }
    FleetOptions fo;
    fo.network.loss = o.loss;
    fo.network.dup = o.dup;
    fo.network.latency_s = o.latency_ms / 1000.0;
    fo.network.seed = o.seed;
    fo.radio_np = static_cast<uint8_t>(o.radio_np);
    fo.radio_ee = static_cast<uint8_t>(o.radio_ee);
    fo.serial_mode = o.api_mode == 1 ? protocol::ApiMode::kUnescaped : protocol::ApiMode::kEscaped;
    Fleet fleet(folder.crusher, *folder.truth, fo);
    const int64_t end_s = fleet.start_s() + static_cast<int64_t>(std::llround(days * 86400.0));
    Pty pty(o.serial_out);
    struct sigaction sa {};
    sa.sa_handler = OnSignal;
    sigaction(SIGINT, &sa, nullptr);
    sigaction(SIGTERM, &sa, nullptr);
    std::signal(SIGPIPE, SIG_IGN);
    if (!o.quiet) {
      std::fprintf(stderr, "linerwatch-sim: crusher %s: %zu boards, %.1f days from %s; truth: %s\n",
                   folder.crusher.crusher_id.c_str(), fleet.board_count(), days, core::FormatIsoSeconds(fleet.start_s()).c_str(),
                   folder.truth->Describe().c_str());
      std::fprintf(stderr, "linerwatch-sim: coordinator on %s -> %s (API mode %d)%s%s\n", o.serial_out.c_str(),
                   pty.slave_name().c_str(), o.api_mode, o.clock_out.empty() ? "" : ", virtual clock in ", o.clock_out.c_str());
    }
    if (!o.clock_out.empty())
      lw::core::WriteFileAtomically(o.clock_out, std::to_string(fleet.start_s() * 1000) + "\n", lw::core::Durability::kAtomic);
    Runner runner(o, folder, fleet, pty);
    const bool stopped = !runner.WaitForGateway() || runner.Run(end_s);
    if (!o.ledger.empty()) lw::core::WriteFileAtomically(o.ledger, LedgerCsv(fleet.ledger()));
    if (!o.bundle_out.empty()) WriteBundle(o.bundle_out, folder, fleet, std::min<int64_t>(end_s, std::llround(fleet.now())));
    if (!o.quiet) {
      const FleetCounters c = fleet.counters();
      std::fprintf(stderr,
                   "linerwatch-sim: %s: %llu readings produced, %llu acked to the sensors, %zu still queued; "
                   "%llu serial bytes dropped (no gateway), %llu ack waits timed out; "
                   "frames refused as too large: %llu from boards, %llu acks\n",
                   stopped ? "stopped" : "done", static_cast<unsigned long long>(c.readings_produced),
                   static_cast<unsigned long long>(c.readings_acked), fleet.queued_records(),
                   static_cast<unsigned long long>(runner.serial_dropped()),
                   static_cast<unsigned long long>(runner.hold_timeouts()), static_cast<unsigned long long>(c.frames_too_large),
                   static_cast<unsigned long long>(c.acks_too_large));
    }
    return 0;
  } catch (const UsageError& e) {
    return Fail(e.what(), 2);
  } catch (const std::exception& e) {
    return Fail(e.what(), 1);
  }
}

}  // namespace lw::sim
