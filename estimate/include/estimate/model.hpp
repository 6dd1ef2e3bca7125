#pragma once
/// The per-crusher model live wear is estimated on: what does not depend on the readings. The
/// crusher's configuration, its DEM wear map with the map model (the reconstruction plan, built
/// once: smoothing is the expensive part) and its laser scans projected onto the map's faces. Made
/// once (from a crusher folder by the server's registry, from a bundle by `linerwatch reconstruct`
/// and the diagnosis) and read-only after: the plan points into config and map, so a model never
/// moves (held by pointer).
#include <memory>
#include <mutex>
#include <optional>
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

/// An earlier campaign's end-of-life scan, this liner's prior for the wear pattern until it has a
/// scan of its own: the scan's wear at each of this liner's sensor positions stands in for the
/// sensors' wear at its date, so each row's pattern is the scan's divided by its row's scale
/// whatever sensors the old liner had (docs/wear.md, *Earlier campaigns*).
struct PriorScan {
  std::string campaign;                           ///< the history folder's name
  ModelScan scan;                                 ///< its file is history/NAME/scans/FILE
  std::vector<core::SensorWear> wear_at_sensors;  ///< the scan's wear at this liner's sensors (those it covers)
};

/// How this liner's sensors agree with the prior's pattern: within each row the sensors' wear over
/// the prior's wear at them is one number when the pattern held; its spread beyond the readings'
/// own noise is the pattern's change between campaigns (relative), shrunk towards kPriorChange0 by
/// kPriorDof0 degrees of freedom while few sensors have worn enough to tell.
struct PriorCheck {
  static constexpr double kPriorChange0 = 0.2;  ///< assumed relative change before the sensors say
  static constexpr double kPriorDof0 = 2;
  static constexpr double kMinWearMm = 5;  ///< a sensor below this has not worn enough to compare patterns
  double change_rel = kPriorChange0;       ///< the prior's relative error per face used: its weight
  double spread_prior_rel = 0;             ///< the sensors' spread around the prior's pattern, beyond noise (NaN: none measured)
  double spread_map_rel = 0;               ///< the same around the DEM map's pattern, for comparison
  size_t sensors = 0;                      ///< sensors compared (in rows with two or more)
  double dof = 0;                          ///< their degrees of freedom (sensors less one per row)
};

/// The crusher's plan corrected by one scan (core::ApplyScan), for the sensors' wear at its date.
struct ScannedPlan {
  size_t scan = 0;                             ///< index into CrusherModel::scans (unused for the prior)
  std::optional<PriorCheck> prior;             ///< set when the scan is CrusherModel::prior's
  std::vector<core::SensorWear> wear_at_scan;  ///< what the correction was computed from
  core::ReconstructionPlan plan;
  core::ScanCorrection correction;
};

struct CrusherModel {
  core::CrusherConfig config;
  core::WearMap map;
  core::ReconstructionPlan plan;   ///< points into config and map
  std::vector<ModelScan> scans;    ///< sorted by date
  std::optional<PriorScan> prior;  ///< the latest earlier campaign's latest scan (bundle history/)

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
  /// An earlier campaign's scan (`scan`, its points; shown as `file`) as the prior, projected on the
  /// map and read at this liner's sensors: after the plan is prepared and the sensors set. False
  /// (no prior) when the scan reaches none of the sensors' positions.
  bool SetPrior(const std::string& campaign, const core::Scan& scan, const std::string& file);

  /// The scan `p` was corrected by: one of `scans`, or the prior's.
  const ModelScan& ScanOf(const ScannedPlan& p) const { return p.prior ? prior->scan : scans[p.scan]; }

  /// Without a scan of this liner at or before `at`, the prior (when there is one) corrects the
  /// plan, its faces' error widened by the pattern change the sensors show (PriorCheck).
  std::shared_ptr<const ScannedPlan> PlanWithScan(const std::vector<core::Reading>& readings, core::TimePoint at,
                                                  const std::vector<std::string>& stuck = {}, bool interval_centre = true) const;

 private:
  std::shared_ptr<const ScannedPlan> PlanWithPrior(const std::vector<core::Reading>& readings, core::TimePoint at,
                                                   const std::vector<std::string>& stuck, bool interval_centre) const;
  mutable std::mutex scan_mutex_;
  mutable std::shared_ptr<const ScannedPlan> scanned_;  ///< the last one computed (a cache, not state)
};

}  // namespace lw::estimate
