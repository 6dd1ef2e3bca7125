// SurfaceIndex (the kernel's neighbour search) against a brute-force scan of every face: the same
// faces, with bit-identical offsets, so kernel sums over them agree up to summation order.
#include <algorithm>
#include <cmath>
#include <map>
#include <random>

#include "core/map_model.hpp"
#include "core/surface_index.hpp"
#include "unit/core/bundle_fixture.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw::core;

namespace {

struct Hit {
  double dz, arc;
};

/// Every face with |dz| <= rz and |arc| <= ra, by looking at all of them (the reference).
std::map<uint32_t, Hit> BruteForce(const WearMap& m, double z, double theta, double radius, double rz, double ra) {
  std::map<uint32_t, Hit> out;
  for (Eigen::Index j = 0; j < m.z.size(); ++j) {
    double dth = std::fmod(m.theta_deg[j] - theta, 360.0);
    if (dth > 180.0) dth -= 360.0;
    if (dth < -180.0) dth += 360.0;
    const double r = radius > 0 ? 0.5 * (radius + m.radius[j]) : m.radius[j];
    const double dz = m.z[j] - z, arc = r * dth * 0.017453292519943295;
    if (std::fabs(dz) <= rz && std::fabs(arc) <= ra) out[static_cast<uint32_t>(j)] = {dz, arc};
  }
  return out;
}

/// Checks the index against the brute force at `queries` points; returns the hits compared.
size_t Compare(const WearMap& m, double rz, double ra, int queries, unsigned seed) {
  const SurfaceIndex index(m, rz, ra);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uz(m.z.minCoeff() - rz, m.z.maxCoeff() + rz), ut(-400.0, 760.0);
  std::uniform_int_distribution<Eigen::Index> face(0, m.z.size() - 1);
  size_t hits = 0;
  for (int q = 0; q < queries; ++q) {
    // Half at faces (as the smoothing asks, with the face's radius), half anywhere (a sensor).
    const bool at_face = q % 2 == 0;
    const Eigen::Index f = face(rng);
    const double z = at_face ? m.z[f] : uz(rng), th = at_face ? m.theta_deg[f] : ut(rng), r = at_face ? m.radius[f] : -1.0;
    const auto expected = BruteForce(m, z, th, r, rz, ra);
    std::map<uint32_t, Hit> got;
    size_t visits = 0, beyond = 0;
    std::map<uint32_t, int> seen;
    index.Visit(z, th, r, [&](uint32_t j, double dz, double arc) {
      ++visits;
      ++seen[j];
      if (std::fabs(dz) <= rz && std::fabs(arc) <= ra) got[j] = {dz, arc};
      if (std::fabs(dz) > rz * (1 + 1e-6) || std::fabs(arc) > ra * (1 + 1e-6)) ++beyond;
    });
    CHECK_EQUAL(seen.size(), visits);  // no face twice
    CHECK_EQUAL(0u, beyond);           // nothing beyond the reach (but for a rounding error)
    CHECK_EQUAL(expected.size(), got.size());
    for (const auto& [j, h] : expected) {
      const auto it = got.find(j);
      CHECK(it != got.end());
      if (it == got.end()) continue;
      CHECK(h.dz == it->second.dz);  // bit-identical
      CHECK(h.arc == it->second.arc);
    }
    hits += expected.size();
  }
  return hits;
}

}  // namespace

TEST_GROUP(SurfaceIndex){};

TEST(SurfaceIndex, SameFacesAsABruteForceScanOnACone) {
  const WearMap m = lw::test::ConeMap(60, 30, 0.8, 1.6, [](double z) { return 1.0 + z; });
  CHECK(Compare(m, 0.1, 0.1, 400, 1) > 400);   // isotropic, a few cells per reach
  CHECK(Compare(m, 0.05, 0.6, 400, 2) > 400);  // reaching much further around than along z
  Compare(m, 0.3, 4.0, 100, 3);                // around: more than half the circumference (every arc cell)
  Compare(m, 5.0, 5.0, 50, 4);                 // the whole map
  Compare(m, 1e-4, 1e-4, 200, 5);              // tiny: mostly the face itself
}

TEST(SurfaceIndex, AnglesOutsideZeroTo360AndAThinRing) {
  WearMap m = lw::test::ConeMap(7, 40, 0.05, 0.05, [](double) { return 1.0; });  // circumference < 3 reaches
  for (Eigen::Index i = 0; i < m.theta_deg.size(); ++i) m.theta_deg[i] += (i % 3 == 0) ? 720.0 : (i % 3 == 1 ? -360.0 : 0.0);
  Compare(m, 0.2, 0.12, 300, 6);
}

// The map model built on the index (every kernel sum) agrees with one built on an index that visits
// every face of the map: the neighbour search changes how faces are found, not the result.
TEST(SurfaceIndex, MapModelEqualsBruteForceKernelSums) {
  WearMap m = lw::test::ConeMap(48, 24, 0.9, 1.4, [](double z) { return 2.0 - 0.6 * z; });
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.15);
  for (Eigen::Index i = 0; i < m.wear.size(); ++i) m.wear[i] = std::max(0.0, m.wear[i] * (1.0 + noise(rng)));
  const MapModel model = BuildMapModel(m);
  CHECK(model.bandwidth_m > 0);
  // Each face's smoothed value recomputed by brute force with the chosen kernel (the model's form).
  const double h = model.bandwidth_m, ha = model.bandwidth_arc_m > 0 ? model.bandwidth_arc_m : h;
  double worst = 0;
  for (Eigen::Index i = 0; i < m.z.size(); i += 7) {
    double s0 = 0, s1 = 0, s2 = 0, t0 = 0, t1 = 0;
    for (const auto& [j, hit] : BruteForce(m, m.z[i], m.theta_deg[i], m.radius[i], 2.5 * h, 2.5 * ha)) {
      const double q = hit.dz * hit.dz / (h * h) + hit.arc * hit.arc / (ha * ha);
      if (q > 6.25) continue;
      const double w = m.areas[j] * std::exp(-0.5 * q), y = model.clean[j];
      s0 += w, s1 += w * hit.dz, s2 += w * hit.dz * hit.dz, t0 += w * y, t1 += w * hit.dz * y;
    }
    const bool linear = model.local_linear && s0 * s2 - s1 * s1 > 1e-6 * s0 * s2 && s2 > 0;
    const double v = std::max(0.0, linear ? (s2 * t0 - s1 * t1) / (s0 * s2 - s1 * s1) : t0 / s0);
    worst = std::max(worst, std::fabs(v - model.intensity[i]) / std::max(1e-12, std::fabs(v)));
  }
  CHECK(worst < 1e-9);
}
