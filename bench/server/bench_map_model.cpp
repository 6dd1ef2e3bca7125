// Issue 16 benchmark (maps): what a server start pays per crusher map, against just reading the
// file. Writes an N-face truncated-cone map with a noisy wear field (relative noise ~0.3 per face,
// like a short DEM run) as VTK, then, alternating in one run: reading the file's bytes,
// LoadWearMap (reading and parsing), LoadWearMap + BuildMapModel (CV-chosen smoothing, as the
// server does: binned kernel sums above MapModelOptions::binned_above_faces); then once each the
// model alone on one thread and face by face (the exact sums, binned_above_faces = max; skipped
// with --no-exact). Prints medians and the ratios. Then on a smaller map (--compare-faces, same
// field) the binned and the face-by-face model, and their differences face by face.
//   lw_bench_map_model [--faces N] [--reps R] [--dir D] [--threads T] [--compare-faces M] [--no-exact]
//   (defaults 1000000, 3, /var/tmp, one per core, 100000)
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
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "core/map_model.hpp"
#include "unit/core/bundle_fixture.hpp"
#include "../bench_stats.hpp"

namespace {

using lw::bench::Median;

double Seconds(std::chrono::steady_clock::duration d) {
  return std::chrono::duration<double>(d).count();
}

/// CPU seconds of the whole process (every thread).
double Cpu() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

double Quantile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  return v[static_cast<size_t>(p * static_cast<double>(v.size() - 1))];
}

/// About `faces` faces of a truncated cone, wear falling along z, a 5 % ripple around and gamma
/// noise (relative sd ~0.32) per face.
lw::core::WearMap NoisyCone(long faces, int& nt, int& nz) {
  nt = std::max(8, static_cast<int>(std::sqrt(static_cast<double>(faces) / 2.0) * 1.5));
  nz = static_cast<int>(std::max(1L, faces / (2L * nt)));
  lw::core::WearMap map = lw::test::ConeMap(
      nt, nz, 1.6, 2.6, [](double z) { return 0.06 + std::pow(1 - z / 3.0, 1.5); }, 3.0);
  std::mt19937 rng(16);
  std::gamma_distribution<double> noise(10.0, 0.1);  // mean 1, sd ~0.32
  for (Eigen::Index i = 0; i < map.wear.size(); ++i) {
    map.wear[i] *= (1 + 0.05 * std::sin(7.0 * map.theta_deg[i] * M_PI / 180.0)) * noise(rng);
  }
  return map;
}

struct Timed {
  double wall = 0, cpu = 0;
};
template <typename Fn>
Timed Time(Fn&& fn) {
  const auto t0 = std::chrono::steady_clock::now();
  const double c0 = Cpu();
  fn();
  return {Seconds(std::chrono::steady_clock::now() - t0), Cpu() - c0};
}

/// The binned path (forced) against the face-by-face path on `small`, face by face.
void CompareBinned(const lw::core::WearMap& small, const lw::core::MapModelOptions& face_by_face) {
  lw::core::MapModelOptions binned = face_by_face;
  binned.binned_above_faces = 0;
  lw::core::MapModel a, b;
  const Timed ta = Time([&] { a = lw::core::BuildMapModel(small, face_by_face); });
  const Timed tb = Time([&] { b = lw::core::BuildMapModel(small, binned); });
  std::vector<double> d_int, d_noise, d_sd;
  size_t other_scale = 0;
  for (Eigen::Index i = 0; i < small.z.size(); ++i) {
    d_int.push_back(std::fabs(a.intensity[i] - b.intensity[i]) / std::max(a.intensity_noise_sd[i], 1e-300));
    d_noise.push_back(std::fabs(b.intensity_noise_sd[i] / a.intensity_noise_sd[i] - 1));
    d_sd.push_back(std::fabs(b.intensity_sd[i] / a.intensity_sd[i] - 1));
    if (a.local_bandwidth_m.size() && a.local_bandwidth_m[i] != b.local_bandwidth_m[i]) ++other_scale;
  }
  std::printf("\ncompare on %zu faces: face by face %.2f s wall %.2f s CPU, binned %.2f s wall %.2f s CPU (%s chosen model)\n",
              small.face_count(), ta.wall, ta.cpu, tb.wall, tb.cpu,
              a.bandwidth_m == b.bandwidth_m && a.local_linear == b.local_linear ? "the same" : "a DIFFERENT");
  std::printf("  |binned - exact| intensity / exact noise sd   median %.3g  p99 %.3g  max %.3g\n", Median(d_int),
              Quantile(d_int, 0.99), Quantile(d_int, 1.0));
  std::printf("  relative difference of intensity_noise_sd     median %.3g  p99 %.3g  max %.3g\n", Median(d_noise),
              Quantile(d_noise, 0.99), Quantile(d_noise, 1.0));
  std::printf("  relative difference of intensity_sd           median %.3g  p99 %.3g  max %.3g\n", Median(d_sd),
              Quantile(d_sd, 0.99), Quantile(d_sd, 1.0));
  std::printf("  faces at another local scale                  %zu of %zu\n", other_scale, small.face_count());
}

}  // namespace

int main(int argc, char** argv) {
  long faces = 1'000'000, compare_faces = 100'000;
  int reps = 3;
  int threads = 0;
  bool exact = true;
  std::string dir = "/var/tmp", compare_map;
  for (int i = 1; i < argc; ++i) {
    const bool has_value = i + 1 < argc;
    if (!std::strcmp(argv[i], "--help")) {
      std::puts(
          "usage: lw_bench_map_model [--faces N] [--reps R] [--dir D] [--threads T] [--compare-faces M] [--no-exact] "
          "[--compare-map FILE]\n"
          "What a server start pays per crusher map against just reading the file: an N-face map (default 1,000,000) "
          "read, parsed, and its map model built, alternating R repetitions in one run; prints medians and ratios, "
          "then the binned against the face-by-face model on M faces (or on a map file) (bench/server/RESULTS.md).");
      return 0;
    }
    if (!std::strcmp(argv[i], "--no-exact")) {
      exact = false;
    } else if (has_value && !std::strcmp(argv[i], "--faces")) {
      faces = std::atol(argv[++i]);
    } else if (has_value && !std::strcmp(argv[i], "--compare-faces")) {
      compare_faces = std::atol(argv[++i]);
    } else if (has_value && !std::strcmp(argv[i], "--compare-map")) {
      compare_map = argv[++i];
    } else if (has_value && !std::strcmp(argv[i], "--reps")) {
      reps = std::atoi(argv[++i]);
    } else if (has_value && !std::strcmp(argv[i], "--dir")) {
      dir = argv[++i];
    } else if (has_value && !std::strcmp(argv[i], "--threads")) {
      threads = std::atoi(argv[++i]);
    } else {
      std::fprintf(stderr,
                   "usage: lw_bench_map_model [--faces N] [--reps R] [--dir D] [--threads T] [--compare-faces M] [--no-exact] "
                   "[--compare-map FILE]\n");
      return 2;
    }
  }
  if (!compare_map.empty()) {
    // Only the comparison, on a map file (e.g. a real LIGGGHTS map, far below the binning threshold).
    lw::core::MapModelOptions face_by_face;
    face_by_face.threads = threads;
    face_by_face.binned_above_faces = std::numeric_limits<size_t>::max();
    CompareBinned(lw::core::LoadWearMap(compare_map), face_by_face);
    return 0;
  }
  if (faces < 100 || reps < 1) {
    std::fprintf(stderr, "lw_bench_map_model: --faces must be >= 100 and --reps >= 1\n");
    return 2;
  }
  int nt = 0, nz = 0;
  lw::core::WearMap map = NoisyCone(faces, nt, nz);
  const std::filesystem::path file = std::filesystem::path(dir) / ("lw_bench_map_" + std::to_string(map.face_count()) + ".vtk");
  std::fprintf(stderr, "writing a %zu-face map to %s...\n", map.face_count(), file.c_str());
  lw::core::WriteWearMapVtk(file, map, {{"wear", &map.wear}});
  const auto bytes = std::filesystem::file_size(file);

  lw::core::MapModelOptions options;
  options.threads = threads;
  lw::core::MapModelOptions face_by_face = options;
  face_by_face.binned_above_faces = std::numeric_limits<size_t>::max();
  const int used = threads > 0 ? threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  std::vector<double> t_bytes, t_read, t_model, c_bytes, c_read, c_model;
  lw::core::MapModel last;
  lw::core::WearMap loaded;
  size_t checksum = 0;
  for (int r = 0; r < reps; ++r) {
    Timed t = Time([&] {
      std::ifstream in(file, std::ios::binary);
      std::ostringstream ss;
      ss << in.rdbuf();
      checksum += ss.str().size();
    });
    t_bytes.push_back(t.wall);
    c_bytes.push_back(t.cpu);
    t = Time([&] { loaded = lw::core::LoadWearMap(file); });
    t_read.push_back(t.wall);
    c_read.push_back(t.cpu);
    t = Time([&] {
      const lw::core::WearMap m2 = lw::core::LoadWearMap(file);
      last = lw::core::BuildMapModel(m2, options);
      last.map = nullptr;  // m2 goes out of scope
    });
    t_model.push_back(t.wall);
    c_model.push_back(t.cpu);
  }
  std::filesystem::remove(file);
  // The model alone: on one thread (what the threads buy), and face by face (the exact sums).
  const Timed one = Time([&] {
    lw::core::MapModelOptions single = options;
    single.threads = 1;
    checksum += lw::core::BuildMapModel(loaded, single).intensity.size();
  });
  Timed fbf;
  if (exact) fbf = Time([&] { checksum += lw::core::BuildMapModel(loaded, face_by_face).intensity.size(); });
  const bool binned_used = loaded.face_count() > options.binned_above_faces;
  const double bytes_s = Median(t_bytes), read_s = Median(t_read), model_s = Median(t_model);
  const double bytes_c = Median(c_bytes), read_c = Median(c_read), model_c = Median(c_model);
  std::printf("faces                          %zu (%d x %d quads), file %.1f MB; model %s\n", loaded.face_count(), nt, nz,
              bytes / 1e6, binned_used ? "binned (above binned_above_faces)" : "face by face (at or below binned_above_faces)");
  std::printf("                               wall median   CPU median (%d reps, alternated)\n", reps);
  std::printf("read the file's bytes          %8.2f s    %8.2f s\n", bytes_s, bytes_c);
  std::printf("LoadWearMap (read + parse)     %8.2f s    %8.2f s\n", read_s, read_c);
  std::printf("LoadWearMap + BuildMapModel    %8.2f s    %8.2f s   (%d threads)\n", model_s, model_c, used);
  std::printf("BuildMapModel alone, 1 thread  %8.2f s    %8.2f s\n", one.wall, one.cpu);
  if (exact)
    std::printf("BuildMapModel face by face     %8.2f s    %8.2f s   (%d threads, binned_above_faces = max)\n", fbf.wall, fbf.cpu,
                used);
  std::printf(
      "  chosen: bandwidth %.4f m along z, %.4f m around, %s, %zu outlier faces capped, %zu CV candidates, %zu local scales\n",
      last.bandwidth_m, last.bandwidth_arc_m, last.local_linear ? "local-linear" : "kernel mean", last.outlier_faces,
      last.cv_curve.size(), last.local_ladder_m.size());
  std::printf("ratio (load + model) / read the bytes   wall %.1f   CPU %.1f\n", model_s / bytes_s, model_c / bytes_c);
  std::printf("ratio (load + model) / LoadWearMap      wall %.2f   CPU %.2f\n", model_s / read_s, model_c / read_c);
  if (exact) std::printf("ratio face by face / (load + model)     wall %.1f   CPU %.1f\n", fbf.wall / model_s, fbf.cpu / model_c);

  // The binned sums against the face-by-face ones on a smaller map (the same field).
  if (compare_faces >= 100) {
    int ct = 0, cz = 0;
    CompareBinned(NoisyCone(compare_faces, ct, cz), face_by_face);
  }
  return checksum > 0 ? 0 : 1;
}
