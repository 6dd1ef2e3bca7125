// An earlier campaign's end-of-life scan as the next liner's prior for the wear pattern (bundle
// history/, docs/wear.md *Earlier campaigns*): on a DEM map wrong around the ring, the prior brings
// live wear closer to the truth than the map alone; where the ore changed the pattern, this liner's
// sensors say so and the prior counts less.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "core/bundle.hpp"
#include "core/scan_correction.hpp"
#include "core/time.hpp"
#include "estimate/estimate.hpp"
#include "support/temp_directory.hpp"
#include "unit/cli/run_cli.hpp"
#include "unit/diagnosis/synthetic_bundle.hpp"

#include <CppUTest/TestHarness.h>  // last: its leak-detection macros clash with std headers

namespace fs = std::filesystem;
using namespace lw;

namespace {

constexpr double kDays = 40;

/// The synthetic crusher: a DEM map 25 % noisy per face and 40 % wrong in a smooth pattern around
/// the ring (the same map for every campaign: the same seed).
test::SyntheticSpec Spec(double days, bool scan) {
  test::SyntheticSpec s;
  s.seed = 7;
  s.days = days;
  s.map_noise = 0.25;
  s.map_smooth_error = 0.4;
  s.with_scan = scan;
  s.with_normal_stress = false;
  return s;
}

/// Campaign 1 (60 days, scanned at its end) moved into `dir`/history/c1 as a liner installed 200
/// days before the bundle's, its scan dated accordingly.
void AddHistory(const fs::path& dir, const test::SyntheticSpec& old_liner) {
  test::TempDirectory tmp{"lw-prior-old"};
  test::WriteSyntheticBundle(tmp.path(), old_liner);
  const fs::path h = dir / "history" / "c1";
  fs::create_directories(h / "scans");
  std::ifstream in(tmp.path() / "crusher.json");
  std::stringstream text;
  text << in.rdbuf();
  std::string json = text.str();
  const std::string from = "\"installed_at\": \"2024-01-01T00:00:00Z\"";
  CHECK(json.find(from) != std::string::npos);
  json.replace(json.find(from), from.size(), "\"installed_at\": \"2023-06-15T00:00:00Z\"");
  std::ofstream(h / "crusher.json") << json;
  for (const auto& e : fs::directory_iterator(tmp.path() / "scans")) fs::copy_file(e.path(), h / "scans" / "scan_2023-08-14.xyz");
}

/// Per-face RMSE of live wear at the campaign's end against the truth there (a 0.3 mm scan of it).
double LiveWearRmse(const core::Bundle& bundle, const core::Bundle& truth, std::optional<estimate::PriorCheck>* prior) {
  const auto model = estimate::CrusherModel::FromBundle(bundle);
  const auto at = bundle.crusher.installed_at + std::chrono::hours(static_cast<int>(24 * kDays));
  const estimate::WearEstimate est = estimate::Estimate(*model, estimate::SamplesOf(bundle.readings), at);
  if (prior) *prior = est.scan ? est.scan->prior : std::nullopt;
  const core::ScanFaces t = core::ProjectScanToFaces(bundle.map, truth.scans.at(0));
  double sum = 0;
  size_t n = 0;
  for (Eigen::Index i = 0; i < t.wear_mm.size(); ++i) {
    if (!std::isfinite(t.wear_mm[i])) continue;
    const double d = est.reconstruction.wear_mm[i] - t.wear_mm[i];
    sum += d * d;
    ++n;
  }
  CHECK(n > 1000);
  return std::sqrt(sum / static_cast<double>(n));
}

}  // namespace

TEST_GROUP(Prior){};

TEST(Prior, LastLinersScanBringsLiveWearCloserToTheTruthWhereThePatternHeld) {
  test::TempDirectory dir{"lw-prior"}, truth_dir{"lw-prior-truth"};
  test::WriteSyntheticBundle(dir.path(), Spec(kDays, false));
  test::WriteSyntheticBundle(truth_dir.path(), Spec(kDays, true));
  const core::Bundle truth = core::LoadBundle(truth_dir.path());
  const core::Bundle alone = core::LoadBundle(dir.path());
  AddHistory(dir.path(), Spec(60, true));
  const core::Bundle with = core::LoadBundle(dir.path());
  LONGS_EQUAL(1, with.history.size());
  STRCMP_EQUAL("c1", with.history[0].name.c_str());

  std::optional<estimate::PriorCheck> none, check;
  const double rmse_alone = LiveWearRmse(alone, truth, &none);
  const double rmse_with = LiveWearRmse(with, truth, &check);
  CHECK_FALSE(none.has_value());
  CHECK(check.has_value());
  UT_PRINT(("live wear RMSE per face vs truth: map alone " + std::to_string(rmse_alone) + " mm, with the prior " +
            std::to_string(rmse_with) + " mm; pattern change " + std::to_string(check->change_rel) + ", spread around prior " +
            std::to_string(check->spread_prior_rel) + ", around map " + std::to_string(check->spread_map_rel))
               .c_str());
  CHECK_TEXT(rmse_with < 0.6 * rmse_alone, (std::to_string(rmse_with) + " vs " + std::to_string(rmse_alone)).c_str());
  // The sensors agree with the old liner's pattern better than with the map's.
  CHECK(check->sensors >= 6);
  CHECK_TEXT(check->spread_prior_rel <= check->spread_map_rel,
             (std::to_string(check->spread_prior_rel) + " vs " + std::to_string(check->spread_map_rel)).c_str());
  CHECK(check->change_rel < estimate::PriorCheck::kPriorChange0);

  // The same scan in scans/, dated before this liner's installation: a previous liner's, so the
  // prior, not this liner's own scan.
  test::TempDirectory plain{"lw-prior-plain"};
  test::WriteSyntheticBundle(plain.path(), Spec(kDays, false));
  fs::create_directories(plain.path() / "scans");
  for (const auto& e : fs::directory_iterator(dir.path() / "history" / "c1" / "scans"))
    fs::copy_file(e.path(), plain.path() / "scans" / e.path().filename());
  std::optional<estimate::PriorCheck> from_scans;
  const double rmse_scans = LiveWearRmse(core::LoadBundle(plain.path()), truth, &from_scans);
  CHECK(from_scans.has_value());
  DOUBLES_EQUAL(rmse_with, rmse_scans, 1e-9);

  // The CLI says which prior it used and how far it trusts it.
  const test::CliRun r = test::RunLinerwatch({"reconstruct", dir.path().string()});
  LONGS_EQUAL_TEXT(0, r.code, r.err.c_str());
  CHECK_TEXT(r.out.find("the prior is campaign c1's end-of-life scan") != std::string::npos, r.out.c_str());
  CHECK_TEXT(r.out.find("scan history/c1/scans/scan_2023-08-14.xyz (") != std::string::npos, r.out.c_str());
}

TEST(Prior, ChangedOreRaisesThePatternChangeAndAScanOfThisLinerWins) {
  test::TempDirectory same{"lw-prior-same"}, changed{"lw-prior-changed"}, scanned{"lw-prior-scanned"};
  test::WriteSyntheticBundle(same.path(), Spec(kDays, false));
  test::SyntheticSpec ore = Spec(kDays, false);
  ore.feed_amplitude = 0.4;  // this liner's feed is off-centre: its pattern around the ring moved
  test::WriteSyntheticBundle(changed.path(), ore);
  test::WriteSyntheticBundle(scanned.path(), Spec(kDays, true));
  for (const fs::path& d : {same.path(), changed.path(), scanned.path()}) AddHistory(d, Spec(60, true));
  const auto prior_of = [](const fs::path& d) {
    const core::Bundle b = core::LoadBundle(d);
    const auto model = estimate::CrusherModel::FromBundle(b);
    const auto at = b.crusher.installed_at + std::chrono::hours(static_cast<int>(24 * kDays));
    const estimate::WearEstimate est = estimate::Estimate(*model, estimate::SamplesOf(b.readings), at);
    CHECK(est.scan != nullptr);
    return est.scan->prior;
  };
  const std::optional<estimate::PriorCheck> held = prior_of(same.path()), moved = prior_of(changed.path());
  CHECK(held && moved);
  UT_PRINT(("pattern change: held " + std::to_string(held->change_rel) + " (spread " + std::to_string(held->spread_prior_rel) +
            "), feed moved " + std::to_string(moved->change_rel) + " (spread " + std::to_string(moved->spread_prior_rel) + ")")
               .c_str());
  CHECK_TEXT(moved->spread_prior_rel > 3 * held->spread_prior_rel + 0.05,
             (std::to_string(moved->spread_prior_rel) + " vs " + std::to_string(held->spread_prior_rel)).c_str());
  CHECK_TEXT(moved->change_rel > held->change_rel + 0.05,
             (std::to_string(moved->change_rel) + " vs " + std::to_string(held->change_rel)).c_str());
  // Where the pattern moved, the prior's weight falls: live wear is no worse than the map's alone.
  test::TempDirectory changed_alone{"lw-prior-changed-alone"}, changed_truth{"lw-prior-changed-truth"};
  test::WriteSyntheticBundle(changed_alone.path(), ore);
  test::SyntheticSpec ore_truth = ore;
  ore_truth.with_scan = true;
  test::WriteSyntheticBundle(changed_truth.path(), ore_truth);
  const core::Bundle truth = core::LoadBundle(changed_truth.path());
  const double rmse_alone = LiveWearRmse(core::LoadBundle(changed_alone.path()), truth, nullptr);
  const double rmse_with = LiveWearRmse(core::LoadBundle(changed.path()), truth, nullptr);
  UT_PRINT(("feed moved: live wear RMSE per face, map alone " + std::to_string(rmse_alone) + " mm, with the prior " +
            std::to_string(rmse_with) + " mm")
               .c_str());
  CHECK_TEXT(rmse_with <= 1.05 * rmse_alone, (std::to_string(rmse_with) + " vs " + std::to_string(rmse_alone)).c_str());
  // A scan of this liner is its own truth: the earlier liner's is not used.
  CHECK_FALSE(prior_of(scanned.path()).has_value());
}
