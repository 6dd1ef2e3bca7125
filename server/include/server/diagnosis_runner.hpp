#pragma once
/// Runs `linerwatch diagnose` (the lw::diagnosis library) in the background on a crusher's stored
/// readings, with its map, operations.csv and scans/ from the crusher folder. One run per crusher
/// at a time; the result is kept in the database.
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
  DiagnosisRunner(const Registry& registry, Store& read, std::mutex& read_mutex);
  ~DiagnosisRunner();  ///< waits for running diagnoses
  /// Starts a run; false when one is already running for that crusher.
  bool Start(const std::string& crusher);
  /// {"status": "none"|"running"|"done"|"failed", "time", "result", "error"}.
  std::string StatusJson(const std::string& crusher);

 private:
  void Run(const std::string& crusher);
  const Registry& registry_;
  Store& read_;
  std::mutex& read_mutex_;
  std::mutex mutex_;
  std::map<std::string, std::string> state_;  ///< "running" / "failed: ..." per crusher
  struct Job {
    std::thread thread;
    std::shared_ptr<std::atomic<bool>> done;
  };
  std::vector<Job> jobs_;
};

}  // namespace lw::server
