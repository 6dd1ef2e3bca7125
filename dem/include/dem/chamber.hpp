#pragma once
/// The chamber a DEM case is made from: concave and mantle profiles, gyration, feed and particles.
/// Read from the optional "chamber" object of a crusher folder's crusher.json (docs/dem.md); every
/// key has a default, so an empty object describes a 62-75-like primary gyratory.
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

namespace lw::dem {

/// One size class of the feed: spheres of `radius_m` making `mass_fraction` of the feed mass.
struct SizeClass {
  double radius_m = 0;
  double mass_fraction = 0;
};

/// A radius profile r(z) through (z, r) points in ascending z, linear between them.
struct Profile {
  std::vector<std::pair<double, double>> points;
  double RadiusAt(double z) const;  ///< clamped to the end points outside the profile
  double z_min() const { return points.front().first; }
  double z_max() const { return points.back().first; }
};

struct ChamberSpec {
  std::string name = "chamber";
  Profile concave;                  ///< inner surface of the concave, z = 0 at its bottom (discharge) edge
  Profile mantle;                   ///< outer surface of the mantle in its centred position
  double eccentric_throw_m = 0.03;  ///< radius of the mantle's circular gyration
  double speed_rpm = 150;           ///< gyrations per minute
  double feed_rate_tph = 40000;     ///< insertion rate cap; above the chamber's capacity = choke fed
  std::vector<SizeClass> psd;       ///< feed size classes (no breakage: the product size range)
  double density_kg_m3 = 2700;
  double simulated_s = 16;  ///< total simulated time, filling included
  double timestep_s = 4e-4;
  double dump_interval_s = 0.5;    ///< mesh dumps (wear, stresses) every this many seconds
  double youngs_modulus_pa = 1e7;  ///< soft contacts (the seed paper's value) allow ~1e-4 s steps
  double poisson_ratio = 0.3;
  double restitution = 0.3;
  double friction = 0.6;
  double rolling_friction = 0.3;  ///< EPSD2 rolling friction coefficient
  double finnie_k = 1.0;
  int mesh_n_theta = 96;  ///< concave faces around the circumference (x2 triangles)
  int mesh_n_z = 36;      ///< concave face bands from discharge to feed edge
  unsigned seed = 1;      ///< selects the insertion's random seeds
  int windows = 0;        ///< independent time windows for the uncertainty; 0 = automatic

  double height_m() const { return concave.z_max(); }
  /// Smallest gap at the discharge (z = 0) over a gyration: concave r - mantle r - throw.
  double closed_side_setting_m() const;
  double open_side_setting_m() const;
  double max_radius_m() const;
  double min_radius_m() const;
  /// Rayleigh time of the smallest particle (s): the stable time step scale of a Hertz contact.
  double rayleigh_time_s() const;
};

/// The chamber of a crusher.json: its "chamber" object (absent = all defaults). Throws
/// std::invalid_argument naming `file` and the key on a bad value or an inconsistent chamber
/// (mantle touching the concave, CSS smaller than the largest particle, size fractions that do not
/// sum to 1, a time step above 20 % of the Rayleigh time, fewer dumps than windows need, ...).
ChamberSpec ChamberFromCrusherJson(const nlohmann::json& crusher, const std::string& file);

/// All parameters, defaults filled in (what `linerwatch dem` ran), as the "chamber" object form.
nlohmann::json ToJson(const ChamberSpec& spec);

}  // namespace lw::dem
