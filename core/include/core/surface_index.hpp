#pragma once
/// Fixed-radius neighbour search on a wear map's unwrapped surface (z, arc length): the faces a
/// Gaussian kernel cut at a few standard deviations can reach. A flat grid of cells (two per
/// reach along each axis, faces stored cell by cell with their coordinates, so a query reads
/// contiguous memory), anisotropic (a gyratory chamber's kernels reach much further around than
/// along z). A k-d tree (nanoflann, in Debian) answers the same question but not on a cylinder
/// with an arc length that depends on the radius, and a grid sized to the kernel is simpler and
/// faster for a fixed radius.
#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/wear_map.hpp"

namespace lw::core {

class SurfaceIndex {
 public:
  /// Isotropic: faces within `reach_m` in both directions.
  SurfaceIndex(const WearMap& map, double reach_m) : SurfaceIndex(map, reach_m, reach_m) {}
  /// Faces within `reach_z_m` along z and `reach_arc_m` around the circumference.
  SurfaceIndex(const WearMap& map, double reach_z_m, double reach_arc_m);
  /// The reach along z (for an isotropic index, the reach).
  double reach() const { return reach_z_; }

  /// Calls fn(face, squared surface distance) for every face within reach() of (z, theta) (meant
  /// for an isotropic index); the arc length uses the mean of the point's and the face's radius
  /// (the face's when radius_m <= 0).
  template <typename Fn>
  void ForEachWithin(double z, double theta_deg, double radius_m, Fn&& fn) const {
    const double r2 = reach_z_ * reach_z_;
    Visit(z, theta_deg, radius_m, [&](uint32_t j, double dz, double arc) {
      const double d2 = dz * dz + arc * arc;
      if (d2 <= r2) fn(j, d2);
    });
  }

  /// Calls fn(face, dz, arc) for every face with |dz| <= reach along z and |arc| <= reach around
  /// (and possibly a few a rounding error beyond; dz = face z - z, arc = signed arc length from the
  /// point to the face, at the mean of the point's and the face's radius, the face's when
  /// radius_m <= 0). Every face of the map is visited at most once. Order: cell by cell.
  template <typename Fn>
  void Visit(double z, double theta_deg, double radius_m, Fn&& fn) const {
    if (ids_.empty()) return;
    const double fz = std::floor((z - zmin_) / cell_z_);
    if (!(fz >= -kSub - 1.0) || !(fz <= static_cast<double>(n_z_) + kSub)) return;  // far off the map (or NaN)
    const long iz = static_cast<long>(fz);
    const long z0 = std::max<long>(0, iz - kSub), z1 = std::min<long>(n_z_ - 1, iz + kSub);
    const long ia = BucketA(theta_deg);
    const bool all_around = 2 * kSub + 1 >= n_a_;
    const long a0 = all_around ? 0 : ia - kSub, a1 = all_around ? n_a_ - 1 : ia + kSub;
    const double lim_z = reach_z_ * (1.0 + 1e-9), lim_a = reach_arc_ * (1.0 + 1e-9);
    for (long cz = z0; cz <= z1; ++cz) {
      for (long ca = a0; ca <= a1; ++ca) {
        const long cell = cz * n_a_ + ((ca % n_a_) + n_a_) % n_a_;
        const uint32_t end = start_[static_cast<size_t>(cell) + 1];
        for (uint32_t k = start_[static_cast<size_t>(cell)]; k < end; ++k) {
          const double dz = z_[k] - z;
          if (std::fabs(dz) > lim_z) continue;
          double dth = theta_[k] - theta_deg;
          if (!(dth < 360.0 && dth > -360.0)) dth = std::fmod(dth, 360.0);  // fmod is exact, and the identity, within +-360
          if (dth > 180.0) dth -= 360.0;
          if (dth < -180.0) dth += 360.0;
          const double r = radius_m > 0 ? 0.5 * (radius_m + radius_[k]) : radius_[k];
          const double arc = r * dth * 0.017453292519943295;
          if (std::fabs(arc) > lim_a) continue;
          fn(ids_[k], dz, arc);
        }
      }
    }
  }

 private:
  static constexpr long kSub = 2;  ///< cells per reach along each axis
  long BucketA(double theta_deg) const {
    const double a = std::floor(theta_deg / 360.0 * static_cast<double>(n_a_));
    if (!std::isfinite(a)) return 0;
    return ((static_cast<long>(std::fmod(a, static_cast<double>(n_a_))) % n_a_) + n_a_) % n_a_;
  }
  double reach_z_, reach_arc_;
  double zmin_ = 0, cell_z_ = 1;
  long n_z_ = 1, n_a_ = 1;
  std::vector<uint32_t> start_;             ///< per cell (z-major), first position in the arrays below; one past the end last
  std::vector<uint32_t> ids_;               ///< face index, cell by cell
  std::vector<double> z_, theta_, radius_;  ///< the face's coordinates, in the same order
};

}  // namespace lw::core
