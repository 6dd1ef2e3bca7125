#pragma once
/// The crushers this server knows: one sub-folder of --crusher-dir per crusher, with crusher.json
/// (docs/bundle.md) and its DEM wear map (wear_map.vtk, or wear_map.csv as an EDEM-style per-face
/// export). Maps are validated and hashed on import; the reconstruction plan is prepared once.
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <memory>
#include <string>
#include <vector>

#include "core/bundle.hpp"
#include "core/reconstruction.hpp"
#include "core/wear_map.hpp"

namespace lw::server {

struct Crusher {
  std::filesystem::path dir;
  core::CrusherConfig config;
  core::WearMap map;
  core::MapValidation validation;
  core::ReconstructionPlan plan;  ///< points into config and map (a Crusher never moves)
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

  /// Loads one crusher folder. Throws core::InputError / std::runtime_error naming file and rule.
  static std::unique_ptr<Crusher> LoadCrusher(const std::filesystem::path& folder,
                                              const core::ReconstructionOptions& options = {});

  const Crusher* Find(const std::string& crusher_id) const;
  std::vector<const Crusher*> All() const;
  void Add(std::unique_ptr<Crusher> crusher);

 private:
  std::map<std::string, std::unique_ptr<Crusher>> crushers_;
};

}  // namespace lw::server
