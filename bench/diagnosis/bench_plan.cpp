// Checks `linerwatch plan`'s advice (docs/plan.md) on real LIGGGHTS maps: per run of a DEM library
// and per seed, the map from half the run's windows and the truth from the other half
// (bench/diagnosis/realdem.hpp); the same campaign read by three layouts of K sensors (K = the
// crusher.json layout's): crusher.json's, the plan's, and a random one (uniform in each row's
// z-range less the margin, and around). Live wear at the campaign's end: the band the live wear
// reports (its thinnest area's half-width, the liner's and each row's mean) and whether it holds the
// truth, per layout.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "core/bundle.hpp"
#include "core/thinnest_area.hpp"
#include "core/time.hpp"
#include "estimate/estimate.hpp"
#include "estimate/plan.hpp"
#include "realdem.hpp"
#include "support/temp_directory.hpp"

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Outcome {
  double half_band = kNaN;  ///< the liner's thinnest area: half its band (mm)
  double row_half = kNaN;   ///< mean over rows of their thinnest area's half band (mm)
  double err = kNaN;        ///< reported - the truth's thinnest area of that size (mm)
  bool in_band = false;
  std::string detail;  ///< --detail: where the area is, the band's parts, the truth there and at its own thinnest
};

/// `run` with its sensors at `layout` (the ids of crusher.json's, in order).
lw::bench::DemRun WithLayout(const lw::bench::DemRun& run, const std::vector<lw::estimate::PlannedSensor>& layout) {
  lw::bench::DemRun r = run;
  for (size_t i = 0; i < layout.size() && i < r.crusher.sensors.size(); ++i) {
    r.crusher.sensors[i].row = layout[i].row;
    r.crusher.sensors[i].z_m = layout[i].z_m;
    r.crusher.sensors[i].theta_deg = layout[i].theta_deg;
  }
  return r;
}

/// The campaign of `run` (its sensors as laid out there) written to `dir`, crusher.json's sensors
/// replaced by the run's, then live wear at its end against its truth.
Outcome Measure(const lw::bench::DemRun& run, const lw::bench::RealDemSpec& spec, const std::filesystem::path& dir) {
  const lw::bench::RealDemCampaign c(run, spec);
  c.WriteBundle(dir);
  std::ifstream in(dir / "crusher.json");
  nlohmann::json j = nlohmann::json::parse(in);
  in.close();
  for (size_t i = 0; i < run.crusher.sensors.size(); ++i) {
    j["sensors"][i]["row"] = run.crusher.sensors[i].row;
    j["sensors"][i]["z_m"] = run.crusher.sensors[i].z_m;
    j["sensors"][i]["theta_deg"] = run.crusher.sensors[i].theta_deg;
  }
  std::ofstream(dir / "crusher.json") << j.dump(2);
  const lw::core::Bundle b = lw::core::LoadBundle(dir);
  const auto model = lw::estimate::CrusherModel::FromBundle(b);
  const auto at = lw::core::AddDays(b.crusher.installed_at, spec.days);
  lw::estimate::EstimateOptions options;
  options.use_scans = false;
  const lw::estimate::WearEstimate est = lw::estimate::Estimate(*model, lw::estimate::SamplesOf(b.readings), at, options);
  const double new_mm = b.crusher.thickness_new_mm;
  const Eigen::VectorXd truth_rem = (new_mm - c.TrueFaceWear(spec.days).array().min(new_mm)).matrix();
  Outcome o;
  const lw::core::ThinnestArea& a = est.areas.liner;
  const double truth_thin = lw::bench::TruthThinnest(model->plan, est.areas, truth_rem);
  o.half_band = a.half_width_mm;
  o.err = a.thickness_mm - truth_thin;
  o.in_band = truth_thin >= a.lo_mm - 1e-9 && truth_thin <= a.hi_mm + 1e-9;
  // The error's two parts: the estimate against the truth over the reported area, and the truth
  // there against the truth's own thinnest area of that size (elsewhere when the hot spot moved).
  const lw::core::ThinnestArea t = a.whole_row ? a : lw::core::ThinnestPatchOf(model->plan, truth_rem, -1, a.patch_m, a.shape);
  const double here = lw::core::AreaMean(model->plan, truth_rem, a);
  std::string per_row;
  for (const lw::core::Row& row : b.crusher.rows) {
    int k = 0;
    for (const auto& x : b.crusher.sensors) k += x.row == row.name;
    per_row += " " + row.name + ":" + std::to_string(k);
  }
  char line[400];
  std::snprintf(line, sizeof line,
                "area %s z %.2f th %.0f patch %.2f%s | est %.1f truth there %.1f (est-truth %.1f) truth thinnest %.1f at %s z "
                "%.2f th %.0f | sd scale %.1f map %.1f x%.1f, %zu row sensors, nearest %.2f m%s | sensors%s",
                a.row.c_str(), a.z_m, a.theta_deg, a.patch_m, a.whole_row ? " (row)" : "", a.thickness_mm, here,
                a.thickness_mm - here, truth_thin, t.row.c_str(), t.z_m, t.theta_deg, a.scale_sd_mm, a.map_sd_mm,
                a.half_width_mm / std::max(1e-9, std::hypot(a.scale_sd_mm, a.map_sd_mm)), a.row_sensors, a.nearest_sensor_m,
                a.extrapolated ? " (extrapolated)" : "", per_row.c_str());
  o.detail = line;
  double sum = 0;
  for (const auto& row : est.areas.rows) sum += row.half_width_mm;
  o.row_half = est.areas.rows.empty() ? kNaN : sum / static_cast<double>(est.areas.rows.size());
  return o;
}

}  // namespace

int main(int argc, char** argv) {
  std::string dem_dir;
  int seeds = 4;
  double days = 90;
  bool detail = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "lw_bench_plan: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--help" || a == "-h") {
      std::printf(
          "usage: lw_bench_plan --dem-dir DIR [--seeds N] [--days D] [--detail]\n"
          "Checks linerwatch plan's advice on each LIGGGHTS run of DIR (folders with wear_windows.vtk and\n"
          "crusher.json, data/dem*): per seed (default 4) one campaign of D days (default 90), no scan, read by\n"
          "three layouts of as many sensors as crusher.json has: crusher.json's, the plan's, a random one.\n"
          "Prints, per case and in sum, the band live wear reports at the end (the liner's thinnest area and\n"
          "the rows' mean half-width) and whether the truth (independent windows) lies inside it.\n"
          "--detail adds, per layout, where the reported area is, the band's parts (row scale, map; one sd),\n"
          "the truth over that area and where the truth's own thinnest area is, and the sensors per row.\n");
      return 0;
    }
    if (a == "--dem-dir")
      dem_dir = next();
    else if (a == "--seeds")
      seeds = std::atoi(next().c_str());
    else if (a == "--days")
      days = std::atof(next().c_str());
    else if (a == "--detail")
      detail = true;
    else {
      std::fprintf(stderr, "lw_bench_plan: unknown option '%s' (see --help)\n", a.c_str());
      return 2;
    }
  }
  if (dem_dir.empty() || seeds < 1 || !(days > 0)) {
    std::fprintf(stderr, "lw_bench_plan: --dem-dir DIR is required; --seeds and --days must be positive\n");
    return 2;
  }
  const std::vector<lw::bench::DemRun> runs = lw::bench::LoadDemRuns(dem_dir);
  if (runs.empty()) {
    std::fprintf(stderr, "lw_bench_plan: no folder of %s holds wear_windows.vtk and crusher.json\n", dem_dir.c_str());
    return 1;
  }
  const char* names[3] = {"crusher.json", "plan", "random"};
  std::vector<double> liner[3], rows[3], err[3];
  int held[3] = {0, 0, 0}, n = 0, plan_narrower = 0, plan_narrower_random = 0;
  std::printf("%-22s %4s  %-12s %9s %9s %7s %5s\n", "run", "seed", "layout", "liner_+-", "rows_+-", "err", "in");
  for (const lw::bench::DemRun& run : runs) {
    for (int k = 0; k < seeds; ++k) {
      lw::bench::RealDemSpec spec;
      spec.seed = static_cast<uint64_t>(k + 1);
      spec.days = days;
      spec.with_scan = false;
      // The plan, from the map this seed's split makes (a bundle of crusher.json's layout).
      lw::test::TempDirectory d0{"lw-bench-plan"}, d1{"lw-bench-plan"}, d2{"lw-bench-plan"};
      const Outcome current = Measure(run, spec, d0.path());
      const lw::core::Bundle b = lw::core::LoadBundle(d0.path());
      const auto model = lw::estimate::CrusherModel::FromBundle(b);
      lw::estimate::PlanOptions options;
      options.sensors = run.crusher.sensors.size();
      const lw::estimate::SensorPlan plan = lw::estimate::PlanSensors(*model, options);
      // A random layout: the same number per row as the plan, uniform inside each row's margins.
      std::mt19937_64 rng(static_cast<uint64_t>(1000 + k));
      std::vector<lw::estimate::PlannedSensor> random = plan.sensors;
      for (lw::estimate::PlannedSensor& s : random) {
        const lw::core::Row& row = b.crusher.rows[static_cast<size_t>(b.crusher.RowIndex(s.row))];
        const double lo = row.z_min_m + options.edge_margin_m, hi = std::max(lo, row.z_max_m - options.edge_margin_m);
        s.z_m = std::uniform_real_distribution<double>(lo, hi)(rng);
        s.theta_deg = std::uniform_real_distribution<double>(0.0, 360.0)(rng);
      }
      const Outcome planned = Measure(WithLayout(run, plan.sensors), spec, d1.path());
      const Outcome randomly = Measure(WithLayout(run, random), spec, d2.path());
      const Outcome* all[3] = {&current, &planned, &randomly};
      for (int l = 0; l < 3; ++l) {
        std::printf("%-22s %4d  %-12s %9.1f %9.1f %7.1f %5s\n", run.name.c_str(), k + 1, names[l], all[l]->half_band,
                    all[l]->row_half, all[l]->err, all[l]->in_band ? "yes" : "no");
        if (detail) std::printf("    %s\n", all[l]->detail.c_str());
        liner[l].push_back(all[l]->half_band);
        rows[l].push_back(all[l]->row_half);
        err[l].push_back(std::abs(all[l]->err));
        held[l] += all[l]->in_band;
      }
      plan_narrower += planned.row_half < current.row_half;
      plan_narrower_random += planned.row_half < randomly.row_half;
      ++n;
      std::fflush(stdout);
    }
  }
  for (int l = 0; l < 3; ++l) {
    std::printf(
        "%-12s: liner band +/- %.1f mm median, rows' mean +/- %.1f mm median, |error| median %.1f mm, truth inside %d / %d\n",
        names[l], lw::bench::FiniteMedian(liner[l]), lw::bench::FiniteMedian(rows[l]), lw::bench::FiniteMedian(err[l]), held[l],
        n);
  }
  std::printf("the plan's rows' band narrower than crusher.json's in %d / %d cases, than the random layout's in %d / %d\n",
              plan_narrower, n, plan_narrower_random, n);
  return 0;
}
