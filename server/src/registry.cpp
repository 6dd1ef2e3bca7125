#include "server/registry.hpp"

#include <algorithm>
#include <atomic>
#include <fstream>
#include <future>
#include <stdexcept>
#include <thread>

namespace lw::server {

const core::MapModel& Registry::MapModels::Get(const core::WearMap& map, const core::MapModelOptions& options) {
  std::unique_lock<std::mutex> lock(mutex_);
  const auto it = models_.find(map.sha256);
  if (it != models_.end()) {
    const std::shared_future<core::MapModel> ready = it->second;
    lock.unlock();
    return ready.get();  // waits while another thread builds it; rethrows its error
  }
  std::promise<core::MapModel> promise;
  const std::shared_future<core::MapModel> future = promise.get_future().share();
  models_.emplace(map.sha256, future);
  lock.unlock();
  try {
    promise.set_value(core::BuildMapModel(map, options));
  } catch (...) {
    promise.set_exception(std::current_exception());
  }
  return future.get();
}

std::unique_ptr<Crusher> Registry::LoadCrusher(const std::filesystem::path& folder, const core::ReconstructionOptions& options,
                                               MapModels* models) {
  auto c = std::make_unique<Crusher>();
  c->dir = folder;
  c->config = core::LoadCrusherConfig(folder / "crusher.json");
  std::filesystem::path map_path = folder / "wear_map.vtk";
  if (!std::filesystem::exists(map_path) && std::filesystem::exists(folder / "wear_map.csv")) map_path = folder / "wear_map.csv";
  if (!std::filesystem::exists(map_path)) {
    throw core::InputError("wear_map.vtk", 0, "missing in " + folder.string() + " (a crusher folder needs its DEM wear map)");
  }
  c->map = core::LoadWearMap(map_path, &c->validation);
  core::CheckCrusherAgainstMap(c->config, c->map, "crusher.json");
  if (!models) {
    c->plan = core::PrepareReconstruction(c->config, c->map, options);
  } else {
    c->plan = core::PrepareReconstruction(c->config, c->map, models->Get(c->map, options.map_model), options);
  }
  const auto summary_path = folder / "dem_summary.json";
  if (std::filesystem::exists(summary_path)) {
    std::ifstream in(summary_path);
    try {
      c->dem_summary = nlohmann::json::parse(in);
      if (!c->dem_summary.is_object()) throw std::runtime_error("not a JSON object");
    } catch (const std::exception& e) {  // the map itself is fine: say so and go on without it
      c->dem_summary = nullptr;
      c->validation.warnings.push_back("dem_summary.json ignored: " + std::string(e.what()));
    }
  }
  // Laser scans: each projected onto the map once. A scan that does not load is a warning (live wear
  // goes on from the map and the sensors); one mostly off the map is applied where it covers.
  if (std::filesystem::is_directory(folder / "scans")) {
    std::optional<core::Scan> previous;
    std::vector<std::filesystem::path> files;
    for (const auto& e : std::filesystem::directory_iterator(folder / "scans"))
      if (e.path().extension() == ".xyz") files.push_back(e.path());
    std::sort(files.begin(), files.end());
    for (const auto& f : files) {
      try {
        estimate::ModelScan s;
        s.scan = core::LoadScan(f);
        s.faces = core::ProjectScanToFaces(c->map, s.scan);
        if (s.faces.points_used < s.faces.points_total / 2) {
          c->validation.warnings.push_back(s.scan.file + ": only " + std::to_string(s.faces.points_used) + " of " +
                                           std::to_string(s.faces.points_total) + " points lie on the mapped surface");
        }
        if (s.scan.date < c->config.installed_at) {
          // A previous liner's scan (files sort by date: the last is the latest): the prior.
          previous = std::move(s.scan);
          continue;
        }
        s.scan.points.clear();
        s.scan.points.shrink_to_fit();
        c->scans.push_back(std::move(s));
      } catch (const core::InputError& e) {  // names the file, the line and the rule
        c->validation.warnings.push_back(std::string(e.what()) + " (scan ignored)");
      } catch (const std::exception& e) {
        c->validation.warnings.push_back("scans/" + f.filename().string() + ": " + e.what() + " (scan ignored)");
      }
    }
    c->SortScans();
    if (previous && !c->SetPrior("before " + core::FormatIsoTime(c->config.installed_at), *previous, previous->file))
      c->validation.warnings.push_back(previous->file + " reaches none of the sensors: not used as the prior");
  }
  return c;
}

std::unique_ptr<Registry> Registry::Load(const std::filesystem::path& dir, std::vector<std::string>* errors) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) throw std::runtime_error("--crusher-dir '" + dir.string() + "' is not a folder");
  auto reg = std::make_unique<Registry>();
  std::vector<std::filesystem::path> folders;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    if (entry.is_directory() && std::filesystem::exists(entry.path() / "crusher.json")) folders.push_back(entry.path());
  }
  if (ec) throw std::runtime_error("--crusher-dir '" + dir.string() + "': " + ec.message());
  std::sort(folders.begin(), folders.end());
  // Folders load on every core at once (a fleet's hundred map files parse in parallel); identical
  // maps are still smoothed once. Results are taken in folder order, so which of two folders with
  // the same crusher_id is refused does not depend on the threads.
  MapModels models;
  std::vector<std::unique_ptr<Crusher>> loaded(folders.size());
  std::vector<std::string> failed(folders.size());
  std::atomic<size_t> next{0};
  const auto work = [&] {
    for (size_t i = next++; i < folders.size(); i = next++) {
      try {
        loaded[i] = LoadCrusher(folders[i], {}, &models);
      } catch (const std::exception& e) {
        failed[i] = e.what();
      }
    }
  };
  const size_t threads = std::min<size_t>(folders.size(), std::max(1u, std::thread::hardware_concurrency()));
  std::vector<std::thread> pool;
  for (size_t t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
  for (size_t i = 0; i < folders.size(); ++i) {
    if (loaded[i] && reg->Find(loaded[i]->config.crusher_id)) {
      failed[i] = "crusher_id '" + loaded[i]->config.crusher_id + "' is already used by another folder";
      loaded[i].reset();
    }
    if (loaded[i]) {
      reg->Add(std::move(loaded[i]));
    } else if (errors) {
      errors->push_back(folders[i].string() + ": " + failed[i]);
    }
  }
  return reg;
}

std::unique_ptr<Crusher> Registry::ForCampaign(const Crusher& base, core::CrusherConfig config, const std::string& prior_scan_xyz,
                                               std::optional<core::TimePoint> previous_start) {
  auto c = std::make_unique<Crusher>();
  c->dir = base.dir;
  c->validation = base.validation;
  c->dem_summary = base.dem_summary;
  c->config = std::move(config);
  c->map = base.map;
  core::CheckCrusherAgainstMap(c->config, c->map, "sensors");
  c->plan = core::PrepareReconstruction(c->config, c->map, base.plan.model, base.plan.options);
  for (const estimate::ModelScan& s : base.scans)
    if (s.scan.date >= c->config.installed_at) c->scans.push_back(s);
  const std::string previous = "before " + core::FormatIsoTime(c->config.installed_at);
  if (!prior_scan_xyz.empty()) {
    core::Scan scan;
    scan.date = c->config.installed_at;
    scan.points = core::ParseScanPoints(prior_scan_xyz, "scan_xyz");
    if (!c->SetPrior(previous, scan, "the reline's end-of-life scan (" + core::FormatIsoTime(scan.date) + ")"))
      c->validation.warnings.push_back("the reline's end-of-life scan reaches none of the sensors: not used as the prior");
  } else {
    // The latest scan in scans/ of an earlier liner (its points are gone: loaded again from its file).
    const estimate::ModelScan* last = nullptr;
    for (const estimate::ModelScan& s : base.scans)
      if (s.scan.date < c->config.installed_at && (!previous_start || s.scan.date >= *previous_start)) last = &s;
    if (last) {
      try {
        // ModelScan::scan.file is "scans/NAME", relative to the crusher folder.
        if (!c->SetPrior(previous, core::LoadScan(base.dir / last->scan.file), last->scan.file))
          c->validation.warnings.push_back(last->scan.file + " reaches none of the sensors: not used as the prior");
      } catch (const std::exception& e) {
        c->validation.warnings.push_back(last->scan.file + ": " + e.what() + " (not used as the prior)");
      }
    }
  }
  return c;
}

const Crusher* Registry::Find(const std::string& crusher_id) const {
  const auto it = crushers_.find(crusher_id);
  return it == crushers_.end() ? nullptr : it->second->current.load();
}

std::vector<const Crusher*> Registry::All() const {
  std::vector<const Crusher*> out;
  for (const auto& [id, slot] : crushers_) out.push_back(slot->current.load());
  return out;
}

void Registry::Add(std::unique_ptr<Crusher> crusher) {
  auto slot = std::make_unique<Slot>();
  slot->current = crusher.get();
  slot->models.push_back(std::move(crusher));
  crushers_[slot->current.load()->config.crusher_id] = std::move(slot);
}

const Crusher& Registry::Folder(const std::string& crusher_id) {
  Slot& slot = *crushers_.at(crusher_id);
  std::lock_guard<std::mutex> lock(models_mutex_);
  return *slot.models.front();
}

void Registry::Restore(const std::string& crusher_id) {
  Slot& slot = *crushers_.at(crusher_id);
  std::lock_guard<std::mutex> lock(models_mutex_);
  slot.current = slot.models.front().get();
}

void Registry::Replace(std::unique_ptr<Crusher> crusher) {
  Slot& slot = *crushers_.at(crusher->config.crusher_id);
  std::lock_guard<std::mutex> lock(models_mutex_);
  slot.current = crusher.get();
  slot.models.push_back(std::move(crusher));
}

}  // namespace lw::server
