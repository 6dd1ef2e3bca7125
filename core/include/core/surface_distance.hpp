#pragma once
/// Distances on the liner's surface: along z and the arc around the crusher axis, the surface
/// unrolled locally (docs/wear.md: a sensor's reach, an area's nearest sensor).
#include <cmath>
#include <cstddef>
#include <vector>

#include "core/angles.hpp"
#include "core/wear_map.hpp"

namespace lw::core {

/// Surface distance between two points `dz_m` apart along z at angles `theta_a_deg` and
/// `theta_b_deg`, the arc taken the short way round at `radius_m` (0: along z only).
inline double SurfaceDistance(double dz_m, double radius_m, double theta_a_deg, double theta_b_deg) {
  return std::hypot(dz_m, radius_m * AngleDiffDeg(theta_a_deg, theta_b_deg) * (M_PI / 180.0));
}

/// The map's mean surface radius at a height (faces binned by z, area-weighted): the radius an arc
/// between two heights is taken at (their mean height's).
class RadiusProfile {
 public:
  RadiusProfile() = default;
  explicit RadiusProfile(const WearMap& map);
  /// The radius at `z` (the nearest bin with faces); 1 m for a map without faces.
  double At(double z) const;

 private:
  size_t Bin(double z) const;
  double zmin_ = 0, step_ = 1;
  std::vector<double> sum_, weight_;
};

}  // namespace lw::core
