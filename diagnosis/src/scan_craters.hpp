#pragma once
/// Material loss read from a scan's shape (docs/diagnosis.md, "Material loss in a scan"): a spall
/// is a compact, sharp-edged depression a few cm deep, which no smooth wear pattern makes. Each
/// scanned face's wear is compared with a robust local background from a ring of its neighbours;
/// a compact connected patch far deeper than the scan's own face-to-face noise, whose edge is a
/// step much larger than the change just outside it, is a crater. Distances are on the unwrapped
/// surface in metres (the mesh's own coordinates and areas), so the rules carry across meshes.
#include <string>
#include <vector>

#include "core/bundle.hpp"
#include "diagnosis/diagnose.hpp"
#include "fields.hpp"
#include "stage_setup.hpp"

namespace lw::diagnosis::detail {

/// The thresholds, with why (docs/diagnosis.md lists them for users).
struct CraterRules {
  /// The background ring, m: outside a spall's own radius (0.1 m^2 is a disc of 0.18 m) and near
  /// enough that the wear pattern is about quadratic across it. Widened to 2 and 4 face sizes on
  /// meshes too coarse for it.
  double ring_inner_m = 0.25;
  double ring_outer_m = 0.45;
  /// A patch's seed faces lie this many noise sd (the scan's robust face-to-face residual scatter)
  /// above the background, and at least `min_depth_mm`; the patch grows over neighbours above half
  /// that, and its faces' median excess (its depth) is at least `min_depth_mm` and 3/4 of the seed's.
  double seed_sigmas = 6.0;
  /// Half the shallowest spall (8 mm): shallower dents are within a real liner's texture.
  double min_depth_mm = 4.0;
  /// A spall's area (0.05-0.1 m^2) with margin either side; larger patches are wear patterns.
  double min_area_m2 = 0.02;
  double max_area_m2 = 0.3;
  /// The patch's area over the disc reaching its farthest face: a strip along an edge is no crater.
  double min_compactness = 0.25;
  /// The step across the patch's edge (its boundary faces minus the faces just outside) relative
  /// to its depth: a broken-out piece has a wall, a smooth depression a flank.
  double min_edge_fraction = 0.4;
  /// That step over the change across the next layer of faces outward (the background's gradient
  /// just outside the edge, at least half the face noise: a difference of medians of a few faces):
  /// many times larger at a wall, a few times on a flank sampled by faces of its own size.
  double min_edge_over_outside = 5.0;
};

/// One crater found in one scan.
struct ScanCrater {
  size_t scan = 0;  ///< index into the scans
  double t_days = 0;
  std::string file;
  double z_m = 0, theta_deg = 0;  ///< area-weighted centre
  double radius_m = 1;            ///< the liner's radius there (arc lengths)
  double z_min_m = 0, z_max_m = 0, theta_min_deg = 0, theta_max_deg = 0;
  double area_m2 = 0;
  double depth_mm = 0;                ///< median excess of its faces over the background
  double max_depth_mm = 0;            ///< the deepest face's excess
  double volume_mm_m2 = 0;            ///< sum of area x excess (mm m^2; 1e-3 m^3 per unit)
  double edge_step_mm = 0;            ///< boundary faces minus the faces just outside (medians)
  double outside_change_mm = 0;       ///< the faces just outside minus the next layer out (medians)
  double ring_gradient_mm_per_m = 0;  ///< the background fit's wear gradient at the centre
  double noise_mm = 0;                ///< the scan's robust face-to-face residual sd
  size_t faces = 0;
  size_t edge_faces = 0;       ///< neighbours with a tested value (the faces just outside)
  size_t open_edge_faces = 0;  ///< neighbours without one (unscanned, or no ring around them)
};

/// Craters in one scan (its face wear, ScanCells::face_wear_mm).
std::vector<ScanCrater> FindScanCraters(const core::WearMap& map, const MapFields& fields, const ScanCells& scan,
                                        size_t scan_index, const CraterRules& rules = {});

/// Craters in every scan, one per place: a crater seen again in a later scan (centre within its
/// own reach) is kept from the first scan that shows it, the later scans' dates in `seen_again_days`.
struct CraterSighting {
  ScanCrater crater;
  std::vector<double> seen_again_days;
};
std::vector<CraterSighting> FindCratersInScans(const core::WearMap& map, const MapFields& fields,
                                               const std::vector<ScanCells>& scans, const CraterRules& rules = {});

/// Material loss findings: each sensor's loss step, and each crater no sensor's step accounts for.
/// A crater over a sensor that saw a step is that step's finding, with the scan's place, area and
/// depth added (one finding, not two).
std::vector<Finding> MaterialLossFindings(const std::vector<SensorData>& sensors, const std::vector<CraterSighting>& craters,
                                          double face_size_m, core::TimePoint installed_at);

}  // namespace lw::diagnosis::detail
