#pragma once
/// Writes a LIGGGHTS-PUBLIC 3.8 case for a chamber: STL meshes in the crusher frame, the input
/// script (fresh start and resume-from-restart), a Slurm batch script and an MPI hostfile example.
#include <filesystem>
#include <string>

#include "dem/chamber.hpp"

namespace lw::dem {

/// Fixed layout of a case folder (docs/dem.md).
struct CaseLayout {
  static constexpr const char* kConcaveStl = "concave.stl";
  static constexpr const char* kMantleStl = "mantle.stl";
  static constexpr const char* kHopperStl = "hopper.stl";
  static constexpr const char* kInput = "in.crusher";     ///< fresh start
  static constexpr const char* kResume = "in.resume";     ///< continue from a restart file
  static constexpr const char* kCaseJson = "case.json";   ///< the chamber as run (defaults filled in)
  static constexpr const char* kMassSeries = "mass.txt";  ///< t, particles and mass in chamber, inserted mass
  static constexpr const char* kDumpDir = "post";         ///< concave_<step>.vtk mesh dumps
  static constexpr const char* kRestartDir = "restart";   ///< crusher.<step>.restart
  static constexpr const char* kSlurm = "run.slurm";
  static constexpr const char* kHostfile = "hostfile.example";
};

/// Steps of the whole run, of one dump interval, of one gyration and of one restart interval.
/// A gyration is a whole number of steps (the speed is rounded to it, by far under 1 %), and
/// restarts fall on whole gyrations: at a restart the mantle is where its STL puts it, so a
/// resumed run continues the gyration exactly whether or not LIGGGHTS restores mesh positions.
struct CaseSteps {
  long total = 0;
  long dump_every = 0;
  long gyration = 0;
  long restart_every = 0;
  double omega_rad_s = 0;  ///< the gyration's angular speed as run
};
CaseSteps StepsOf(const ChamberSpec& spec);

/// Writes every file of the case into `dir` (created if missing; existing case files replaced,
/// dumps and restarts left alone). Each file is written to a temporary and renamed.
void WriteCase(const ChamberSpec& spec, const std::filesystem::path& dir);

}  // namespace lw::dem
