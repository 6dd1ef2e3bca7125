#pragma once
/// The per-crusher model live wear is estimated on: what does not depend on the readings. The
/// crusher's configuration, its DEM wear map with the map model (the reconstruction plan, built
/// once: smoothing is the expensive part) and its laser scans projected onto the map's faces. Made
/// once (from a crusher folder by the server's registry, from a bundle by `linerwatch reconstruct`
/// and the diagnosis) and read-only after: the plan points into config and map, so a model never
/// moves (held by pointer).
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "core/bundle.hpp"
#include "core/map_model.hpp"
#include "core/reconstruction.hpp"
#include "core/scan_correction.hpp"
#include "core/wear_map.hpp"

namespace lw::estimate {

/// A laser scan of the crusher projected onto its map (the points themselves are not kept).
struct ModelScan {
  core::Scan scan;  ///< file and date; points emptied after projection
  core::ScanFaces faces;
};

/// The crusher's plan corrected by one scan (core::ApplyScan), for the sensors' wear at its date.
struct ScannedPlan {
  size_t scan = 0;                             ///< index into CrusherModel::scans
  std::vector<core::SensorWear> wear_at_scan;  ///< what the correction was computed from
  core::ReconstructionPlan plan;
  core::ScanCorrection correction;
};

struct CrusherModel {
  core::CrusherConfig config;
  core::WearMap map;
  core::ReconstructionPlan plan;  ///< points into config and map
  std::vector<ModelScan> scans;   ///< sorted by date

  CrusherModel() = default;
  CrusherModel(const CrusherModel&) = delete;
  CrusherModel& operator=(const CrusherModel&) = delete;

  /// A bundle's crusher, map and scans (each scan projected once), with the map model built here
  /// or given (the diagnosis builds one per bundle).
  static std::unique_ptr<CrusherModel> FromBundle(const core::Bundle& bundle, const core::ReconstructionOptions& options = {});
  static std::unique_ptr<CrusherModel> FromBundle(const core::Bundle& bundle, core::MapModel model,
                                                  const core::ReconstructionOptions& options = {});
  /// Sorts `scans` by date (stable: of two scans of one date the later loaded wins, as
  /// core::LatestScanAt picks).
  void SortScans();

  /// The plan live wear at `at` applies: `plan` corrected by the latest scan at or before `at`, with
  /// the sensors' wear at the scan's date from `readings` (usable readings only; of the sensors stuck
  /// now, `stuck`, those whose value had already frozen then too: core::ScanSensorWear); nullptr
  /// when there is no such scan (then `plan` applies). Remembered: recomputed only when the scan or
  /// the sensors' wear at its date changed. Thread-safe.
  std::shared_ptr<const ScannedPlan> PlanWithScan(const std::vector<core::Reading>& readings, core::TimePoint at,
                                                  const std::vector<std::string>& stuck = {}, bool interval_centre = true) const;

 private:
  mutable std::mutex scan_mutex_;
  mutable std::shared_ptr<const ScannedPlan> scanned_;  ///< the last one computed (a cache, not state)
};

}  // namespace lw::estimate
