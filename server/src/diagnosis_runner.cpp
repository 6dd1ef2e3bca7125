#include "server/diagnosis_runner.hpp"

#include <nlohmann/json.hpp>

#include "core/time.hpp"
#include "diagnosis/diagnose.hpp"

namespace lw::server {

DiagnosisRunner::DiagnosisRunner(const Registry& registry, LockedStore& store) : registry_(registry), store_(store) {}

DiagnosisRunner::~DiagnosisRunner() {
  for (auto& j : jobs_) {
    if (j.thread.joinable()) j.thread.join();
  }
}

bool DiagnosisRunner::Start(const std::string& crusher) {
  std::lock_guard<std::mutex> lock(mutex_);
  RunStatus& run = runs_[crusher];
  if (run.state == RunState::kRunning) return false;
  run = {RunState::kRunning, ""};
  // Reap finished runs so their threads do not pile up over months.
  for (auto it = jobs_.begin(); it != jobs_.end();) {
    if (*it->done) {
      it->thread.join();
      it = jobs_.erase(it);
    } else {
      ++it;
    }
  }
  auto done = std::make_shared<std::atomic<bool>>(false);
  jobs_.push_back({std::thread([this, crusher, done] {
                     Run(crusher);
                     *done = true;
                   }),
                   done});
  return true;
}

void DiagnosisRunner::Run(const std::string& crusher_id) {
  bool failed = false;
  std::string error;
  try {
    const Crusher* c = registry_.Find(crusher_id);
    if (!c) throw std::runtime_error("unknown crusher");
    core::Bundle b;
    b.dir = c->dir;
    b.crusher = c->config;
    b.map = c->map;
    b.map_validation = c->validation;
    const std::vector<StoredReading> stored = store_.With([&](Store& s) { return s.All(crusher_id); });
    for (const StoredReading& r : stored) {
      core::Reading x;
      x.time = core::FromUnixSeconds(r.time_s);
      x.sensor_id = r.sensor;
      x.thickness_mm = r.thickness_mm;
      b.readings.push_back(std::move(x));
    }
    if (std::filesystem::exists(c->dir / "operations.csv")) b.operations = core::LoadOperations(c->dir / "operations.csv");
    b.scans = core::LoadScans(c->dir);
    const auto result = diagnosis::Diagnose(b);
    const auto now = std::chrono::floor<std::chrono::seconds>(std::chrono::system_clock::now());
    const std::string json = diagnosis::ToJson(result).dump();
    store_.With([&](Store& s) { s.SaveDiagnosis(crusher_id, now.time_since_epoch().count(), json); });
  } catch (const std::exception& e) {
    failed = true;
    error = e.what();
  }
  std::lock_guard<std::mutex> lock(mutex_);
  runs_[crusher_id] = failed ? RunStatus{RunState::kFailed, error} : RunStatus{};
}

std::string DiagnosisRunner::StatusJson(const std::string& crusher) {
  nlohmann::ordered_json j;
  RunStatus run;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (const auto it = runs_.find(crusher); it != runs_.end()) run = it->second;
  }
  const std::optional<std::pair<int64_t, std::string>> latest = store_.With([&](Store& s) { return s.LatestDiagnosis(crusher); });
  switch (run.state) {
    case RunState::kRunning:
      j["status"] = "running";
      break;
    case RunState::kFailed:
      j["status"] = "failed";
      break;
    case RunState::kIdle:
      j["status"] = latest ? "done" : "none";
      break;
  }
  j["time"] = latest ? nlohmann::ordered_json(core::FormatIsoSeconds(latest->first)) : nlohmann::ordered_json(nullptr);
  j["result"] = latest ? nlohmann::ordered_json::parse(latest->second) : nlohmann::ordered_json(nullptr);
  if (run.state == RunState::kFailed) j["error"] = run.error;
  return j.dump();
}

}  // namespace lw::server
