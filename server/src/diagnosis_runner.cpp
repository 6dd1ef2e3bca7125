#include "server/diagnosis_runner.hpp"

#include <nlohmann/json.hpp>

#include "core/time.hpp"
#include "diagnosis/diagnose.hpp"

namespace lw::server {

DiagnosisRunner::DiagnosisRunner(const Registry& registry, Store& read, std::mutex& read_mutex)
    : registry_(registry), read_(read), read_mutex_(read_mutex) {}

DiagnosisRunner::~DiagnosisRunner() {
  for (auto& j : jobs_) {
    if (j.thread.joinable()) j.thread.join();
  }
}

bool DiagnosisRunner::Start(const std::string& crusher) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (state_[crusher] == "running") return false;
  state_[crusher] = "running";
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
  std::string error;
  try {
    const Crusher* c = registry_.Find(crusher_id);
    if (!c) throw std::runtime_error("unknown crusher");
    core::Bundle b;
    b.dir = c->dir;
    b.crusher = c->config;
    b.map = c->map;
    b.map_validation = c->validation;
    std::vector<StoredReading> stored;
    {
      std::lock_guard<std::mutex> rl(read_mutex_);
      stored = read_.All(crusher_id);
    }
    for (const StoredReading& r : stored) {
      core::Reading x;
      x.time = core::TimePoint(std::chrono::seconds(r.time_s));
      x.sensor_id = r.sensor;
      x.thickness_mm = r.thickness_mm;
      b.readings.push_back(std::move(x));
    }
    if (std::filesystem::exists(c->dir / "operations.csv")) b.operations = core::LoadOperations(c->dir / "operations.csv");
    b.scans = core::LoadScans(c->dir);
    const auto result = diagnosis::Diagnose(b);
    const auto now = std::chrono::floor<std::chrono::seconds>(std::chrono::system_clock::now());
    std::lock_guard<std::mutex> rl(read_mutex_);
    read_.SaveDiagnosis(crusher_id, now.time_since_epoch().count(), diagnosis::ToJson(result).dump());
  } catch (const std::exception& e) {
    error = e.what();
  }
  std::lock_guard<std::mutex> lock(mutex_);
  state_[crusher_id] = error.empty() ? "" : "failed: " + error;
}

std::string DiagnosisRunner::StatusJson(const std::string& crusher) {
  nlohmann::ordered_json j;
  std::string state;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    state = state_[crusher];
  }
  std::optional<std::pair<int64_t, std::string>> latest;
  {
    std::lock_guard<std::mutex> rl(read_mutex_);
    latest = read_.LatestDiagnosis(crusher);
  }
  if (state == "running") j["status"] = "running";
  else if (state.rfind("failed: ", 0) == 0) j["status"] = "failed";
  else j["status"] = latest ? "done" : "none";
  j["time"] = latest ? nlohmann::ordered_json(core::FormatIsoTime(core::TimePoint(std::chrono::seconds(latest->first))))
                     : nlohmann::ordered_json(nullptr);
  j["result"] = latest ? nlohmann::ordered_json::parse(latest->second) : nlohmann::ordered_json(nullptr);
  if (state.rfind("failed: ", 0) == 0) j["error"] = state.substr(8);
  return j.dump();
}

}  // namespace lw::server
