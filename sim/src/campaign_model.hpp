#pragma once
// The reduced-order chamber model the campaign generator and its truth integration share
// (docs/sim.md): internal to sim/src.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "sim/campaign.hpp"

namespace lw::sim::model {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

inline double Param(const EffectSpec& e, const char* key, double fallback) {
  auto it = e.params.find(key);
  return it == e.params.end() ? fallback : it->second;
}

inline const EffectSpec* Find(const std::vector<EffectSpec>& effects, const std::string& name) {
  for (const auto& e : effects) {
    if (e.name == name) return &e;
  }
  return nullptr;
}

// Reduced-order chamber model (docs/sim.md). zeta = z / height, 0 at the discharge.
// Abrasive sliding work rises towards the discharge (finer, faster rock); Finnie's angle factor
// keeps it the dominant term of the DEM wear.
inline double Abrasion(double zeta) {
  return 0.06 + std::pow(std::clamp(1.0 - zeta, 0.0, 1.5), 1.5);
}
// Compressive (normal) stress peaks where rock is nipped, in the mid-lower chamber, with a mild
// two-lobed variation around the circumference from the eccentric throw.
inline double NormalStress(double zeta, double theta_deg) {
  return 0.05 + std::exp(-std::pow((zeta - 0.3) / 0.2, 2.0)) * (1.0 + 0.1 * std::cos(2.0 * theta_deg * kDeg)) / 1.1;
}

inline double SmoothStep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

}  // namespace lw::sim::model
