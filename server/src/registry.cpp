#include "server/registry.hpp"

#include <algorithm>
#include <fstream>
#include <stdexcept>

namespace lw::server {

std::unique_ptr<Crusher> Registry::LoadCrusher(const std::filesystem::path& folder, const core::ReconstructionOptions& options) {
  auto c = std::make_unique<Crusher>();
  c->dir = folder;
  c->config = core::LoadCrusherConfig(folder / "crusher.json");
  std::filesystem::path map_path = folder / "wear_map.vtk";
  if (!std::filesystem::exists(map_path) && std::filesystem::exists(folder / "wear_map.csv")) map_path = folder / "wear_map.csv";
  if (!std::filesystem::exists(map_path)) {
    throw core::InputError("wear_map.vtk", 0, "missing in " + folder.string() + " (a crusher folder needs its DEM wear map)");
  }
  c->map = core::LoadWearMap(map_path, &c->validation);
  c->plan = core::PrepareReconstruction(c->config, c->map, options);
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
  for (const auto& folder : folders) {
    try {
      auto c = LoadCrusher(folder);
      if (reg->Find(c->config.crusher_id)) {
        throw std::runtime_error("crusher_id '" + c->config.crusher_id + "' is already used by another folder");
      }
      reg->Add(std::move(c));
    } catch (const std::exception& e) {
      if (errors) errors->push_back(folder.string() + ": " + e.what());
    }
  }
  return reg;
}

const Crusher* Registry::Find(const std::string& crusher_id) const {
  const auto it = crushers_.find(crusher_id);
  return it == crushers_.end() ? nullptr : it->second.get();
}

std::vector<const Crusher*> Registry::All() const {
  std::vector<const Crusher*> out;
  for (const auto& [id, c] : crushers_) out.push_back(c.get());
  return out;
}

void Registry::Add(std::unique_ptr<Crusher> crusher) {
  const std::string id = crusher->config.crusher_id;
  crushers_[id] = std::move(crusher);
}

}  // namespace lw::server
