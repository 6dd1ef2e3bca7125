#pragma once
/// Angles around the crusher axis (degrees, counter-clockwise seen from above, docs/bundle.md).
#include <cmath>

namespace lw::core {

/// Signed a - b wrapped to (-180, 180]: the short way round from b to a.
inline double AngleDiffDeg(double a, double b) {
  double d = a - b;
  if (!(d < 360.0 && d > -360.0)) d = std::fmod(d, 360.0);  // fmod is exact, and the identity, within +-360
  if (d > 180.0) d -= 360.0;
  if (d <= -180.0) d += 360.0;
  return d;
}

}  // namespace lw::core
