#pragma once
/// The crushers this server knows: one sub-folder of --crusher-dir per crusher, with crusher.json
/// (docs/bundle.md) and its DEM wear map (wear_map.vtk, or wear_map.csv as an EDEM-style per-face
/// export). Maps are validated and hashed on import; the reconstruction plan is prepared once.
/// Laser scans in the folder's scans/ (scan_YYYY-MM-DD.xyz, docs/bundle.md) are projected onto the
/// map's faces once, at load; live wear applies the latest one (docs/server.md).
#include <atomic>
#include <filesystem>
#include <future>
#include <map>
#include <nlohmann/json.hpp>
#include <memory>
#include <optional>
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

  /// `base`'s crusher for another liner campaign (a reline, docs/campaigns.md): `config` (the folder's
  /// with the campaign's installed_at, thickness and sensors) over base's map and map model, with
  /// only base's scans dated from the campaign's start on (an older scan is a previous liner's).
  /// Throws core::InputError naming "sensors" when a sensor lies off the map.
  /// The previous liner's end-of-life scan (`prior_scan_xyz`, the reline's `scan_xyz`; empty: none)
  /// becomes the new campaign's prior for the wear pattern (docs/wear.md, *Earlier campaigns*); without
  /// one, the latest of base's scans of the previous campaign (dated from `previous_start`, before
  /// this campaign's start) does.
  static std::unique_ptr<Crusher> ForCampaign(const Crusher& base, core::CrusherConfig config,
                                              const std::string& prior_scan_xyz = "",
                                              std::optional<core::TimePoint> previous_start = std::nullopt);

  /// The crusher's current model: a pointer that stays valid for the registry's lifetime (a model
  /// replaced by Replace() is kept, not freed). Safe to call while another thread calls Replace().
  const Crusher* Find(const std::string& crusher_id) const;
  /// The model loaded from the crusher's folder (its first, before any campaign replaced it): the
  /// base of a campaign's model. Throws std::out_of_range for an unknown id.
  const Crusher& Folder(const std::string& crusher_id);
  std::vector<const Crusher*> All() const;
  /// Before the registry is shared: a new crusher.
  void Add(std::unique_ptr<Crusher> crusher);
  /// Makes `crusher` the current model of its (known) crusher_id; the one it replaces stays alive, so
  /// pointers handed out before (a wear state computed on it) stay valid. Relines are rare: what
  /// the kept models cost is a map copy per reline. Throws std::out_of_range for an unknown id.
  void Replace(std::unique_ptr<Crusher> crusher);
  /// Makes the folder's model (Folder()) the current one again: every reline of the crusher voided.
  void Restore(const std::string& crusher_id);

 private:
  struct Slot {
    std::atomic<const Crusher*> current{nullptr};
    std::vector<std::unique_ptr<Crusher>> models;  ///< every model it had, the current last (guarded by models_mutex_)
  };
  std::map<std::string, std::unique_ptr<Slot>> crushers_;  ///< fixed once shared: only a slot's current changes
  std::mutex models_mutex_;
};

}  // namespace lw::server
