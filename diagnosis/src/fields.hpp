#pragma once
/// Fields the wear model needs, derived from the DEM map: normalised intensity, normalised normal
/// stress, the map's own noise level, an unwrapped (z, theta) cell grid, and scan wear per cell.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/angles.hpp"
#include "core/bundle.hpp"
#include "core/map_model.hpp"

namespace lw::diagnosis::detail {

inline constexpr double kUnestimatedFaceNoise = 0.25;
/// A DEM map's standard error of its first circumferential harmonic (cosine or sine part, relative
/// to the ring mean) per unit of its faces' relative noise. The load sloshes around the chamber, so
/// over a finite span that harmonic scatters far more than independent face noise would let it:
/// measured on five LIGGGHTS runs of four chambers (docs/diagnosis.md, "Feed segregation against the map's own asymmetry"; the
/// measurements in bench/diagnosis/RESULTS.md) as 0.036-0.080 of the per-face relative scatter between time windows, median 0.07.
/// Both fall as one over the root of the simulated span, so the ratio carries to maps of other lengths.
inline constexpr double kHarmonic1PerFaceNoise = 0.07;
/// A DEM map's standard error of its ring-mean profile at one eighth of the concave height (relative
/// to that band's mean, after the map's total, which the row scales absorb) per unit of its faces'
/// relative noise. A time window's load sits higher or lower in the chamber as a whole, so a band's
/// ring mean scatters between windows far more than its faces' independent noise would let it:
/// measured on the nine LIGGGHTS runs of the five committed libraries (docs/diagnosis.md, "The map's
/// own profile error") as 0.072-0.172 of the per-face relative scatter between windows, median 0.10,
/// nearly the same at a sixteenth of the height. Both fall as one over the root of the simulated
/// span, so the ratio carries to maps of other lengths.
inline constexpr double kBandMeanPerFaceNoise = 0.10;

struct MapFields {
  /// The map model (core/map_model.hpp) every intensity here comes from: smoothed at the
  /// data-chosen scale, with a standard error per face.
  core::MapModel model;
  Eigen::VectorXd intensity;       ///< per face, model intensity / median (median face = 1)
  Eigen::VectorXd rel_sd;          ///< per face, relative standard error of `intensity` (map noise + smoothing error)
  Eigen::VectorXd rel_noise_sd;    ///< per face, its sampling-noise part only (the kernel-averaged face noise)
  double normal_robust_max = 1;    ///< normal stress that maps to normal_tilde = 1
  double normal_to_intensity = 0;  ///< normal_i = normal stress x this
  Eigen::VectorXd normal_tilde;    ///< per face, normal stress / robust max, clipped to [0, 1.5]; 1 when absent
  Eigen::VectorXd normal_i;        ///< per face, normal stress in intensity units (same area-weighted mean)
  /// Per face, the wear intensity smoothed with the normal stress's kernel (MapModel::intensity_broad),
  /// in intensity units (same area-weighted mean): squeeze wear's stand-in without stress (broad_to_intensity
  /// converts the model's values).
  Eigen::VectorXd broad_i;
  double broad_to_intensity = 0;
  bool has_normal = false;
  double intensity_median = 1;  ///< raw intensity that maps to 1
  double face_rel_noise = 0;    ///< relative noise of one raw face (the model's noise law), for notes
  /// Standard error of the map's first circumferential harmonic (cosine or sine part, relative):
  /// the larger of kHarmonic1PerFaceNoise x face_rel_noise and the harmonic the raw map itself
  /// shows (an axisymmetric chamber's map should show none). 0 when the map is not a full ring.
  double harmonic1_rel_sd = 0;
  /// Standard error of the map's ring-mean profile per eighth of the concave height (relative):
  /// kBandMeanPerFaceNoise x face_rel_noise.
  double band_rel_sd = 0;
  bool noise_estimated = false;  ///< false: too few faces to estimate it; kUnestimatedFaceNoise assumed
  double face_size_m = 0.05;     ///< typical face edge
  double z_bottom = 0;           ///< concave extent along z (rows)
  double z_top = 1;
  double theta_lo_deg = 0;      ///< start of the covered angular range
  double theta_span_deg = 360;  ///< covered angular range
  double mean_radius_m = 1;
  /// The map's circumferential-mean intensity profile along z: relative rate change per concave
  /// height of upward translation, -(d ln I_mean / d zeta) minus its intensity-weighted liner mean
  /// (the translated profile does the same total work). Sampled at profile_z.
  /// Print resolution of the raw wear values when the map looks %f-truncated (else 0): intensities
  /// of a few resolution steps are biased by rounding, in a spatially smooth, not random, way.
  double quantum_raw = 0;
  std::vector<double> profile_z;
  std::vector<double> profile_shift_rel;
};

/// Relative intensity error from the print resolution at a (normalised) intensity; not reduced by
/// averaging faces (neighbouring faces round the same way).
double QuantisationRel(const MapFields& fields, double intensity);
/// Relative rate change at height z when the map's profile moves up by one concave height.
double ProfileShiftRel(const MapFields& fields, double z);

/// What the wear model needs at one location (a sensor or a grid cell).
struct PointField {
  double z = 0;
  double theta_deg = 0;
  double intensity = 0;  ///< normalised
  double normal_tilde = 1;
  double normal_i = 0;
  double broad_i = 0;       ///< MapFields::broad_i here
  double rel_noise = 0;     ///< relative noise of `intensity` from the map's per-face noise
  double rel_sampling = 0;  ///< its sampling-noise part (without the smoothing's error), with quantisation
  double area = 0;
  size_t faces = 0;
};

struct CellGrid {
  size_t nz = 0;
  size_t nt = 0;
  double z0 = 0;
  double dz = 1;
  double t0_deg = 0;
  double dt_deg = 360;
  std::vector<int> face_cell;     ///< per face: cell index or -1
  std::vector<PointField> cells;  ///< nz * nt (cells with faces == 0 are empty)
  int CellOf(double z, double theta_deg) const;
};

/// Per-cell wear measured by one scan (mm along the as-new face normal).
struct ScanCells {
  double t_days = 0;
  std::string file;
  std::vector<double> wear_mm;       ///< per cell (NaN where no points)
  std::vector<double> sigma_mm;      ///< standard error of the cell mean
  std::vector<size_t> points;        ///< per cell
  std::vector<double> face_wear_mm;  ///< per face (NaN where no points), for crater checks
  std::vector<PointField> fields;    ///< per cell, over the faces the scan covered
  double point_noise_mm = 0;         ///< estimated scan noise per point
  size_t points_used = 0;
  size_t points_total = 0;
};

MapFields ComputeMapFields(const core::Bundle& bundle);
/// The map model at (z, theta): the same kernel as the faces (Eq. 9 at a sensor sees what the faces see).
PointField FieldAt(const core::WearMap& map, const MapFields& fields, double z, double theta_deg);
CellGrid BuildCellGrid(const core::WearMap& map, const MapFields& fields, size_t target_cells);
ScanCells ProjectScan(const core::WearMap& map, const MapFields& fields, const CellGrid& grid, const core::Scan& scan,
                      double t_days, double thickness_new_mm);

using core::AngleDiffDeg;  ///< signed a - b wrapped to (-180, 180]

}  // namespace lw::diagnosis::detail
