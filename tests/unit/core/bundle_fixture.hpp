#pragma once
// Writes a small valid bundle (two rows on a cylinder map) into a scratch directory.
#include <cmath>
#include <string>

#include "core/bundle.hpp"
#include "core/wear_map.hpp"
#include "support/temp_directory.hpp"

namespace lw::test {

/// Two rows (LDWN 0-1 m, LUP 1-2 m), one sensor each (1001 at z 0.5, theta 0; 1002 at z 1.5, theta 90).
inline core::CrusherConfig TwoRows() {
  core::CrusherConfig c;
  c.crusher_id = "cr1";
  c.thickness_new_mm = 120;
  c.thickness_min_mm = 30;
  c.rows = {{"LDWN", 0.0, 1.0}, {"LUP", 1.0, 2.0}};
  c.sensors = {{"1001", "LDWN", 0.5, 0.0, 120, {}}, {"1002", "LUP", 1.5, 90.0, 120, {}}};
  return c;
}

/// Truncated cone, radius r0 at z = 0 to r1 at z = height, nt x nz quads; wear = intensity(z) per face.
template <typename F>
core::WearMap ConeMap(int nt, int nz, double r0, double r1, F intensity, double height = 2.0) {
  core::WearMap m;
  for (int k = 0; k <= nz; ++k) {
    const double r = r0 + (r1 - r0) * k / nz;
    for (int j = 0; j < nt; ++j) {
      const double th = 2 * M_PI * j / nt;
      m.points.emplace_back(r * std::cos(th), r * std::sin(th), height * k / nz);
    }
  }
  std::vector<double> w;
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < nt; ++j) {
      const auto a = static_cast<uint32_t>(k * nt + j), b = static_cast<uint32_t>(k * nt + (j + 1) % nt);
      const auto c = a + static_cast<uint32_t>(nt), d = b + static_cast<uint32_t>(nt);
      m.faces.push_back({a, d, b});
      m.faces.push_back({a, c, d});
      const double zc = height * (k + 0.5) / nz;
      w.push_back(intensity(zc));
      w.push_back(intensity(zc));
    }
  }
  m.wear = Eigen::Map<Eigen::VectorXd>(w.data(), static_cast<Eigen::Index>(w.size()));
  m.ComputeGeometry();
  return m;
}

/// Cylinder of radius 1 m, z in [0, 2] m, nt x nz quads; wear = intensity(z) per face.
template <typename F>
core::WearMap CylinderMap(int nt, int nz, F intensity) {
  return ConeMap(nt, nz, 1.0, 1.0, intensity);
}

inline const char* kCrusherJson = R"({
  "crusher_id": "cr1", "installed_at": "2026-01-01T00:00:00Z",
  "concave": {"thickness_new_mm": 120, "thickness_min_mm": 30,
              "rows": [{"name": "LDWN", "z_min_m": 0.0, "z_max_m": 1.0}, {"name": "LUP", "z_min_m": 1.0, "z_max_m": 2.0}]},
  "sensors": [{"id": "1001", "row": "LDWN", "z_m": 0.5, "theta_deg": 0},
              {"id": "1002", "row": "LUP", "z_m": 1.5, "theta_deg": 90, "address": "0013A20040A1B2C3"}]
})";

inline void WriteBundle(const TempDirectory& dir, const std::string& readings) {
  dir.Write("crusher.json", kCrusherJson);
  core::WearMap m = CylinderMap(24, 20, [](double z) { return 2.0 - 0.5 * z; });
  core::WriteWearMapVtk(dir.path() / "wear_map.vtk", m, {{"wear", &m.wear}});
  dir.Write("readings.csv", readings);
}

}  // namespace lw::test
