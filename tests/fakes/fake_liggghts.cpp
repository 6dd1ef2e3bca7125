// A stand-in for `mpirun ... liggghts` that `linerwatch dem --mpirun` can run in tests: it reads the
// case's input script (steps, time step, dump and restart intervals), and writes what LIGGGHTS would
// (the log's version line, mass.txt, post/concave_<step>.vtk with cumulative wear and stresses,
// restart/crusher.<step>.restart) in a fraction of a second. The wear per face is a smooth field
// times independent exponential increments per dump interval (relative sd 1 per interval), so a
// map's standard error falls as 1/sqrt(steady time), as sampling noise does. Deterministic: a
// resumed run writes the same dumps a straight one would.
//   Called as: fake_liggghts --bind-to none -np N liggghts -in FILE -log LOG [-var restartfile F]
//   LW_FAKE_LIGGGHTS_WALL_PER_S: wall seconds it takes per simulated second (default 0).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

struct Script {
  double dt = 0;
  long nsteps = 0, dump_every = 0, restart_every = 0, print_every = 0;
};

Script ReadScript(const std::string& file) {
  Script s;
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::string a, b, c, d;
    ls >> a >> b >> c >> d;
    if (a == "variable" && b == "dt") s.dt = std::stod(d);
    if (a == "variable" && b == "nsteps") s.nsteps = std::stol(d);
    if (a == "dump" && b == "dmesh") {
      std::string n;
      ls >> n;  // "dump dmesh all mesh/vtk N ...": a b c d = dump dmesh all mesh/vtk
      s.dump_every = std::stol(n);
    }
    if (a == "restart") s.restart_every = std::stol(b);
    if (a == "fix" && b == "masslog") {
      std::string n;
      ls >> n;  // "fix masslog all print N ..."
      s.print_every = std::stol(n);
    }
  }
  return s;
}

struct Face {
  double v[3][3];
};

std::vector<Face> ReadStl(const std::string& file) {
  std::vector<Face> faces;
  std::ifstream in(file);
  std::string word;
  std::vector<double> xyz;
  while (in >> word) {
    if (word != "vertex") continue;
    double x, y, z;
    in >> x >> y >> z;
    xyz.insert(xyz.end(), {x, y, z});
    if (xyz.size() == 9) {
      Face f;
      for (int k = 0; k < 3; ++k)
        for (int j = 0; j < 3; ++j) f.v[k][j] = xyz[static_cast<size_t>(3 * k + j)];
      faces.push_back(f);
      xyz.clear();
    }
  }
  return faces;
}

/// Exp(1) from (face, interval): the same on every call.
double Increment(size_t face, long interval) {
  uint64_t h =
      (static_cast<uint64_t>(face) + 1) * 0x9E3779B97F4A7C15ULL ^ (static_cast<uint64_t>(interval) + 7) * 0xC2B2AE3D27D4EB4FULL;
  h ^= h >> 31, h *= 0xBF58476D1CE4E5B9ULL, h ^= h >> 27, h *= 0x94D049BB133111EBULL, h ^= h >> 31;
  const double u = (static_cast<double>(h >> 11) + 0.5) / 9007199254740992.0;
  return -std::log(u);
}

constexpr double kFillS = 0.5;

double ChamberMass(double t) {
  return 400.0 * std::min(1.0, t / kFillS) + 4.0 * std::sin(7.0 * t);
}

void WriteDump(const std::string& path, const std::vector<Face>& faces, long step, const Script& s, double height) {
  const long intervals = step / s.dump_every;
  const double interval_s = static_cast<double>(s.dump_every) * s.dt;
  std::ostringstream o;
  o << "# vtk DataFile Version 3.0\nfake liggghts\nASCII\nDATASET POLYDATA\nPOINTS " << 3 * faces.size() << " float\n";
  for (const Face& f : faces)
    for (const auto& v : f.v) o << v[0] << ' ' << v[1] << ' ' << v[2] << '\n';
  o << "POLYGONS " << faces.size() << ' ' << 4 * faces.size() << '\n';
  for (size_t i = 0; i < faces.size(); ++i) o << "3 " << 3 * i << ' ' << 3 * i + 1 << ' ' << 3 * i + 2 << '\n';
  std::vector<double> wear(faces.size(), 0.0), stress(faces.size(), 0.0);
  for (size_t i = 0; i < faces.size(); ++i) {
    const double z = (faces[i].v[0][2] + faces[i].v[1][2] + faces[i].v[2][2]) / 3.0;
    const double rate = 1e-3 * (1.0 + 3.0 * std::pow(1.0 - z / height, 2));
    for (long k = 1; k <= intervals; ++k)  // from the start: a dump at the steady start has wear
      wear[i] += rate * interval_s * Increment(i, k);
    stress[i] = 1e8 * rate * (intervals > 0 ? Increment(i, -intervals) : 0.0);
  }
  o << "CELL_DATA " << faces.size() << '\n';
  for (const char* name : {"wear", "normal_stress_average", "shear_stress_average"}) {
    o << "SCALARS " << name << " double 1\nLOOKUP_TABLE default\n";
    for (size_t i = 0; i < faces.size(); ++i)
      o << (name[0] == 'w' ? wear[i] : name[0] == 'n' ? stress[i] : 0.5 * stress[i]) << '\n';
  }
  std::ofstream(path) << o.str();
}

}  // namespace

int main(int argc, char** argv) {
  std::string input, log, restart;
  for (int i = 1; i + 1 < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-in") input = argv[i + 1];
    if (a == "-log") log = argv[i + 1];
    if (a == "-var" && i + 2 < argc && std::string(argv[i + 1]) == "restartfile") restart = argv[i + 2];
  }
  const Script s = ReadScript(input);
  const std::vector<Face> faces = ReadStl("concave.stl");
  if (s.dt <= 0 || s.nsteps <= 0 || s.dump_every <= 0 || faces.empty()) {
    std::cerr << "fake_liggghts: cannot read " << input << " or concave.stl\n";
    return 1;
  }
  double height = 0;
  for (const Face& f : faces)
    for (const auto& v : f.v) height = std::max(height, v[2]);
  long start = 0;
  if (!restart.empty()) {
    const auto dot = restart.rfind(".restart"), before = restart.rfind('.', dot - 1);
    start = std::stol(restart.substr(before + 1, dot - before - 1));
  }
  std::ofstream(log) << "LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, fake for linerwatch tests)\n";
  std::ofstream mass("mass.txt", restart.empty() ? std::ios::trunc : std::ios::app);
  if (restart.empty()) mass << "t_s n_chamber m_chamber_kg m_hopper_kg m_total_kg m_inserted_kg\n";
  const char* pace = std::getenv("LW_FAKE_LIGGGHTS_WALL_PER_S");
  const double wall_per_s = pace ? std::atof(pace) : 0.0;
  const long print_every = std::max(1L, s.print_every);
  if (restart.empty()) WriteDump("post/concave_0.vtk", faces, 0, s, height);
  for (long step = start + 1; step <= s.nsteps; ++step) {
    const double t = static_cast<double>(step) * s.dt;
    if (step % print_every == 0) {
      const double m = ChamberMass(t), hopper = 100.0;
      mass << t << ' ' << std::lround(m) << ' ' << m << ' ' << hopper << ' ' << m + hopper << ' ' << m + hopper + 100.0 * t
           << '\n';
      mass.flush();
    }
    if (step % s.dump_every == 0) {
      WriteDump("post/concave_" + std::to_string(step) + ".vtk", faces, step, s, height);
      if (wall_per_s > 0)
        std::this_thread::sleep_for(std::chrono::duration<double>(wall_per_s * static_cast<double>(s.dump_every) * s.dt));
    }
    if (s.restart_every > 0 && step % s.restart_every == 0)
      std::ofstream("restart/crusher." + std::to_string(step) + ".restart") << "fake restart\n";
  }
  return 0;
}
