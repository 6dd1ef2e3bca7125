#include "dem/runner.hpp"

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>
#include <fcntl.h>
#include <sys/file.h>
#include <sys/prctl.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "core/atomic_file.hpp"
#include "core/time.hpp"
#include "dem/case_writer.hpp"

namespace lw::dem {
namespace {

namespace fs = std::filesystem;
std::atomic<bool> g_stop{false};  // lock-free: safe to set from a signal handler or another thread

struct MassSample {
  double t = 0, n = 0, m_chamber = 0, m_hopper = 0, m_total = 0, m_inserted = 0;
};

std::vector<MassSample> ReadMassSeries(const fs::path& file) {
  std::vector<MassSample> s;
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#' || !(std::isdigit(static_cast<unsigned char>(line[0])) || line[0] == '-')) continue;
    std::istringstream ls(line);
    MassSample m;
    if (ls >> m.t >> m.n >> m.m_chamber >> m.m_hopper >> m.m_total >> m.m_inserted) s.push_back(m);
  }
  return s;
}

// Keeps only the samples at or before `t_max` (the resumed restart's time): a killed run wrote
// samples past its last restart that the resumed run writes again.
void TruncateMassSeries(const fs::path& file, double t_max) {
  std::ifstream in(file);
  if (!in) return;
  std::ostringstream kept;
  std::string line;
  while (std::getline(in, line)) {
    double t = 0;
    std::istringstream ls(line);
    if ((ls >> t) && t >= t_max - 1e-9) continue;  // the resumed run writes this time again
    kept << line << '\n';
  }
  in.close();
  core::WriteFileAtomically(file, kept.str());
}

int NextAttempt(const fs::path& dir) {
  int n = 1;
  while (fs::exists(dir / ("log." + std::to_string(n) + ".liggghts"))) ++n;
  return n;
}

// Where this attempt starts: the case's input, or the resume input with the newest restart file.
struct Start {
  std::string input = CaseLayout::kInput;
  std::string restart_file;
};

// Resume from the newest restart file that is complete (a kill while writing leaves a short one:
// LIGGGHTS then fails at once and the next newest is used on the following call).
Start ChooseStart(const ChamberSpec& spec, const fs::path& dir, RunResult& r) {
  auto restarts = StepsInFolder(dir / CaseLayout::kRestartDir, "crusher.", ".restart");
  Start start;
  if (!restarts.empty()) {
    r.resumed = true;
    r.resumed_from_step = restarts.back();
    start.restart_file = std::string(CaseLayout::kRestartDir) + "/crusher." + std::to_string(restarts.back()) + ".restart";
    start.input = CaseLayout::kResume;
    TruncateMassSeries(dir / CaseLayout::kMassSeries, static_cast<double>(r.resumed_from_step) * spec.timestep_s);
  }
  return start;
}

// One run per case folder: the lock is inherited by mpirun, so it holds while LIGGGHTS runs,
// even if this process was killed and LIGGGHTS has not finished stopping yet. Returns its fd.
int LockCase(const fs::path& dir) {
  const std::string lock_path = (dir / ".run.lock").string();
  const int lock_fd = open(lock_path.c_str(), O_RDWR | O_CREAT, 0644);
  if (lock_fd < 0 || flock(lock_fd, LOCK_EX | LOCK_NB) != 0) {
    if (lock_fd >= 0) close(lock_fd);
    throw std::runtime_error(dir.string() + ": another LIGGGHTS run of this case is still active (" + lock_path + " is locked)");
  }
  return lock_fd;
}

std::vector<std::string> LiggghtsArgv(const RunOptions& options, const Start& start, const std::string& log) {
  std::vector<std::string> argv = {options.mpirun,   "--bind-to", "none",      "-np",  std::to_string(options.np),
                                   options.liggghts, "-in",       start.input, "-log", log};
  if (!start.restart_file.empty()) argv.insert(argv.end(), {"-var", "restartfile", start.restart_file});
  return argv;
}

// Starts `argv` in `dir` in a process group of its own, its output into `screen`; returns its pid.
pid_t Spawn(const fs::path& dir, std::vector<std::string>& argv, const std::string& screen, int lock_fd) {
  const pid_t pid = fork();
  if (pid < 0) {
    close(lock_fd);
    throw std::runtime_error("cannot start mpirun (fork failed)");
  }
  if (pid == 0) {
    setpgid(0, 0);
    prctl(PR_SET_PDEATHSIG, SIGTERM);  // if `linerwatch dem` dies, LIGGGHTS stops (its restarts stay)
    if (chdir(dir.c_str()) != 0) _exit(126);
    const int fd = open(screen.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      dup2(fd, 1);
      dup2(fd, 2);
      close(fd);
    }
    if (geteuid() == 0) {  // Open MPI refuses root unless told; a container build runs as root
      setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
      setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
    }
    std::vector<char*> cargv;
    for (auto& a : argv) cargv.push_back(a.data());
    cargv.push_back(nullptr);
    execvp(cargv[0], cargv.data());
    std::fprintf(stderr, "cannot run %s\n", cargv[0]);
    _exit(127);
  }
  setpgid(pid, pid);
  return pid;
}

// One progress line from the mass series so far (none while it is empty).
void ReportProgress(const fs::path& dir, double total_s, double start_s, std::chrono::steady_clock::time_point t0,
                    std::chrono::steady_clock::time_point now, std::ostream& progress) {
  const auto series = ReadMassSeries(dir / CaseLayout::kMassSeries);
  if (series.empty()) return;
  const MassSample& s = series.back();
  double flow_tph = 0;  // discharged mass rate over the last ~2 simulated seconds
  for (size_t i = series.size(); i-- > 0;) {
    if (s.t - series[i].t >= 2.0 || (i == 0 && s.t > series[i].t)) {
      const double out_now = s.m_inserted - s.m_total, out_then = series[i].m_inserted - series[i].m_total;
      flow_tph = (out_now - out_then) / (s.t - series[i].t) * 3.6;
      break;
    }
  }
  const double wall = std::chrono::duration<double>(now - t0).count();
  const double done = s.t - start_s;
  const double eta = done > 0 ? wall / done * (total_s - s.t) : 0;
  char line[256];
  std::snprintf(line, sizeof line,
                "dem: %6.2f / %.2f s simulated (%3.0f %%), %6.0f particles in chamber (%.1f t), flow %6.0f t/h, "
                "elapsed %s, ETA %s\n",
                s.t, total_s, 100.0 * s.t / total_s, s.n, s.m_chamber / 1000.0, flow_tph, core::FormatDuration(wall).c_str(),
                done > 0 ? core::FormatDuration(eta).c_str() : "?");
  progress << line;
  progress.flush();
}

// Waits for LIGGGHTS to end, reporting progress, and stops it on RequestStop or at the deadline
// (r.out_of_time); returns its wait status.
int Wait(pid_t pid, const ChamberSpec& spec, const CaseSteps& steps, const fs::path& dir, const RunOptions& options,
         std::chrono::steady_clock::time_point t0, std::ostream& progress, RunResult& r) {
  const double total_s = static_cast<double>(steps.total) * spec.timestep_s;
  const double start_s = static_cast<double>(r.resumed_from_step) * spec.timestep_s;
  auto last_report = t0;
  bool stop_sent = false;
  int status = 0;
  for (;;) {
    const pid_t w = waitpid(pid, &status, WNOHANG);
    if (w == pid) break;
    const auto now = std::chrono::steady_clock::now();
    if ((g_stop || now >= options.deadline) && !stop_sent) {
      kill(-pid, SIGTERM);
      stop_sent = true;
      r.out_of_time = !g_stop;
      progress << "dem: stopping LIGGGHTS" << (r.out_of_time ? " at the wall-time budget" : "")
               << " (restart files kept; run again to resume)\n";
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    if (std::chrono::duration<double>(now - last_report).count() < options.progress_every_s) continue;
    last_report = now;
    ReportProgress(dir, total_s, start_s, t0, now, progress);
  }
  return status;
}

// Why the attempt ended before the last step, with where to look.
std::string StopMessage(const RunResult& r, int status, const fs::path& dir, const std::string& log, const std::string& screen) {
  std::ostringstream m;
  if (r.out_of_time)
    m << "LIGGGHTS was stopped at the wall-time budget";
  else if (WIFEXITED(status))
    m << "LIGGGHTS stopped with exit status " << WEXITSTATUS(status);
  else if (WIFSIGNALED(status))
    m << "LIGGGHTS was killed by signal " << WTERMSIG(status);
  m << " before the last step; see " << (dir / log).string() << " and " << (dir / screen).string()
    << "; run again to resume from the newest restart file";
  return m.str();
}

}  // namespace

std::vector<long> StepsInFolder(const fs::path& dir, const std::string& prefix, const std::string& suffix) {
  std::vector<long> steps;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return steps;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.size() <= prefix.size() + suffix.size() || name.rfind(prefix, 0) != 0 ||
        name.compare(name.size() - suffix.size(), suffix.size(), suffix) != 0)
      continue;
    const std::string mid = name.substr(prefix.size(), name.size() - prefix.size() - suffix.size());
    if (mid.empty() || mid.find_first_not_of("0123456789") != std::string::npos) continue;
    steps.push_back(std::stol(mid));
  }
  std::sort(steps.begin(), steps.end());
  return steps;
}

void RequestStop() {
  g_stop = true;
}

RunResult RunCase(const ChamberSpec& spec, const fs::path& dir, const RunOptions& options, std::ostream& progress) {
  g_stop = false;
  RunResult r;
  const CaseSteps steps = StepsOf(spec);
  const auto dumps = StepsInFolder(dir / CaseLayout::kDumpDir, "concave_", ".vtk");
  if (!dumps.empty() && dumps.back() >= steps.total) {
    r.completed = true;
    r.message = "already complete (" + std::to_string(dumps.size()) + " dumps up to step " + std::to_string(dumps.back()) + ")";
    progress << "dem: run " << r.message << "\n";
    return r;
  }
  if (options.np < 1) throw std::invalid_argument("--np must be at least 1");

  const Start start = ChooseStart(spec, dir, r);
  const int lock_fd = LockCase(dir);
  r.attempt = NextAttempt(dir);
  const std::string log = "log." + std::to_string(r.attempt) + ".liggghts";
  const std::string screen = "log." + std::to_string(r.attempt) + ".screen";
  progress << "dem: " << (r.resumed ? "resuming from " + start.restart_file : std::string("starting")) << " with "
           << options.mpirun << " -np " << options.np << " " << options.liggghts << " (log " << (dir / log).string() << ")\n";
  progress.flush();

  std::vector<std::string> argv = LiggghtsArgv(options, start, log);
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = Spawn(dir, argv, screen, lock_fd);
  const int status = Wait(pid, spec, steps, dir, options, t0, progress, r);
  close(lock_fd);
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto after = StepsInFolder(dir / CaseLayout::kDumpDir, "concave_", ".vtk");
  r.completed = !after.empty() && after.back() >= steps.total && WIFEXITED(status) && WEXITSTATUS(status) == 0;
  if (!r.completed) r.message = StopMessage(r, status, dir, log, screen);
  // Record the attempt for the map's summary (wall time per attempt).
  std::ofstream(dir / "attempts.txt", std::ios::app) << r.attempt << ' ' << r.resumed_from_step << ' ' << r.wall_s << ' '
                                                     << options.np << ' ' << (r.completed ? "completed" : "stopped") << '\n';
  return r;
}

}  // namespace lw::dem
