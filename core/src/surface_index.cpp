#include "core/surface_index.hpp"

#include <algorithm>

namespace lw::core {

SurfaceIndex::SurfaceIndex(const WearMap& map, double reach_z_m, double reach_arc_m)
    : reach_z_(std::max(reach_z_m, 1e-9)), reach_arc_(std::max(reach_arc_m, 1e-9)) {
  const Eigen::Index n = map.z.size();
  if (n == 0) return;
  zmin_ = map.z.minCoeff();
  const double span = std::max(0.0, map.z.maxCoeff() - zmin_);
  // Arc cells are sized at the smallest radius: a face within reach around is then at most kSub
  // cells away from the point's cell at any radius.
  const double min_r = std::max(1e-6, map.radius.minCoeff());
  cell_z_ = reach_z_ / static_cast<double>(kSub);
  const double cells_z = std::floor(span / cell_z_) + 1.0;
  const double cells_a = std::max(1.0, std::floor(static_cast<double>(kSub) * 2.0 * M_PI * min_r / reach_arc_));
  // Not more cells than a few per face (a tiny reach on a large map): coarser cells still hold
  // every face within reach of the kSub cells around a point's, the visit just reads more faces.
  const double max_cells = 4.0 * static_cast<double>(n) + 64.0;
  double nz = cells_z, na = std::min(cells_a, max_cells);
  while (nz * na > max_cells) {
    if (nz >= na) {
      cell_z_ *= 2.0;
      nz = std::floor(span / cell_z_) + 1.0;
    } else {
      na = std::max(1.0, std::floor(na / 2.0));
    }
  }
  n_z_ = static_cast<long>(nz);
  n_a_ = static_cast<long>(na);
  const size_t cells = static_cast<size_t>(n_z_ * n_a_);
  std::vector<uint32_t> cell_of(static_cast<size_t>(n));
  start_.assign(cells + 1, 0);
  for (Eigen::Index i = 0; i < n; ++i) {
    const long cz = std::clamp<long>(static_cast<long>(std::floor((map.z[i] - zmin_) / cell_z_)), 0, n_z_ - 1);
    const auto c = static_cast<uint32_t>(cz * n_a_ + BucketA(map.theta_deg[i]));
    cell_of[static_cast<size_t>(i)] = c;
    ++start_[c + 1];
  }
  for (size_t c = 0; c < cells; ++c) start_[c + 1] += start_[c];
  std::vector<uint32_t> fill(start_.begin(), start_.end() - 1);
  ids_.resize(static_cast<size_t>(n));
  z_.resize(ids_.size());
  theta_.resize(ids_.size());
  radius_.resize(ids_.size());
  for (Eigen::Index i = 0; i < n; ++i) {
    const uint32_t k = fill[cell_of[static_cast<size_t>(i)]]++;
    ids_[k] = static_cast<uint32_t>(i);
    z_[k] = map.z[i];
    theta_[k] = map.theta_deg[i];
    radius_[k] = map.radius[i];
  }
}

}  // namespace lw::core
