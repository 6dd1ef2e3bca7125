#pragma once
// Test-only forward model: writes a small campaign bundle whose truth is the diagnosis' own
// hypothesis forms (so a clear effect must be found and its parameters recovered), with 1 mm
// quantised sensor readings, multiplicative DEM map noise and scan noise.
#include <filesystem>
#include <string>

namespace lw::test {

struct SyntheticSpec {
  unsigned seed = 1;
  double days = 90;
  double report_hours = 6;
  double map_noise = 0.05;      ///< relative per-face noise of the DEM map vs the truth
  double map_smooth_error = 0;  ///< amplitude of a smooth (z, theta) DEM error no effect describes
  /// Amplitude of a relative DEM error shared by the whole ring at each height (a short run's load
  /// sitting higher or lower): a wiggle along z, the same all around.
  double map_profile_error = 0;
  double scan_noise_mm = 0.3;
  bool with_scan = true;
  double scan_day = -1;  ///< day of the scan (default: the last day)
  bool with_normal_stress = true;
  // How the DEM map is written. "vtk42": legacy VTK 4.2 with SCALARS; "liggghts": exactly as LIGGGHTS
  // `dump mesh/vtk` writes it (VTK 5.1 POLYDATA, OFFSETS/CONNECTIVITY, points repeated per triangle,
  // CELL_DATA as a FIELD).
  std::string map_format = "vtk42";
  double map_zero_fraction = 0;  ///< share of faces no particle hit in a short DEM run (wear 0)
  double map_scale = 3.7e-4;     ///< raw wear value of unit intensity
  bool map_printf_f = false;     ///< print wear with "%f" (6 decimals: small values are truncated)
  bool with_operations = false;
  double rate = 0.6;  ///< mm/day per unit of intensity
  // Effects (0 = absent).
  double hardening_h = 0, hardening_tau_days = 6;
  double gradient_g = 0, gradient_onset_mm = 10;
  double gradient_width_mm = 0;  ///< ramp width; 0: to mid-thickness (the diagnosis' documented form)
  double squeeze_beta = 0;
  double profile_p = 0;  ///< per 100 days, top vs bottom
  double feed_amplitude = 0, feed_theta_deg = 60;
  double throughput_phi = 0;
  // Faults / local events.
  std::string stuck_sensor;
  double stuck_from_day = 0;
  std::string loss_sensor;
  double loss_day = 0, loss_mm = 0;
  /// A spall on the liner from `crater_day` on (0 deep = none): a flat-bottomed disc of
  /// `crater_radius_m` (on the unwrapped surface) `crater_mm` deep, its wall 1 cm wide; with
  /// `crater_smooth` instead a Gaussian dip of the same volume with sd `crater_radius_m` (a wear
  /// pattern, not a spall). Scans and any sensor inside see it.
  double crater_mm = 0, crater_z = 1.3, crater_theta_deg = 67.5, crater_radius_m = 0.15, crater_day = 40;
  bool crater_smooth = false;
};

/// Writes crusher.json, wear_map.vtk, readings.csv, optional operations.csv and scans/ into `dir`.
void WriteSyntheticBundle(const std::filesystem::path& dir, const SyntheticSpec& spec);

}  // namespace lw::test
