#pragma once
/// DEM wear-intensity map of the as-new concave inner surface: a triangle mesh with per-face arrays.
/// Import: legacy VTK POLYDATA (ASCII, version 4.2 SCALARS or 5.1 OFFSETS/CONNECTIVITY + FIELD, as
/// LIGGGHTS `dump mesh/vtk ... stress wear` writes it) and per-face CSV (EDEM/Rocky-style exports).
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace lw::core {

/// A problem with an input file: names the file, the line (0 when not line-specific) and the rule.
class InputError : public std::runtime_error {
 public:
  InputError(std::string file, size_t line, const std::string& rule);
  const std::string& file() const { return file_; }
  size_t line() const { return line_; }
  const std::string& rule() const { return rule_; }

 private:
  std::string file_;
  size_t line_;
  std::string rule_;
};

/// A whole file's bytes. Throws InputError (the file name, "cannot open ...").
std::string ReadFile(const std::filesystem::path& path);

/// SHA-256 of `bytes` as 64 lower-case hex digits.
std::string Sha256Hex(const std::string& bytes);

struct WearMap {
  std::vector<Eigen::Vector3d> points;         ///< metres, crusher frame
  std::vector<std::array<uint32_t, 3>> faces;  ///< triangles, indices into points
  Eigen::VectorXd wear;                        ///< per face, relative intensity (required)
  Eigen::VectorXd normal_stress;               ///< per face; size 0 when absent
  Eigen::VectorXd shear_stress;                ///< per face; size 0 when absent
  /// Standard error of `wear` per face (same units), from the spread of the DEM run's K steady
  /// time windows (`wear_stderr`, docs/diagnosis.md "map model"); size 0 when the map has none.
  Eigen::VectorXd wear_stderr;
  /// K, the number of independent time windows `wear` sums (title `... windows=K ...`); 0 unknown.
  int windows = 0;
  std::string title;                             ///< the VTK title line (free text); empty for CSV maps
  std::map<std::string, Eigen::VectorXd> extra;  ///< any other per-face arrays found

  // Derived by ComputeGeometry() (LoadWearMap calls it):
  std::vector<Eigen::Vector3d> centroids;
  std::vector<Eigen::Vector3d> normals;  ///< unit, oriented towards the crusher axis (inward)
  Eigen::VectorXd areas;                 ///< m^2
  Eigen::VectorXd z;                     ///< centroid z, m
  Eigen::VectorXd theta_deg;             ///< centroid angle, degrees in [0, 360), CCW from +x
  Eigen::VectorXd radius;                ///< centroid distance from the axis, m

  std::string sha256;  ///< hash of the file bytes as imported (hex)

  size_t face_count() const { return faces.size(); }
  bool has_normal_stress() const { return normal_stress.size() > 0; }
  bool has_shear_stress() const { return shear_stress.size() > 0; }
  bool has_wear_stderr() const { return wear_stderr.size() > 0; }
  void ComputeGeometry();
  /// Faces whose winding pointed away from the axis (their normals were flipped inward).
  size_t flipped_faces = 0;
};

/// Problems found while validating a map (not fatal: reported with the import).
struct MapValidation {
  size_t degenerate_faces = 0;       ///< zero-area triangles
  size_t outward_faces_flipped = 0;  ///< normals that pointed away from the axis and were flipped
  double zero_wear_fraction = 0.0;   ///< share of faces with wear == 0
  bool looks_truncated = false;      ///< values look like %f-truncated (few distinct small values)
  size_t negative_wear_faces = 0;
  std::vector<std::string> warnings;  ///< human-readable, one per problem
};

/// Loads a map by extension: .vtk (legacy VTK) or .csv (per-face CSV, see docs/server.md).
/// Throws InputError naming file, line and rule on malformed input.
WearMap LoadWearMap(const std::filesystem::path& path, MapValidation* validation = nullptr);
/// The same on bytes already in memory: `file` (a file name) selects the format by its extension
/// and names the file in errors.
WearMap ParseWearMap(const std::string& text, const std::string& file, MapValidation* validation = nullptr);

/// Writes a legacy VTK 4.2 ASCII POLYDATA with the given per-face arrays (name -> values, each of
/// face_count() entries) as CELL_DATA SCALARS. Writes to a temporary file and renames, so no partial
/// file is left on failure. `title` is the VTK title line (one line, at most 255 characters; empty:
/// the map's own title, else "linerwatch wear map").
void WriteWearMapVtk(const std::filesystem::path& path, const WearMap& map,
                     const std::vector<std::pair<std::string, const Eigen::VectorXd*>>& cell_arrays,
                     const std::string& title = "");

}  // namespace lw::core
