#pragma once
/// Runs a written case with `mpirun -np N liggghts`, resuming from the newest restart file when a
/// previous run was stopped, and reports progress (simulated seconds, particles in the chamber,
/// mass flow, ETA) while it runs. Each attempt keeps its own log (log.<n>.liggghts, log.<n>.screen).
#include <chrono>
#include <filesystem>
#include <ostream>
#include <string>
#include <vector>

#include "dem/chamber.hpp"

namespace lw::dem {

struct RunOptions {
  int np = 2;  ///< MPI ranks
  std::string mpirun = "mpirun";
  std::string liggghts = "liggghts";
  double progress_every_s = 10;  ///< wall seconds between progress lines
  /// LIGGGHTS is stopped (as by RequestStop) when this passes: a wall-time budget (--max-hours).
  std::chrono::steady_clock::time_point deadline = std::chrono::steady_clock::time_point::max();
};

struct RunResult {
  bool completed = false;  ///< the last dump (the run's final step) exists
  bool resumed = false;    ///< this call continued from a restart file
  long resumed_from_step = 0;
  int attempt = 0;  ///< number of this attempt (its log is log.<attempt>.liggghts)
  double wall_s = 0;
  std::string message;       ///< one line: why it stopped when not completed
  bool out_of_time = false;  ///< stopped at RunOptions::deadline
};

/// Step numbers of the files `<prefix><step><suffix>` in `dir`, ascending.
std::vector<long> StepsInFolder(const std::filesystem::path& dir, const std::string& prefix, const std::string& suffix);

/// Asks a running RunCase to stop (async-signal-safe: call it from a SIGINT/SIGTERM handler).
/// LIGGGHTS is sent SIGTERM, the restart files already written stay, and the next RunCase resumes.
void RequestStop();

/// Runs (or resumes, or, when already complete, does nothing for) the case in `dir`.
RunResult RunCase(const ChamberSpec& spec, const std::filesystem::path& dir, const RunOptions& options, std::ostream& progress);

}  // namespace lw::dem
