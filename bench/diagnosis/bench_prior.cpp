// Two-campaign benchmark of the prior (docs/wear.md, *Earlier campaigns*) on real LIGGGHTS maps:
// per run of a DEM library and per seed, the map from half the run's windows and the truth from the
// other half (bench/diagnosis/realdem.hpp); campaign 1 lives `--days1` days and is scanned at its
// end (the truth + 0.3 mm noise), campaign 2 lives `--days2` days with no scan of its own, its
// feed moved off-centre in every third case (the pattern broke). Live wear at campaign 2's end,
// with the old liner's scan in history/ and without, against campaign 2's truth: the thinnest
// area's error and band, the per-face RMSE, and the pattern change the sensors learned.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/bundle.hpp"
#include "core/thinnest_area.hpp"
#include "core/time.hpp"
#include "estimate/estimate.hpp"
#include "realdem.hpp"
#include "support/temp_directory.hpp"

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Outcome {
  double err_thin = kNaN;  ///< reported thinnest area - the truth's thinnest area of that size (mm)
  bool in_band = false;
  double rmse = kNaN;  ///< per face, remaining thickness (mm)
  double patch_m = kNaN;
  double change = kNaN;     ///< the prior's learned pattern change (with history only)
  double half_band = kNaN;  ///< the reported band's half-width (mm)
};

/// Live wear of `bundle` at `at` against the truth's remaining thickness per face.
Outcome Measure(const lw::core::Bundle& bundle, lw::core::TimePoint at, const Eigen::VectorXd& truth_rem) {
  const auto model = lw::estimate::CrusherModel::FromBundle(bundle);
  const lw::estimate::WearEstimate est = lw::estimate::Estimate(*model, lw::estimate::SamplesOf(bundle.readings), at);
  Outcome o;
  const lw::core::ReconstructionPlan& plan = est.scan && est.scan->correction.detail.empty() ? est.scan->plan : model->plan;
  const lw::core::ThinnestArea& a = est.areas.liner;
  const double truth_thin = lw::bench::TruthThinnest(plan, est.areas, truth_rem);
  o.err_thin = a.thickness_mm - truth_thin;
  o.in_band = truth_thin >= a.lo_mm - 1e-9 && truth_thin <= a.hi_mm + 1e-9;
  o.patch_m = a.whole_row ? kNaN : a.patch_m;
  o.half_band = a.half_width_mm;
  o.rmse = std::sqrt((est.reconstruction.remaining_mm - truth_rem).squaredNorm() / static_cast<double>(truth_rem.size()));
  if (est.scan && est.scan->prior) o.change = est.scan->prior->change_rel;
  return o;
}

/// Campaign 1's bundle (in `old_dir`) as `dir`/history/c1, its liner installed `shift_days` earlier.
void AddHistory(const std::filesystem::path& old_dir, const std::filesystem::path& dir, double shift_days) {
  namespace fs = std::filesystem;
  const fs::path h = dir / "history" / "c1";
  fs::create_directories(h / "scans");
  std::ifstream in(old_dir / "crusher.json");
  nlohmann::json j = nlohmann::json::parse(in);
  const auto installed = lw::core::ParseIsoTime(j["installed_at"].get<std::string>());
  const auto moved = lw::core::AddDays(*installed, -shift_days);
  j["installed_at"] = lw::core::FormatIsoTime(moved);
  std::ofstream(h / "crusher.json") << j.dump(2);
  for (const auto& e : fs::directory_iterator(old_dir / "scans")) {
    const lw::core::Scan s = lw::core::LoadScan(e.path());
    const auto date = lw::core::AddDays(s.date, -shift_days);
    fs::copy_file(e.path(), h / "scans" / ("scan_" + lw::core::FormatIsoTime(date).substr(0, 10) + ".xyz"));
  }
}

struct Summary {
  std::vector<double> err_alone, err_with, rmse_alone, rmse_with, change;
  int in_alone = 0, in_with = 0, n = 0;
};

void Print(const char* title, const Summary& s) {
  if (s.n == 0) return;
  auto worst = [](const std::vector<double>& v) {
    double w = 0;
    for (double x : v)
      if (std::isfinite(x)) w = std::max(w, std::abs(x));
    return w;
  };
  auto abs_of = [](std::vector<double> v) {
    for (double& x : v) x = std::abs(x);
    return v;
  };
  std::printf(
      "%s (%d cases):\n  thinnest-area |error| median %.1f mm, worst %.1f mm with the prior against %.1f / %.1f mm without;"
      "\n  band holds the truth %d / %d against %d / %d; per-face RMSE median %.1f against %.1f mm (ratio %.2f); pattern"
      " change learned median %.2f\n",
      title, s.n, lw::bench::FiniteMedian(abs_of(s.err_with)), worst(s.err_with), lw::bench::FiniteMedian(abs_of(s.err_alone)),
      worst(s.err_alone), s.in_with, s.n, s.in_alone, s.n, lw::bench::FiniteMedian(s.rmse_with),
      lw::bench::FiniteMedian(s.rmse_alone), lw::bench::FiniteMedian(s.rmse_with) / lw::bench::FiniteMedian(s.rmse_alone),
      lw::bench::FiniteMedian(s.change));
}

}  // namespace

int main(int argc, char** argv) {
  std::string dem_dir, keep;
  int seeds = 6;
  double days1 = 120, days2 = 60, feed = 0.3;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "lw_bench_prior: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--help" || a == "-h") {
      std::printf(
          "usage: lw_bench_prior --dem-dir DIR [--seeds N] [--days1 D] [--days2 D] [--feed A] [--keep DIR]\n"
          "Two campaigns per LIGGGHTS run of DIR (folders with wear_windows.vtk and crusher.json, data/dem*) and seed:\n"
          "campaign 1 scanned at its end (day D1, default 120), campaign 2 live at its end (day D2, default 60) with no\n"
          "scan of its own, its feed moved off-centre by A (default 0.3) in every third seed. Prints live wear with\n"
          "the old liner's scan as the prior (history/) beside the map alone, per case and summed up for the cases\n"
          "where the pattern held and where it broke. Seeds default to 6 per run. --keep DIR keeps each case's second\n"
          "campaign, its history/ included, as DIR/RUN-SEED (a bundle for linerwatch reconstruct).\n");
      return 0;
    }
    if (a == "--dem-dir")
      dem_dir = next();
    else if (a == "--seeds")
      seeds = std::atoi(next().c_str());
    else if (a == "--days1")
      days1 = std::atof(next().c_str());
    else if (a == "--days2")
      days2 = std::atof(next().c_str());
    else if (a == "--feed")
      feed = std::atof(next().c_str());
    else if (a == "--keep")
      keep = next();
    else {
      std::fprintf(stderr, "lw_bench_prior: unknown option '%s' (see --help)\n", a.c_str());
      return 2;
    }
  }
  if (dem_dir.empty() || seeds < 1 || !(days1 > 0) || !(days2 > 0)) {
    std::fprintf(stderr, "lw_bench_prior: --dem-dir DIR is required; --seeds, --days1, --days2 must be positive\n");
    return 2;
  }
  const std::vector<lw::bench::DemRun> runs = lw::bench::LoadDemRuns(dem_dir);
  if (runs.empty()) {
    std::fprintf(stderr, "lw_bench_prior: no folder of %s holds wear_windows.vtk and crusher.json\n", dem_dir.c_str());
    return 1;
  }
  Summary held, broke;
  std::printf("%-22s %4s %5s  %9s %9s  %4s %4s  %7s %7s  %7s %7s  %7s %7s  %6s\n", "run", "seed", "feed", "err_alone", "err_with",
              "in_a", "in_w", "patch_a", "patch_w", "band_a", "band_w", "rmse_a", "rmse_w", "change");
  for (const lw::bench::DemRun& run : runs) {
    for (int k = 0; k < seeds; ++k) {
      const bool changed = k % 3 == 2;
      lw::bench::RealDemSpec s1;
      s1.seed = static_cast<uint64_t>(k + 1);
      s1.days = days1;
      s1.scan_day = days1;
      s1.with_scan = true;
      lw::bench::RealDemSpec s2 = s1;
      s2.days = days2;
      s2.with_scan = false;
      if (changed) {
        s2.feed_amplitude = feed;
        s2.feed_theta_deg = 60.0 + 97.0 * k;
      }
      const lw::bench::RealDemCampaign c1(run, s1), c2(run, s2);
      lw::test::TempDirectory old_dir{"lw-bench-prior-1"}, dir{"lw-bench-prior-2"};
      c1.WriteBundle(old_dir.path());
      c2.WriteBundle(dir.path());
      const lw::core::Bundle alone = lw::core::LoadBundle(dir.path());
      AddHistory(old_dir.path(), dir.path(), days1 + 30);
      const lw::core::Bundle with = lw::core::LoadBundle(dir.path());
      if (!keep.empty()) {
        const std::filesystem::path kept = std::filesystem::path(keep) / (run.name + "-" + std::to_string(k + 1));
        std::filesystem::remove_all(kept);
        std::filesystem::create_directories(kept.parent_path());
        std::filesystem::copy(dir.path(), kept, std::filesystem::copy_options::recursive);
      }
      const auto at = lw::core::AddDays(alone.crusher.installed_at, days2);
      const double new_mm = alone.crusher.thickness_new_mm;
      const Eigen::VectorXd truth_rem = (new_mm - c2.TrueFaceWear(days2).array().min(new_mm)).matrix();
      const Outcome a = Measure(alone, at, truth_rem), w = Measure(with, at, truth_rem);
      std::printf("%-22s %4d %5.2f  %9.1f %9.1f  %4s %4s  %7.2f %7.2f  %7.1f %7.1f  %7.2f %7.2f  %6.3f\n", run.name.c_str(),
                  k + 1, changed ? feed : 0.0, a.err_thin, w.err_thin, a.in_band ? "yes" : "no", w.in_band ? "yes" : "no",
                  a.patch_m, w.patch_m, a.half_band, w.half_band, a.rmse, w.rmse, w.change);
      std::fflush(stdout);
      Summary& sum = changed ? broke : held;
      sum.err_alone.push_back(a.err_thin);
      sum.err_with.push_back(w.err_thin);
      sum.rmse_alone.push_back(a.rmse);
      sum.rmse_with.push_back(w.rmse);
      sum.change.push_back(w.change);
      sum.in_alone += a.in_band;
      sum.in_with += w.in_band;
      ++sum.n;
    }
  }
  Print("pattern held", held);
  Print("feed moved (pattern broke)", broke);
  return 0;
}
