#include "dem/case_writer.hpp"

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "core/atomic_file.hpp"

namespace lw::dem {
namespace {

namespace fs = std::filesystem;
constexpr double kPi = 3.14159265358979323846;

void WriteAtomically(const fs::path& path, const std::string& text) {
  core::WriteFileAtomically(path, text);
}

// Surface of revolution through `rings` (z, r), `n_theta` segments, as ASCII STL facets.
void Revolve(std::ostringstream& out, const std::vector<std::pair<double, double>>& rings, int n_theta, double x_offset) {
  char line[160];
  auto vertex = [&](double r, double a, double z) {
    std::snprintf(line, sizeof line, "      vertex %.7f %.7f %.7f\n", x_offset + r * std::cos(a), r * std::sin(a), z);
    out << line;
  };
  for (size_t j = 0; j + 1 < rings.size(); ++j) {
    const auto [za, ra] = rings[j];
    const auto [zb, rb] = rings[j + 1];
    for (int i = 0; i < n_theta; ++i) {
      const double a = 2 * kPi * i / n_theta, b = 2 * kPi * (i + 1) / n_theta;
      out << "  facet normal 0 0 0\n    outer loop\n";
      vertex(ra, a, za), vertex(ra, b, za), vertex(rb, b, zb);
      out << "    endloop\n  endfacet\n  facet normal 0 0 0\n    outer loop\n";
      vertex(ra, a, za), vertex(rb, b, zb), vertex(rb, a, zb);
      out << "    endloop\n  endfacet\n";
    }
  }
}

std::string Stl(const std::string& name, const std::vector<std::vector<std::pair<double, double>>>& parts,
                const std::vector<int>& n_theta, double x_offset = 0.0) {
  std::ostringstream out;
  out << "solid " << name << "\n";
  for (size_t k = 0; k < parts.size(); ++k) Revolve(out, parts[k], n_theta[k], x_offset);
  out << "endsolid " << name << "\n";
  return out.str();
}

std::vector<std::pair<double, double>> Rings(const Profile& p, double z0, double z1, int n) {
  std::vector<std::pair<double, double>> r;
  for (int j = 0; j <= n; ++j) {
    const double z = z0 + (z1 - z0) * j / n;
    r.push_back({z, p.RadiusAt(z)});
  }
  return r;
}

// Heights of the parts above the concave (m, crusher frame).
struct Heights {
  double mantle_apex, feed_lo, feed_hi, hopper_top, box_lo, box_r;
};
Heights HeightsOf(const ChamberSpec& s) {
  Heights h;
  h.mantle_apex = s.mantle.z_max() + 0.3;
  h.feed_lo = std::max(h.mantle_apex, s.height_m()) + 0.1;
  h.feed_hi = h.feed_lo + std::max(0.35, 6 * s.max_radius_m());
  h.hopper_top = h.feed_hi + 0.05;
  h.box_lo = s.mantle.z_min() - 0.4;
  double rmax = 0;
  for (const auto& [z, r] : s.concave.points) rmax = std::max(rmax, r);
  h.box_r = rmax + 0.1;
  return h;
}

// Primes above 10000 for LIGGGHTS's random seeds, picked by the spec's seed.
long Prime(unsigned seed, int k) {
  static const long kPrimes[] = {15485863, 15485867, 32452843,  32452867,  49979687,  49979693,  67867967,  67867979,
                                 86028121, 86028157, 104395301, 104395303, 122949823, 122949829, 141650939, 141650963};
  return kPrimes[(seed * 5 + static_cast<unsigned>(k)) % 16];
}

std::string Script(const ChamberSpec& s, bool resume) {
  const Heights h = HeightsOf(s);
  const CaseSteps steps = StepsOf(s);
  const double omega = steps.omega_rad_s;
  std::ostringstream o;
  o.precision(10);
  o << "# LIGGGHTS-PUBLIC 3.8 case written by `linerwatch dem` for chamber '" << s.name << "' (docs/dem.md).\n"
    << "# Crusher frame: metres, z up the axis, z = 0 at the concave's discharge edge.\n"
    << (resume ? "# Resume: run with -var restartfile restart/crusher.<step>.restart\n" : "# Fresh start.\n")
    << "variable dt equal " << s.timestep_s << "\n"
    << "variable ecc equal " << s.eccentric_throw_m << "\n"
    << "variable omega equal " << omega << "\n"
    << "variable nsteps equal " << steps.total << "\n"
    << "atom_style granular\natom_modify map array\nboundary f f f\nnewton off\ncommunicate single vel yes\nunits si\n";
  if (resume) {
    o << "read_restart ${restartfile}\n";
  } else {
    o << "region domain block " << -h.box_r << " " << h.box_r << " " << -h.box_r << " " << h.box_r << " " << h.box_lo << " "
      << h.hopper_top + 0.1 << " units box\ncreate_box 1 domain\n";
  }
  o << "neighbor " << std::max(0.01, 0.3 * s.min_radius_m()) << " bin\nneigh_modify delay 0\n"
    << "fix m1 all property/global youngsModulus peratomtype " << s.youngs_modulus_pa << "\n"
    << "fix m2 all property/global poissonsRatio peratomtype " << s.poisson_ratio << "\n"
    << "fix m3 all property/global coefficientRestitution peratomtypepair 1 " << s.restitution << "\n"
    << "fix m4 all property/global coefficientFriction peratomtypepair 1 " << s.friction << "\n"
    << "fix m5 all property/global coefficientRollingFriction peratomtypepair 1 " << s.rolling_friction << "\n"
    << "fix m6 all property/global k_finnie peratomtypepair 1 " << s.finnie_k << "\n"
    << "pair_style gran model hertz tangential history rolling_friction epsd2\npair_coeff * *\n"
    << "timestep ${dt}\n"
    << "fix gravi all gravity 9.81 vector 0.0 0.0 -1.0\n"
    << "# Concave: wear-tracked (Finnie). Mantle: its STL has the axis at (+e, 0), phase 0 of a circular\n"
    << "# translation of radius e about the crusher axis (velocity below). Hopper: keeps the choke feed.\n"
    << "fix concave all mesh/surface/stress file " << CaseLayout::kConcaveStl << " type 1 wear finnie\n"
    << "fix mantle all mesh/surface file " << CaseLayout::kMantleStl << " type 1 curvature_tolerant yes\n"
    << "fix hopper all mesh/surface file " << CaseLayout::kHopperStl << " type 1\n"
    << "fix walls all wall/gran model hertz tangential history rolling_friction epsd2 mesh n_meshes 3 meshes concave mantle "
       "hopper\n"
    << "variable vx equal -${ecc}*${omega}*sin(${omega}*step*${dt})\n"
    << "variable vy equal ${ecc}*${omega}*cos(${omega}*step*${dt})\n"
    << "variable vz equal 0\n"
    << "fix gyration all move/mesh mesh mantle linear/variable v_vx v_vy v_vz\n"
    << "region feed cylinder z 0 0 " << h.box_r - 0.1 - s.max_radius_m() - 0.02 << " " << h.feed_lo << " " << h.feed_hi
    << " units box\n";
  for (size_t k = 0; k < s.psd.size(); ++k)
    o << "fix pts" << k + 1 << " all particletemplate/sphere " << Prime(s.seed, static_cast<int>(k))
      << " atom_type 1 density constant " << s.density_kg_m3 << " radius constant " << s.psd[k].radius_m << "\n";
  o << "fix pdd all particledistribution/discrete " << Prime(s.seed, 11) << " " << s.psd.size();
  for (size_t k = 0; k < s.psd.size(); ++k) o << " pts" << k + 1 << " " << s.psd[k].mass_fraction;
  o << "\n";
  const long insert_every = std::max(1L, std::lround(0.1 / s.timestep_s));
  o << "fix ins all insert/rate/region seed " << Prime(s.seed, 13) << " distributiontemplate pdd nparticles INF massrate "
    << s.feed_rate_tph / 3.6 << " insert_every " << insert_every
    << " overlapcheck yes all_in yes vel constant 0. 0. -1. region feed ntry_mc 10000\n"
    << "fix integr all nve/sphere\n"
    << "region chamber cylinder z 0 0 " << h.box_r << " 0.0 " << s.height_m() << " units box\n"
    << "region hopperfill cylinder z 0 0 " << h.box_r << " " << s.height_m() << " " << h.hopper_top << " units box\n"
    << "variable t equal step*${dt}\n"
    << "variable nch equal count(all,chamber)\n"
    << "variable mch equal mass(all,chamber)\n"
    << "variable mhop equal mass(all,hopperfill)\n"
    << "variable mall equal mass(all)\n"
    << "variable mins equal f_ins[2]\n"
    << "thermo_style custom step atoms v_nch v_mch cpu\n"
    << "thermo " << steps.dump_every << "\n"
    << "thermo_modify lost ignore norm no\n"
    << "fix masslog all print " << std::max(1L, steps.dump_every / 5) << " \"${t} ${nch} ${mch} ${mhop} ${mall} ${mins}\" "
    << (resume ? "append " : "file ") << CaseLayout::kMassSeries << " screen no"
    << (resume ? "" : " title \"t_s n_chamber m_chamber_kg m_hopper_kg m_total_kg m_inserted_kg\"") << "\n"
    << "dump dmesh all mesh/vtk " << steps.dump_every << " " << CaseLayout::kDumpDir << "/concave_*.vtk stress wear concave\n"
    << "restart " << steps.restart_every << " " << CaseLayout::kRestartDir << "/crusher.*.restart\n"
    << "run ${nsteps} upto\n";
  return o.str();
}

}  // namespace

CaseSteps StepsOf(const ChamberSpec& s) {
  CaseSteps c;
  c.dump_every = std::max(1L, std::lround(s.dump_interval_s / s.timestep_s));
  c.total = std::lround(s.simulated_s / s.timestep_s);
  c.total = ((c.total + c.dump_every - 1) / c.dump_every) * c.dump_every;  // end on a dump
  c.gyration = std::max(8L, std::lround(60.0 / s.speed_rpm / s.timestep_s));
  c.omega_rad_s = 2 * kPi / (static_cast<double>(c.gyration) * s.timestep_s);
  // A restart about every 2 s simulated (at least six per run), on a whole gyration.
  const double period_s = static_cast<double>(c.gyration) * s.timestep_s;
  c.restart_every = c.gyration * std::max(1L, std::lround(std::min(2.0, s.simulated_s / 6.0) / period_s));
  return c;
}

void WriteCase(const ChamberSpec& s, const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir / CaseLayout::kDumpDir, ec);
  fs::create_directories(dir / CaseLayout::kRestartDir, ec);
  if (!fs::is_directory(dir / CaseLayout::kDumpDir))
    throw std::runtime_error("cannot create '" + (dir / CaseLayout::kDumpDir).string() + "'");
  const Heights h = HeightsOf(s);

  WriteAtomically(dir / CaseLayout::kConcaveStl,
                  Stl("concave", {Rings(s.concave, 0.0, s.height_m(), s.mesh_n_z)}, {s.mesh_n_theta}));
  const int mantle_theta = std::max(16, s.mesh_n_theta * 2 / 3);
  const double span = s.mantle.z_max() - s.mantle.z_min();
  const int mantle_bands = std::max(4, static_cast<int>(std::lround(span / 0.25)));
  Profile cap;
  cap.points = {{s.mantle.z_max(), s.mantle.points.back().second}, {h.mantle_apex, 0.06}};
  WriteAtomically(
      dir / CaseLayout::kMantleStl,
      Stl("mantle", {Rings(s.mantle, s.mantle.z_min(), s.mantle.z_max(), mantle_bands), Rings(cap, cap.z_min(), cap.z_max(), 1)},
          {mantle_theta, 16}, s.eccentric_throw_m));  // at phase 0 of the gyration: axis at (+e, 0)
  const double r_top = s.concave.points.back().second;
  Profile hopper;
  hopper.points = {{s.height_m(), r_top}, {h.hopper_top, r_top}};
  WriteAtomically(dir / CaseLayout::kHopperStl, Stl("hopper", {Rings(hopper, s.height_m(), h.hopper_top, 2)}, {48}));

  WriteAtomically(dir / CaseLayout::kInput, Script(s, false));
  WriteAtomically(dir / CaseLayout::kResume, Script(s, true));
  nlohmann::json cj = {{"name", s.name}, {"chamber", ToJson(s)}};
  const CaseSteps st = StepsOf(s);
  cj["steps"] = {
      {"total", st.total}, {"dump_every", st.dump_every}, {"gyration", st.gyration}, {"restart_every", st.restart_every}};
  cj["derived_speed_rpm"] = 60.0 * st.omega_rad_s / (2 * kPi);
  cj["derived"] = {{"closed_side_setting_m", s.closed_side_setting_m()},
                   {"open_side_setting_m", s.open_side_setting_m()},
                   {"rayleigh_time_s", s.rayleigh_time_s()},
                   {"concave_faces", 2 * s.mesh_n_theta * s.mesh_n_z}};
  WriteAtomically(dir / CaseLayout::kCaseJson, cj.dump(2) + "\n");

  std::ostringstream slurm;
  slurm << "#!/bin/bash\n"
        << "# Slurm batch script for the LIGGGHTS case of chamber '" << s.name << "' (written by `linerwatch dem`).\n"
        << "# Submit from this folder: sbatch run.slurm. LIGGGHTS decomposes the box over the MPI ranks;\n"
        << "# beyond ~1 rank per 5-10k particles the communication outweighs the gain.\n"
        << "#SBATCH --job-name=lw-dem-" << s.name << "\n"
        << "#SBATCH --ntasks=8\n#SBATCH --time=04:00:00\n#SBATCH --output=slurm-%j.log\n"
        << "set -euo pipefail\n"
        << "cd \"${SLURM_SUBMIT_DIR:-.}\"\n"
        << "last=$(ls restart/crusher.*.restart 2>/dev/null | sort -t. -k2 -n | tail -n 1 || true)\n"
        << "if [ -n \"$last\" ]; then\n"
        << "  srun liggghts -in " << CaseLayout::kResume << " -var restartfile \"$last\" -log log.slurm-$SLURM_JOB_ID.liggghts\n"
        << "else\n"
        << "  srun liggghts -in " << CaseLayout::kInput << " -log log.slurm-$SLURM_JOB_ID.liggghts\n"
        << "fi\n"
        << "# Then, on any machine with the case folder: linerwatch dem CRUSHER_DIR --work THIS_FOLDER --stage map\n";
  WriteAtomically(dir / CaseLayout::kSlurm, slurm.str());
  WriteAtomically(dir / CaseLayout::kHostfile,
                  "# Open MPI hostfile for running this case over several machines without a scheduler:\n"
                  "#   mpirun --hostfile hostfile.example -np 8 liggghts -in in.crusher\n"
                  "# Every host needs liggghts (Debian: apt install liggghts openmpi-bin) and this folder at the\n"
                  "# same path (a shared file system). One line per host, slots = cores to use there.\n"
                  "node1 slots=4\nnode2 slots=4\n");
}

}  // namespace lw::dem
