#include "core/surface_distance.hpp"

#include <algorithm>

namespace lw::core {

RadiusProfile::RadiusProfile(const WearMap& map) {
  if (map.z.size() == 0) return;
  zmin_ = map.z.minCoeff();
  const double span = std::max(1e-6, map.z.maxCoeff() - zmin_);
  step_ = span / 200.0;
  sum_.assign(201, 0.0);
  weight_.assign(201, 0.0);
  for (Eigen::Index i = 0; i < map.z.size(); ++i) {
    const size_t b = Bin(map.z[i]);
    sum_[b] += map.areas[i] * map.radius[i];
    weight_[b] += map.areas[i];
  }
}

double RadiusProfile::At(double z) const {
  if (sum_.empty()) return 1.0;
  const size_t b = Bin(z);
  for (size_t d = 0; d < sum_.size(); ++d) {  // the nearest bin with faces
    if (b >= d && weight_[b - d] > 0) return sum_[b - d] / weight_[b - d];
    if (b + d < sum_.size() && weight_[b + d] > 0) return sum_[b + d] / weight_[b + d];
  }
  return 1.0;
}

size_t RadiusProfile::Bin(double z) const {
  return static_cast<size_t>(std::clamp(std::floor((z - zmin_) / step_), 0.0, static_cast<double>(sum_.size() - 1)));
}

}  // namespace lw::core
