#pragma once
/// The DEM wear map as data with an uncertainty: the one map model every consumer applies (live
/// wear and forecast in the server, `linerwatch reconstruct`, the diagnosis and its predictions).
///
/// A finite DEM run samples a few thousand contacts per face, so its per-face wear is a noisy
/// estimate of the underlying wear field (relative scatter about 1 on real LIGGGHTS maps, spikes
/// of 10-20x at the feed and discharge edges). The model
///  * describes the per-face noise by a variance law var = phi * m^p in the map's own units, fitted
///    to `wear_stderr` when the map has it (the spread of the run's time windows) and otherwise to
///    each face's difference from its neighbourhood (the map's own noise);
///  * caps faces far above their neighbourhood (winsorising) before smoothing;
///  * smooths with a Gaussian kernel on the unwrapped surface (z, arc length) whose scale and form
///    (kernel mean, or local-linear in z, less biased at the edges) are chosen from the data: the
///    ones minimising the leave-one-out prediction error of each face from the others (an unbiased
///    estimate of the smoothing's error against the underlying field, up to the noise variance);
///  * gives every smoothed value a standard error: the noise carried through the kernel plus the
///    smoothing's own error (the part of the cross-validated error that noise does not explain).
/// Evaluating the model at a point (a sensor) uses the same kernel, so Eq. 9's row scale and the
/// faces it is applied to see the same averaged intensity.
#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/surface_index.hpp"
#include "core/wear_map.hpp"

namespace lw::core {

struct MapModelOptions {
  /// Gaussian kernel standard deviation along z (m): < 0 chosen from the data (leave-one-out
  /// cross-validation, with the circumferential scale), 0 no smoothing, > 0 fixed (isotropic).
  double bandwidth_m = -1;
  /// With a fixed bandwidth_m (> 0): the kernel sd around the circumference (arc length, m); 0 the
  /// same as bandwidth_m (isotropic). Ignored when the scale is chosen from the data.
  double bandwidth_arc_m = 0;
  /// Cap faces above their neighbourhood's mean + outlier_z noise standard deviations.
  bool robust = true;
  double outlier_z = 5.0;
  /// Faces scored per candidate bandwidth (a spread-out subset on large maps).
  size_t max_cv_faces = 4000;
  /// Local scale along z by intersection of confidence intervals (bandwidth_m < 0 only).
  bool local_scale = true;
  double local_gamma = 2.5;
  /// Threads for the per-face kernel sums (0: one per core). The result does not depend on it.
  int threads = 0;
  /// Maps with more faces than this compute the smoothed field, its standard errors and the local
  /// scale (not the pilot, the noise law or the cross-validation, which stay exact) from kernel sums
  /// on a regular grid over the unwrapped surface (linear binning, a few grid steps per kernel sd):
  /// seconds instead of minutes for a million faces, within a small fraction of the noise of the
  /// exact sums (docs/performance.md, "Maps"). Every map at or below it is computed face by face.
  size_t binned_above_faces = 200000;
};

struct MapModel {
  const WearMap* map = nullptr;
  double bandwidth_m = 0;        ///< Gaussian kernel sd along z, m (0: none)
  double bandwidth_arc_m = 0;    ///< Gaussian kernel sd around the circumference (arc length), m
  std::string bandwidth_method;  ///< "cross-validation", "fixed", "none"
  bool local_linear = false;     ///< local-linear in z (chosen by the CV with the bandwidth), else a kernel mean
  /// Candidate bandwidths and their leave-one-out mean squared error relative to the chosen one.
  std::vector<std::pair<double, double>> cv_curve;
  double face_size_m = 0;    ///< median face edge
  Eigen::VectorXd clean;     ///< per face: `wear` with outliers capped, negatives 0
  size_t outlier_faces = 0;  ///< faces capped
  double noise_phi = 0;      ///< per-face noise variance = noise_phi * m^noise_power (map units)
  double noise_power = 1;
  std::string noise_source;        ///< "wear_stderr (K windows)" or "neighbour differences"
  double face_cv = 0;              ///< median relative noise of one face (sd / local mean)
  double smoothing_error_rel = 0;  ///< relative rms error of the smoothing itself (bias), from the CV
  Eigen::VectorXd intensity;       ///< per face, smoothed (map units)
  Eigen::VectorXd intensity_sd;    ///< per face, standard error of `intensity`
  /// Per face, the part of intensity_sd that is the faces' sampling noise averaged by the kernel
  /// (without the smoothing's own error): what an independent measurement of the pattern, such as
  /// a scan, cannot tell from the map's pattern error.
  Eigen::VectorXd intensity_noise_sd;
  Eigen::VectorXd normal_stress;  ///< per face, smoothed at normal_bandwidth_m; size 0 when absent
  double normal_bandwidth_m = 0;  ///< 3 x bandwidth_m: stress noise shared with the wear's averaged out
  /// Per face, the (outlier-capped) wear smoothed with the normal stress's kernel; size 0 when the
  /// map has no normal stress. On a real map stress follows wear, so a stress-based effect must beat
  /// this field in the stress's place: otherwise what it fitted is only a broader smoothing of the map.
  Eigen::VectorXd intensity_broad;

  /// The model at a point: kernel-weighted like the faces (with the point's own surroundings).
  struct Point {
    double intensity = 0;
    double sd = 0;
    double noise_sd = 0;  ///< the sampling-noise part of sd (as intensity_noise_sd)
    double normal_stress = 0;
    double intensity_broad = 0;  ///< as MapModel::intensity_broad
    double faces = 0;            ///< effective number of faces in the kernel
  };
  Point At(double z, double theta_deg) const;
  /// Relative standard error of face i's intensity (1 when the intensity is 0).
  double RelSd(Eigen::Index i) const;
  /// Noise variance of one face at local mean m (map units).
  double FaceVariance(double m) const;
  Eigen::VectorXd face_var;  ///< FaceVariance(intensity) per face
  /// Local scale along z (intersection of confidence intervals, "ICI"): the candidate kernels
  /// from the face size up to bandwidth_m (around: bandwidth_arc_m); at each face (and point) the
  /// largest one whose estimate stays inside the confidence intervals of every smaller one. Empty
  /// when the model is not cross-validated (fixed or no smoothing).
  std::vector<double> local_ladder_m;
  double local_gamma = 0;                            ///< confidence-interval half width, in sd
  Eigen::VectorXd local_bandwidth_m;                 ///< per face: the scale along z chosen there
  Eigen::VectorXd ref_var;                           ///< per-face noise variance the intervals are built on
  std::shared_ptr<const SurfaceIndex> index;         ///< kernel-support index (bandwidth > 0)
  std::shared_ptr<const SurfaceIndex> normal_index;  ///< the same for the stress kernel
};

MapModel BuildMapModel(const WearMap& map, const MapModelOptions& options = {});

}  // namespace lw::core
