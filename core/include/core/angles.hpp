#pragma once
/// Angles around the crusher axis (degrees, counter-clockwise seen from above, docs/bundle.md).
#include <cmath>

namespace lw::core {

/// Signed a - b wrapped to (-180, 180]: the short way round from b to a.
inline double AngleDiffDeg(double a, double b) {
  double d = std::fmod(a - b, 360.0);
  if (d > 180.0) d -= 360.0;
  if (d <= -180.0) d += 360.0;
  return d;
}

}  // namespace lw::core
