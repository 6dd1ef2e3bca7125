#pragma once
/// Runs `linerwatch diagnose` (the lw::diagnosis library) in the background on a crusher's stored
/// readings, with its map, operations.csv and scans/ from the crusher folder. One run per crusher
/// at a time; the result is kept in the database.
///
/// Threads: Start() and StatusJson() may be called from any thread, several at once (the HTTP
/// workers). Each run has a thread of its own, started by Start() and joined by a later Start() or
/// the destructor; it reads and saves through the LockedStore given, so a run and the status
/// requests never use the store at the same time.
#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "server/registry.hpp"
#include "server/store.hpp"

namespace lw::server {

class DiagnosisRunner {
 public:
  /// `store` (the diagnosis's own connection: a run reads every reading of a crusher) outlives this.
  DiagnosisRunner(const Registry& registry, LockedStore& store);
  ~DiagnosisRunner();  ///< waits for running diagnoses
  /// Starts a run; false when one is already running for that crusher.
  bool Start(const std::string& crusher);
  /// {"status": "none"|"running"|"done"|"failed", "time", "result", "error"}.
  std::string StatusJson(const std::string& crusher);

 private:
  /// What this process knows of a crusher's runs (the database holds the latest result).
  enum class RunState {
    kIdle,  ///< none started since the server started, or the last one succeeded
    kRunning,
    kFailed,  ///< the last run failed (RunStatus::error says why)
  };
  struct RunStatus {
    RunState state = RunState::kIdle;
    std::string error;  ///< kFailed only
  };

  void Run(const std::string& crusher);
  const Registry& registry_;
  LockedStore& store_;
  std::mutex mutex_;
  std::map<std::string, RunStatus> runs_;  ///< per crusher; guarded by mutex_
  struct Job {
    std::thread thread;
    std::shared_ptr<std::atomic<bool>> done;
  };
  std::vector<Job> jobs_;  ///< guarded by mutex_
};

}  // namespace lw::server
