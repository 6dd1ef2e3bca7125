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
#include <unordered_map>
#include <string>
#include <utility>
#include <vector>

#include "core/wear_map.hpp"

namespace lw::core {

/// Bucket index of face centroids on the unwrapped surface (z, arc length). Arc buckets are sized at
/// the smallest radius, so every face within `reach_m` of a point is in the adjacent buckets.
class SurfaceIndex {
 public:
  SurfaceIndex(const WearMap& map, double reach_m);
  double reach() const { return reach_; }
  /// Calls fn(face, squared surface distance) for every face within reach() of (z, theta); the arc
  /// length uses the mean of the point's and the face's radius (the face's when radius_m <= 0).
  template <typename Fn>
  void ForEachWithin(double z, double theta_deg, double radius_m, Fn&& fn) const {
    const double r2 = reach_ * reach_;
    Visit(z, theta_deg, radius_m, [&](uint32_t j, double dz, double arc) {
      const double d2 = dz * dz + arc * arc;
      if (d2 <= r2) fn(j, d2);
    });
  }
  /// Calls fn(face, dz, arc) for the faces of the buckets around (z, theta) (a superset of those
  /// within reach(); dz = face z - z, arc = signed arc length from the point to the face).
  template <typename Fn>
  void Visit(double z, double theta_deg, double radius_m, Fn&& fn) const {
    const long iz = BucketZ(z), ia = BucketA(theta_deg);
    for (long dz = -1; dz <= 1; ++dz) {
      for (long da = -1; da <= 1; ++da) {
        if (n_arc_ < 3 && da != 0) continue;
        const auto it = buckets_.find(Key(iz + dz, ia + da));
        if (it == buckets_.end()) continue;
        for (const uint32_t j : it->second) {
          const auto jj = static_cast<Eigen::Index>(j);
          double dth = std::fmod(map_.theta_deg[jj] - theta_deg, 360.0);
          if (dth > 180.0) dth -= 360.0;
          if (dth < -180.0) dth += 360.0;
          const double r = radius_m > 0 ? 0.5 * (radius_m + map_.radius[jj]) : map_.radius[jj];
          fn(j, map_.z[jj] - z, r * dth * 0.017453292519943295);
        }
      }
    }
  }

 private:
  long BucketZ(double z) const { return static_cast<long>(std::floor((z - zmin_) / reach_)); }
  long BucketA(double theta_deg) const {
    const long a = static_cast<long>(std::floor(theta_deg / 360.0 * static_cast<double>(n_arc_)));
    return ((a % n_arc_) + n_arc_) % n_arc_;
  }
  long long Key(long iz, long ia) const {
    return (static_cast<long long>(iz) << 32) ^ static_cast<long long>(((ia % n_arc_) + n_arc_) % n_arc_);
  }
  const WearMap& map_;
  double reach_;
  double zmin_ = 0;
  long n_arc_ = 1;
  std::unordered_map<long long, std::vector<uint32_t>> buckets_;
};

struct MapModelOptions {
  /// Gaussian kernel standard deviation along z (m): < 0 chosen from the data (leave-one-out
  /// cross-validation, with the circumferential scale), 0 no smoothing, > 0 fixed (isotropic).
  double bandwidth_m = -1;
  /// Cap faces above their neighbourhood's mean + outlier_z noise standard deviations.
  bool robust = true;
  double outlier_z = 5.0;
  /// Faces scored per candidate bandwidth (a spread-out subset on large maps).
  size_t max_cv_faces = 4000;
  /// Local scale along z by intersection of confidence intervals (bandwidth_m < 0 only).
  bool local_scale = true;
  double local_gamma = 2.5;
};

struct MapModel {
  const WearMap* map = nullptr;
  double bandwidth_m = 0;          ///< Gaussian kernel sd along z, m (0: none)
  double bandwidth_arc_m = 0;      ///< Gaussian kernel sd around the circumference (arc length), m
  std::string bandwidth_method;    ///< "cross-validation", "fixed", "none"
  bool local_linear = false;       ///< local-linear in z (chosen by the CV with the bandwidth), else a kernel mean
  /// Candidate bandwidths and their leave-one-out mean squared error relative to the chosen one.
  std::vector<std::pair<double, double>> cv_curve;
  double face_size_m = 0;          ///< median face edge
  Eigen::VectorXd clean;           ///< per face: `wear` with outliers capped, negatives 0
  size_t outlier_faces = 0;        ///< faces capped
  double noise_phi = 0;            ///< per-face noise variance = noise_phi * m^noise_power (map units)
  double noise_power = 1;
  std::string noise_source;        ///< "wear_stderr (K windows)" or "neighbour differences"
  double face_cv = 0;              ///< median relative noise of one face (sd / local mean)
  double smoothing_error_rel = 0;  ///< relative rms error of the smoothing itself (bias), from the CV
  Eigen::VectorXd intensity;       ///< per face, smoothed (map units)
  Eigen::VectorXd intensity_sd;    ///< per face, standard error of `intensity`
  Eigen::VectorXd normal_stress;   ///< per face, smoothed at normal_bandwidth_m; size 0 when absent
  double normal_bandwidth_m = 0;   ///< 3 x bandwidth_m: stress noise shared with the wear's averaged out

  /// The model at a point: kernel-weighted like the faces (with the point's own surroundings).
  struct Point {
    double intensity = 0;
    double sd = 0;
    double normal_stress = 0;
    double faces = 0;  ///< effective number of faces in the kernel
  };
  Point At(double z, double theta_deg) const;
  /// Relative standard error of face i's intensity (1 when the intensity is 0).
  double RelSd(Eigen::Index i) const;
  /// Noise variance of one face at local mean m (map units).
  double FaceVariance(double m) const;
  Eigen::VectorXd face_var;                     ///< FaceVariance(intensity) per face
  /// Local scale along z (intersection of confidence intervals, "ICI"): the candidate kernels
  /// from the face size up to bandwidth_m (around: bandwidth_arc_m); at each face (and point) the
  /// largest one whose estimate stays inside the confidence intervals of every smaller one. Empty
  /// when the model is not cross-validated (fixed or no smoothing).
  std::vector<double> local_ladder_m;
  double local_gamma = 0;                       ///< confidence-interval half width, in sd
  Eigen::VectorXd local_bandwidth_m;            ///< per face: the scale along z chosen there
  Eigen::VectorXd ref_var;                      ///< per-face noise variance the intervals are built on
  std::shared_ptr<const SurfaceIndex> index;    ///< kernel-support index (bandwidth > 0)
  std::shared_ptr<const SurfaceIndex> normal_index;  ///< the same for the stress kernel
};

MapModel BuildMapModel(const WearMap& map, const MapModelOptions& options = {});

}  // namespace lw::core
