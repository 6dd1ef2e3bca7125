#pragma once
/// The crushers this server knows: one sub-folder of --crusher-dir per crusher, with crusher.json
/// (docs/bundle.md) and its DEM wear map (wear_map.vtk, or wear_map.csv as an EDEM-style per-face
/// export). Maps are validated and hashed on import; the reconstruction plan is prepared once.
/// Laser scans in the folder's scans/ (scan_YYYY-MM-DD.xyz, docs/bundle.md) are projected onto the
/// map's faces once, at load; live wear applies the latest one (docs/server.md).
#include <filesystem>
#include <future>
#include <map>
#include <nlohmann/json.hpp>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "core/bundle.hpp"
#include "core/reconstruction.hpp"
#include "core/wear_map.hpp"
#include "estimate/model.hpp"

namespace lw::server {

/// A crusher the server knows: its estimate model (config, map, map model, scans; estimate/model.hpp)
/// and what the server shows of its folder.
struct Crusher : estimate::CrusherModel {
  std::filesystem::path dir;
  core::MapValidation validation;
  /// dem_summary.json of the folder when the map was made by `linerwatch dem` (docs/dem.md): its
  /// validation summary, shown by GET /api/v1/crushers/{c}; null when absent.
  nlohmann::json dem_summary;
};

class Registry {
 public:
  /// Loads every sub-folder of `dir` holding a crusher.json. A folder that fails to load is skipped
  /// and its one-line reason appended to `errors`. Throws std::runtime_error when `dir` is not a
  /// readable folder.
  static std::unique_ptr<Registry> Load(const std::filesystem::path& dir, std::vector<std::string>* errors);

  /// Map models already built, by the map file's SHA-256 (all with the same options). Shared by the
  /// threads that load folders at once: each model is built once, by the first folder that needs
  /// it; the others wait for it (and get its error, if it failed).
  class MapModels {
   public:
    const core::MapModel& Get(const core::WearMap& map, const core::MapModelOptions& options);
    size_t size() const {
      std::lock_guard<std::mutex> lock(mutex_);
      return models_.size();
    }

   private:
    mutable std::mutex mutex_;
    std::map<std::string, std::shared_future<core::MapModel>> models_;
  };
  /// Loads one crusher folder. Throws core::InputError / std::runtime_error naming file and rule.
  /// With `models`, a map whose file is byte for byte one already modelled (a fleet of one crusher
  /// model shares its DEM map) reuses that model instead of smoothing it again; new ones are added.
  static std::unique_ptr<Crusher> LoadCrusher(const std::filesystem::path& folder,
                                              const core::ReconstructionOptions& options = {}, MapModels* models = nullptr);

  const Crusher* Find(const std::string& crusher_id) const;
  std::vector<const Crusher*> All() const;
  void Add(std::unique_ptr<Crusher> crusher);

 private:
  std::map<std::string, std::unique_ptr<Crusher>> crushers_;
};

}  // namespace lw::server
