// Issue 16 benchmark (maps): what a server start pays per crusher map, against just reading the
// file. Writes an N-face truncated-cone map with a noisy wear field (relative noise ~0.3 per face,
// like a short DEM run) as VTK, then, alternating in one run: (a) LoadWearMap alone (reading and
// parsing the file), (b) LoadWearMap + BuildMapModel (CV-chosen smoothing, as the server does).
// Prints medians and the ratio (b)/(a).
//   lw_bench_map_model [--faces N] [--reps R] [--dir D]   (defaults 1000000, 3, /var/tmp)
#include <algorithm>
#include <chrono>
#include <ctime>
#include <fstream>
#include <sstream>
#include <thread>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "core/map_model.hpp"
#include "unit/core/bundle_fixture.hpp"

namespace {

double Seconds(std::chrono::steady_clock::duration d) {
  return std::chrono::duration<double>(d).count();
}

/// CPU seconds of the whole process (every thread).
double Cpu() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  long faces = 1'000'000;
  int reps = 3;
  int threads = 0;
  std::string dir = "/var/tmp";
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--faces"))
      faces = std::atol(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--reps"))
      reps = std::atoi(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--dir"))
      dir = argv[i + 1];
    else if (!std::strcmp(argv[i], "--threads"))
      threads = std::atoi(argv[i + 1]);
    else {
      std::fprintf(stderr, "usage: lw_bench_map_model [--faces N] [--reps R] [--dir D] [--threads T]\n");
      return 2;
    }
  }
  const int nt = std::max(8, static_cast<int>(std::sqrt(static_cast<double>(faces) / 2.0) * 1.5));
  const int nz = static_cast<int>(std::max(1L, faces / (2L * nt)));
  lw::core::WearMap map = lw::test::ConeMap(
      nt, nz, 1.6, 2.6, [](double z) { return 0.06 + std::pow(1 - z / 3.0, 1.5); }, 3.0);
  std::mt19937 rng(16);
  std::gamma_distribution<double> noise(10.0, 0.1);  // mean 1, sd ~0.32
  for (Eigen::Index i = 0; i < map.wear.size(); ++i) {
    map.wear[i] *= (1 + 0.05 * std::sin(7.0 * map.theta_deg[i] * M_PI / 180.0)) * noise(rng);
  }
  const std::filesystem::path file = std::filesystem::path(dir) / ("lw_bench_map_" + std::to_string(map.face_count()) + ".vtk");
  std::fprintf(stderr, "writing a %zu-face map to %s...\n", map.face_count(), file.c_str());
  lw::core::WriteWearMapVtk(file, map, {{"wear", &map.wear}});
  const auto bytes = std::filesystem::file_size(file);

  lw::core::MapModelOptions options;
  options.threads = threads;
  const int used = threads > 0 ? threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  std::vector<double> t_bytes, t_read, t_model, c_bytes, c_read, c_model;
  lw::core::MapModel last;
  lw::core::WearMap loaded;
  size_t checksum = 0;
  for (int r = 0; r < reps; ++r) {
    auto t0 = std::chrono::steady_clock::now();
    double c0 = Cpu();
    {
      std::ifstream in(file, std::ios::binary);
      std::ostringstream ss;
      ss << in.rdbuf();
      checksum += ss.str().size();
    }
    t_bytes.push_back(Seconds(std::chrono::steady_clock::now() - t0));
    c_bytes.push_back(Cpu() - c0);

    t0 = std::chrono::steady_clock::now();
    c0 = Cpu();
    loaded = lw::core::LoadWearMap(file);
    t_read.push_back(Seconds(std::chrono::steady_clock::now() - t0));
    c_read.push_back(Cpu() - c0);

    t0 = std::chrono::steady_clock::now();
    c0 = Cpu();
    const lw::core::WearMap m2 = lw::core::LoadWearMap(file);
    last = lw::core::BuildMapModel(m2, options);
    t_model.push_back(Seconds(std::chrono::steady_clock::now() - t0));
    c_model.push_back(Cpu() - c0);
    last.map = nullptr;  // m2 goes out of scope
  }
  // The model alone with one thread, on the map already loaded (what the threads buy).
  double one_wall = 0, one_cpu = 0;
  if (used > 1) {
    lw::core::MapModelOptions single = options;
    single.threads = 1;
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = Cpu();
    const lw::core::MapModel m1 = lw::core::BuildMapModel(loaded, single);
    one_wall = Seconds(std::chrono::steady_clock::now() - t0);
    one_cpu = Cpu() - c0;
    checksum += m1.intensity.size();
  }
  std::filesystem::remove(file);
  const double bytes_s = Median(t_bytes), read_s = Median(t_read), model_s = Median(t_model);
  std::printf("faces                          %zu (%d x %d quads), file %.1f MB\n", loaded.face_count(), nt, nz, bytes / 1e6);
  std::printf("                               wall median   CPU median (%d reps, alternated)\n", reps);
  std::printf("read the file's bytes          %8.2f s    %8.2f s\n", bytes_s, Median(c_bytes));
  std::printf("LoadWearMap (read + parse)     %8.2f s    %8.2f s\n", read_s, Median(c_read));
  std::printf("LoadWearMap + BuildMapModel    %8.2f s    %8.2f s   (%d threads)\n", model_s, Median(c_model), used);
  if (used > 1) std::printf("BuildMapModel alone, 1 thread  %8.2f s    %8.2f s\n", one_wall, one_cpu);
  std::printf(
      "  chosen: bandwidth %.4f m along z, %.4f m around, %s, %zu outlier faces capped, %zu CV candidates, %zu local scales\n",
      last.bandwidth_m, last.bandwidth_arc_m, last.local_linear ? "local-linear" : "kernel mean", last.outlier_faces,
      last.cv_curve.size(), last.local_ladder_m.size());
  std::printf("ratio (load + model) / read the bytes   wall %.1f   CPU %.1f\n", model_s / bytes_s,
              Median(c_model) / Median(c_bytes));
  std::printf("ratio (load + model) / LoadWearMap      wall %.2f   CPU %.2f\n", model_s / read_s,
              Median(c_model) / Median(c_read));
  return checksum > 0 ? 0 : 1;
}
