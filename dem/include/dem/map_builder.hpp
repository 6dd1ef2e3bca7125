#pragma once
/// Builds the crusher's wear map from a finished LIGGGHTS case: the Finnie wear increment of each
/// concave face over the steady, choke-fed span (found from the chamber mass), split into
/// independent time windows whose spread gives each face's standard error, stresses averaged over
/// the span, and a validation summary.
#include <filesystem>
#include <nlohmann/json.hpp>
#include <vector>

#include "core/bundle.hpp"
#include "dem/chamber.hpp"

namespace lw::dem {

/// Output file names, written into the output folder (each atomically).
struct MapFiles {
  static constexpr const char* kMap = "wear_map.vtk";          ///< wear, wear_stderr, stresses
  static constexpr const char* kWindows = "wear_windows.vtk";  ///< wear_w1..K, normal_stress_w1..K
  static constexpr const char* kSummary = "dem_summary.json";  ///< validation summary
};

/// Reads `case_dir` (case.json, mass.txt, post/concave_*.vtk, logs) and writes the three files into
/// `out_dir`. `rows` name the liner rows for the summary (empty: thirds of the height named
/// LDWN, LMID, LUP). `windows` > 0 asks for that many windows (else the spec's, else automatic:
/// as many windows of >= 3 gyrations as fit, at most 8). Throws std::runtime_error naming the file
/// and the reason when the run is incomplete, never steady, or too short for 2 windows.
/// Returns the summary that was written.
nlohmann::json BuildMap(const ChamberSpec& spec, const std::filesystem::path& case_dir, std::vector<core::Row> rows,
                        const std::filesystem::path& out_dir, int windows = 0);

}  // namespace lw::dem
