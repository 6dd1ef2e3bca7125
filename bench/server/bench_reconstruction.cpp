// Issue 4 benchmark (b): one Eq. 9 reconstruction of a 1,000,000-face map, against a memory-bound
// copy of the same arrays (the per-face inputs it reads, into fresh outputs), side by side in one
// run. Target: ratio <= 2. The plan (map smoothing) is prepared once per map and not timed. Prints medians of alternating
// repetitions.
//   lw_bench_reconstruction [--faces N] [--reps R]
#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "core/reconstruction.hpp"
#include "unit/core/bundle_fixture.hpp"
#include "../bench_stats.hpp"

namespace {

using lw::bench::Median;

double Seconds(std::chrono::steady_clock::duration d) {
  return std::chrono::duration<double>(d).count();
}

/// A truncated-cone concave (radius 1.6 -> 2.6 m over 3 m), the reference profile with a mild
/// ripple around.
lw::core::WearMap Cone(int nt, int nz) {
  lw::core::WearMap m = lw::test::ConeMap(
      nt, nz, 1.6, 2.6, [](double z) { return 0.06 + std::pow(1 - z / 3.0, 1.5); }, 3.0);
  for (Eigen::Index i = 0; i < m.wear.size(); ++i) m.wear[i] *= 1 + 0.05 * std::sin(7.0 * m.theta_deg[i] * M_PI / 180.0);
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  long faces = 1'000'000;
  int reps = 7;
  if (argc == 2 && !std::strcmp(argv[1], "--help")) {
    std::puts(
        "usage: lw_bench_reconstruction [--faces N] [--reps R]\n"
        "One Eq. 9 reconstruction of an N-face map (default 1,000,000) against a memory-bound copy of the arrays it\n"
        "reads, alternating R repetitions (default 7) in one run; prints both medians and their ratio (target <= 2).\n"
        "The plan (the map's smoothing and the sensors' reach) is prepared once and not timed.");
    return 0;
  }
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--faces"))
      faces = std::atol(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--reps"))
      reps = std::atoi(argv[i + 1]);
    else {
      std::fprintf(stderr, "usage: lw_bench_reconstruction [--faces N] [--reps R]\n");
      return 2;
    }
  }
  const int nt = 1000, nz = static_cast<int>(std::max(1L, faces / (2 * nt)));
  std::fprintf(stderr, "building a %d-face map...\n", 2 * nt * nz);
  const lw::core::WearMap map = Cone(nt, nz);
  lw::core::CrusherConfig crusher;
  crusher.crusher_id = "bench";
  crusher.thickness_new_mm = 120;
  crusher.thickness_min_mm = 30;
  crusher.rows = {{"LDWN", 0, 1}, {"LMID", 1, 2}, {"LUP", 2, 3}};
  std::vector<lw::core::SensorWear> wear;
  for (int s = 0; s < 10; ++s) {
    const std::string row = s < 4 ? "LDWN" : s < 8 ? "LMID" : "LUP";
    const double z = s < 4 ? 0.5 : s < 8 ? 1.5 : 2.5;
    crusher.sensors.push_back({std::to_string(1001 + s), row, z, 36.0 * s, 120, std::nullopt});
    wear.push_back({std::to_string(1001 + s), 80.0 - 25.0 * z});
  }
  std::fprintf(stderr, "preparing the plan (smoothing, once per map)...\n");
  const auto t_plan = std::chrono::steady_clock::now();
  const lw::core::ReconstructionPlan plan = lw::core::PrepareReconstruction(crusher, map);
  const double plan_s = Seconds(std::chrono::steady_clock::now() - t_plan);

  const Eigen::Index n = static_cast<Eigen::Index>(map.face_count());
  std::vector<double> t_rec, t_fresh, t_copy;
  lw::core::Reconstruction reused = lw::core::Reconstruct(plan, wear);  // arrays allocated once
  double sink = 0;
  // The copy's outputs are allocated (and faulted in) once, outside the timing: the floor is the
  // bandwidth alone. The reconstruction allocates its two outputs inside its timing.
  Eigen::VectorXd a(n), b(n), c(n);
  std::vector<int> d(static_cast<size_t>(n));
  a.setZero();
  b.setZero();
  c.setZero();
  for (int r = 0; r < reps; ++r) {
    auto t0 = std::chrono::steady_clock::now();
    lw::core::ReconstructInto(plan, wear, &reused);
    t_rec.push_back(Seconds(std::chrono::steady_clock::now() - t0));
    sink += reused.min_thickness_mm;

    t0 = std::chrono::steady_clock::now();
    const lw::core::Reconstruction fresh = lw::core::Reconstruct(plan, wear);
    t_fresh.push_back(Seconds(std::chrono::steady_clock::now() - t0));
    sink += fresh.min_thickness_mm;

    // The floor: read every per-face input the reconstruction reads (intensity, z, row, area)
    // and write as many fresh per-face outputs.
    t0 = std::chrono::steady_clock::now();
    std::memcpy(a.data(), plan.intensity.data(), sizeof(double) * static_cast<size_t>(n));
    std::memcpy(b.data(), map.z.data(), sizeof(double) * static_cast<size_t>(n));
    std::memcpy(c.data(), map.areas.data(), sizeof(double) * static_cast<size_t>(n));
    std::memcpy(d.data(), plan.face_row.data(), sizeof(int) * static_cast<size_t>(n));
    t_copy.push_back(Seconds(std::chrono::steady_clock::now() - t0));
    sink += a[n / 2] + b[n / 3] + c[n / 4] + d[static_cast<size_t>(n / 5)];
  }
  const double rec_s = Median(t_rec), copy_s = Median(t_copy);
  std::printf("faces                      %ld\n", static_cast<long>(n));
  std::printf("plan (smoothing, once)     %.3f s\n", plan_s);
  std::printf("reconstruction  median     %.2f ms  (%d reps, into reused arrays: ReconstructInto)\n", rec_s * 1e3, reps);
  std::printf("  with fresh arrays        %.2f ms  (Reconstruct: allocation and page faults included)\n", Median(t_fresh) * 1e3);
  std::printf("memory-bound copy median   %.2f ms  (intensity, z, area, row -> preallocated arrays)\n", copy_s * 1e3);
  std::printf("ratio reconstruction/copy  %.2f   (target <= 2)   %s\n", rec_s / copy_s, rec_s / copy_s <= 2 ? "MET" : "MISSED");
  std::printf("ratio fresh/copy           %.2f\n", Median(t_fresh) / copy_s);
  std::fprintf(stderr, "(checksum %.3f)\n", sink);
  return 0;
}
