// The stages of Diagnose() (diagnosis/src/stage_*.hpp) through their headers: each stage's typed
// result on a small synthetic campaign (a null one and one with strong work hardening, built once),
// and the stages' pure parts on hand-made inputs.
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "core/bundle.hpp"
#include "scan_craters.hpp"
#include "stage_baseline.hpp"
#include "stage_findings.hpp"
#include "stage_folds.hpp"
#include "stage_hypotheses.hpp"
#include "stage_mismatch.hpp"
#include "stage_predictions.hpp"
#include "stage_regions.hpp"
#include "stage_report.hpp"
#include "stage_setup.hpp"
#include "support/temp_directory.hpp"
#include "unit/diagnosis/synthetic_bundle.hpp"

// CppUTest last: its leak-detector macros redefine new.
#include <CppUTest/TestHarness.h>

namespace {

namespace d = lw::diagnosis::detail;

// One campaign run through the stages up to the mismatch test (and, when `full`, all of them).
struct Run {
  lw::core::Bundle bundle;
  lw::diagnosis::DiagnoseOptions options;
  lw::diagnosis::DiagnosisResult result;
  d::ProblemSetup setup;
  std::vector<double> scan_sigma_before;  ///< scan cells' sigma before the noise model
  d::Baseline base;
  d::NoiseModel noise;
  std::vector<d::Fold> folds;
  d::NullModel null;
  d::Hypotheses hyp;
};

std::unique_ptr<Run> Build(const lw::test::SyntheticSpec& spec, bool full) {
  auto r = std::make_unique<Run>();
  const lw::test::TempDirectory tmp("lw-diag-stages");
  lw::test::WriteSyntheticBundle(tmp.path(), spec);
  r->bundle = lw::core::LoadBundle(tmp.path());
  r->options.try_pairs = false;
  r->setup = d::SetUpProblem(r->bundle, r->options, r->result);
  for (size_t i : r->setup.prob.scan_obs) r->scan_sigma_before.push_back(r->setup.prob.obs[i].sigma);
  r->base = d::FitBaseline(r->setup.prob);
  r->noise = d::CalibrateNoise(r->setup, r->base, r->result);
  r->folds = d::BuildFolds(r->setup, r->options.holdout_fraction);
  r->null = d::TestMismatch(r->setup.prob, r->base, r->folds);
  if (full) {
    r->hyp =
        d::TestHypotheses(r->setup.prob, r->base, r->null, r->folds,
                          d::AvailableEffects(r->setup.fields.has_normal, r->setup.time.throughput_available), false, r->result);
  }
  return r;
}

const Run& Null() {
  static const std::unique_ptr<Run> run = [] {
    lw::test::SyntheticSpec spec;
    spec.seed = 7;
    return Build(spec, false);
  }();
  return *run;
}

const Run& Hardening() {
  static const std::unique_ptr<Run> run = [] {
    lw::test::SyntheticSpec spec;
    spec.hardening_h = 0.5;
    spec.hardening_tau_days = 6;
    return Build(spec, true);
  }();
  return *run;
}

d::SensorData Sensor(const std::string& id, const std::string& row, bool usable) {
  d::SensorData s;
  s.id = id;
  s.row = row;
  s.usable = usable;
  return s;
}

}  // namespace

TEST_GROUP(StageSetup){};

TEST(StageSetup, EverySensorAnalysedAndObservationsOnTheTimeGrid) {
  const d::ProblemSetup& s = Null().setup;
  CHECK_TRUE(s.Diagnosable());
  LONGS_EQUAL(12, s.sensors.size());
  LONGS_EQUAL(3, s.prob.rows);
  CHECK_TRUE((s.anchor_rows == std::vector<std::string>{"LDWN", "LMID", "LUP"}));
  LONGS_EQUAL(12, s.prob.sensor_obs.size());
  CHECK_TRUE(s.prob.scan_obs.size() > 100);
  double t_last = 0;
  for (const d::SensorData& sd : s.sensors) {
    CHECK_TRUE(sd.usable);
    t_last = std::max(t_last, sd.analysis.last_time_days);
  }
  CHECK_TRUE(static_cast<double>(s.prob.grid.steps - 1) * s.prob.grid.dt >= t_last);
  for (const d::Obs& o : s.prob.obs) {
    DOUBLES_EQUAL(o.t, (static_cast<double>(o.j) + o.frac) * s.prob.grid.dt, 1e-9);
    CHECK_TRUE(o.point < s.prob.points.size());
    if (o.sensor >= 0) CHECK_TRUE(o.sigma > 0.1);
  }
  // Scan cells get their noise only from the baseline stage.
  for (double sigma : Null().scan_sigma_before) DOUBLES_EQUAL(0, sigma, 0);
  // Without operations.csv the throughput is flat and the note says so.
  CHECK_FALSE(s.time.throughput_available);
  for (double q : s.prob.grid.throughput) DOUBLES_EQUAL(1, q, 0);
}

TEST(StageSetup, AnchorRowsAreTheRowsWithAUsableSensorBottomToTop) {
  lw::core::CrusherConfig crusher;
  crusher.rows = {{"TOP", 2.0, 3.0}, {"MID", 1.0, 2.0}, {"LOW", 0.0, 1.0}};
  const std::vector<d::SensorData> sensors = {Sensor("a", "TOP", true), Sensor("b", "MID", false), Sensor("c", "LOW", true)};
  d::Interpolator interp;
  const auto rows = d::AnchorRows(crusher, sensors, interp);
  CHECK_TRUE((rows == std::vector<std::string>{"LOW", "TOP"}));
  LONGS_EQUAL(2, interp.centres.size());
  DOUBLES_EQUAL(0.5, interp.centres[0], 1e-12);
  DOUBLES_EQUAL(2.5, interp.centres[1], 1e-12);
  int a = -1, b = -1;
  double wa = 0;
  interp.Weights(1.0, a, b, wa);  // a quarter of the way from LOW to TOP
  LONGS_EQUAL(0, a);
  LONGS_EQUAL(1, b);
  DOUBLES_EQUAL(0.75, wa, 1e-12);
  interp.Weights(3.0, a, b, wa);  // above the top centre: the top row alone
  LONGS_EQUAL(1, a);
  LONGS_EQUAL(1, b);
  DOUBLES_EQUAL(1, wa, 0);
}

TEST_GROUP(StageBaseline){};

TEST(StageBaseline, Eq9FitsANullCampaignAndMissesAHardenedOne) {
  const Run& null = Null();
  const Run& hard = Hardening();
  // The baseline is fitted to the sensor events only.
  size_t n_sensor = 0;
  for (const auto& list : null.setup.prob.sensor_obs) n_sensor += list.size();
  LONGS_EQUAL(n_sensor, null.base.eq9.n_train);
  CHECK_TRUE(null.base.k_scale > 0);
  const lw::diagnosis::ErrorSummary m_null = d::BaselineMetrics(null.setup.prob, null.base, null.folds);
  const lw::diagnosis::ErrorSummary m_hard = d::BaselineMetrics(hard.setup.prob, hard.base, hard.folds);
  LONGS_EQUAL(null.setup.prob.obs.size(), m_null.observations);
  CHECK_TRUE(m_null.holdout_observations > 0);
  CHECK_TRUE(m_null.rmse_mm < 2.0);
  CHECK_TRUE(m_hard.rmse_mm > 1.5 * m_null.rmse_mm);
}

TEST(StageBaseline, NoiseModelSetsEveryScanSigmaAndSensorPrior) {
  const Run& r = Null();
  const d::Thresholds th;
  CHECK_TRUE(r.noise.map_tau >= 0);
  CHECK_TRUE(r.noise.corr_cells >= 1);
  CHECK_TRUE(r.noise.corr_cells <= d::KernelCorrelationCells(r.setup.fields, r.setup.grid) + 1e-9);
  // The smaller of the map's cross-validated error and what the scan measured.
  CHECK_TRUE(r.noise.map_tau <= r.setup.fields.model.smoothing_error_rel);
  CHECK_TRUE(r.noise.tau_source == "scan" || r.noise.tau_source == "map cross-validation");
  for (size_t i : r.setup.prob.scan_obs) CHECK_TRUE(r.setup.prob.obs[i].sigma >= th.scan_floor_mm);
  for (double su : r.setup.prob.sigma_u) CHECK_TRUE(su >= th.u_floor_rel);
  CHECK_TRUE(r.result.noise.contains("map_pattern_error_relative"));
  DOUBLES_EQUAL(d::Round(r.noise.map_tau, 3), r.result.noise["map_pattern_error_relative"].get<double>(), 0);
  // The map's profile error: the DEM law's, capped by what the scan's band means show.
  CHECK_TRUE(r.noise.band_sd >= 0);
  CHECK_TRUE(r.noise.band_sd <= r.setup.fields.band_rel_sd);
  DOUBLES_EQUAL(std::min(r.setup.fields.band_rel_sd, r.noise.band_sd_scan), r.noise.band_sd, 1e-15);
  DOUBLES_EQUAL(r.noise.band_sd, r.setup.prob.band_sd, 0);
}

TEST_GROUP(StageFolds){};

TEST(StageFolds, FoldsHoldOutLaterReadingsSensorsAndScanSectors) {
  const Run& r = Null();
  const d::Problem& p = r.setup.prob;
  LONGS_EQUAL(3, r.folds.size());
  STRCMP_EQUAL("later_readings", r.folds[0].name.c_str());
  STRCMP_EQUAL("left_out_sensors", r.folds[1].name.c_str());
  STRCMP_EQUAL("scan_sectors", r.folds[2].name.c_str());
  for (const d::Fold& f : r.folds)
    for (size_t i = 0; i < p.obs.size(); ++i) CHECK_FALSE(f.train[i] && f.test[i]);
  // later_readings: only sensor events, all later than every training sensor event.
  double last_train = 0, first_test = 1e300;
  for (size_t i = 0; i < p.obs.size(); ++i) {
    if (p.obs[i].sensor < 0) {
      CHECK_TRUE(r.folds[0].train[i]);
      continue;
    }
    if (r.folds[0].test[i]) first_test = std::min(first_test, p.obs[i].t);
    if (r.folds[0].train[i]) last_train = std::max(last_train, p.obs[i].t);
  }
  CHECK_TRUE(first_test > last_train);
  // left_out_sensors: two of four sensors per row, each wholly.
  size_t left = 0;
  for (const auto& list : p.sensor_obs) {
    const bool out = r.folds[1].test[list.front()];
    for (size_t i : list) CHECK_EQUAL(out, r.folds[1].test[i]);
    left += out ? 1 : 0;
  }
  LONGS_EQUAL(6, left);
  // scan_sectors: scan cells only, about half of them.
  size_t held = 0;
  for (size_t i = 0; i < p.obs.size(); ++i)
    if (r.folds[2].test[i]) {
      CHECK_TRUE(p.obs[i].sensor < 0);
      ++held;
    }
  CHECK_TRUE(held > p.scan_obs.size() / 4 && held < 3 * p.scan_obs.size() / 4);
  // A problem without scan cells has no scan fold.
  d::Problem no_scan;
  CHECK_FALSE(d::ScanSectorsFold(no_scan, r.setup.grid).has_value());
}

TEST_GROUP(StageMismatch){};

TEST(StageMismatch, NullIsWithinTheLearnedNoiseAndAOneSensorMismatchIsNot) {
  const d::Thresholds th;
  CHECK_TRUE(std::fabs(Null().null.mismatch_z) <= 2);
  // The noise is learned per type from the other sensors (and scan sectors): a mismatch confined to
  // one sensor of many (its wear 3 mm more from day 30 on, beyond its own scale) stands out.
  d::Problem bent = Null().setup.prob;
  CHECK_TRUE(bent.sensor_obs.size() >= 6);
  for (size_t i : bent.sensor_obs[2])
    if (bent.obs[i].t > 30) bent.obs[i].wear += 3.0;
  CHECK_TRUE(d::TestMismatch(bent, Null().base, Null().folds).mismatch_z > th.mismatch_z);
  // Under the modelled noise the null's excess is far below 0 (the noise the map's faces suggest).
  CHECK_TRUE(Null().null.mismatch_z_modelled < -2);
  const d::NullModel& n = Null().null;
  LONGS_EQUAL(Null().setup.prob.obs.size(), n.fit.n_train);
  LONGS_EQUAL(Null().folds.size(), n.eval.fold_fits.size());
  CHECK_TRUE(n.eval.ho_n > 0);
  DOUBLES_EQUAL(std::log(static_cast<double>(Null().setup.prob.obs.size())), n.log_n, 1e-12);
}

TEST(StageMismatch, OracleNamesAreCheckedBeforeAnyWork) {
  CHECK_FALSE(d::ParseOracle(std::nullopt).has_value());
  lw::diagnosis::OracleEffect o{"profile_evolution:shift", {{"v", 0.1}}};
  CHECK_TRUE(d::ParseOracle(o) == d::Effect::kProfileShift);
  o = {"profile_evolution", {{"p", 0.1}}};
  CHECK_TRUE(d::ParseOracle(o) == d::Effect::kProfileEvolution);
  o = {"no_such_effect", {}};
  CHECK_THROWS(std::invalid_argument, d::ParseOracle(o));
  o = {"work_hardening", {{"h", 0.3}}};  // log_tau missing
  CHECK_THROWS(std::invalid_argument, d::ParseOracle(o));
}

TEST_GROUP(StageHypotheses){};

TEST(StageHypotheses, HardeningIsChosenAmongTheAvailableEffects) {
  const Run& r = Hardening();
  const auto available = d::AvailableEffects(r.setup.fields.has_normal, r.setup.time.throughput_available);
  LONGS_EQUAL(available.size(), r.hyp.singles);
  LONGS_EQUAL(r.hyp.singles, r.hyp.evals.size());  // no pairs asked
  CHECK_TRUE(r.hyp.dispersion >= 1);
  const d::ModelEval* chosen = r.hyp.Chosen();
  CHECK_TRUE(chosen != nullptr);
  CHECK_TRUE(chosen->accepted);
  CHECK_TRUE(chosen->full.spec.effects.front() == d::Effect::kWorkHardening);
  for (const d::ModelEval& ev : r.hyp.evals)
    if (ev.accepted) CHECK_TRUE(ev.score <= chosen->score);
  DOUBLES_EQUAL(d::Round(r.hyp.dispersion, 3), r.result.noise["dispersion"].get<double>(), 0);
}

TEST(StageHypotheses, AvailableEffectsNeedTheirData) {
  const auto all = d::AvailableEffects(true, true);
  LONGS_EQUAL(d::kEffectCount, all.size());
  const auto some = d::AvailableEffects(false, false);
  LONGS_EQUAL(d::kEffectCount - 2, some.size());
  CHECK_TRUE(std::find(some.begin(), some.end(), d::Effect::kSqueezeWear) == some.end());
  CHECK_TRUE(std::find(some.begin(), some.end(), d::Effect::kThroughputVariation) == some.end());
}

TEST(StageHypotheses, BestAcceptedAndPairCandidates) {
  std::vector<d::ModelEval> evals(4);
  const d::Effect effects[4] = {d::Effect::kWorkHardening, d::Effect::kProfileEvolution, d::Effect::kProfileShift,
                                d::Effect::kFeedSegregation};
  const double scores[4] = {5, 30, 20, 12};
  for (size_t k = 0; k < 4; ++k) {
    evals[k].full.spec.effects = {effects[k]};
    evals[k].score = scores[k];
    evals[k].delta_bic = scores[k];
  }
  LONGS_EQUAL(-1, d::BestAccepted(evals));
  evals[0].accepted = evals[3].accepted = true;
  LONGS_EQUAL(3, d::BestAccepted(evals));
  // Best first; the shift form is the weaker form of profile_evolution, already in.
  const auto top = d::PairCandidates(evals);
  CHECK_TRUE((top == std::vector<size_t>{1, 3, 0}));
  evals[0].delta_bic = -1;  // no gain: not a candidate
  CHECK_TRUE((d::PairCandidates(evals) == std::vector<size_t>{1, 3}));
}

// Squeeze wear must be the normal stress's (RequireStressShape). With the synthetic map's stress, which
// peaks mid-liner where the wear falls off, squeeze wear beats the map smoothed like the stress in the
// stress's place and is named, with a note. When that stand-in is the stress itself (a real map, whose
// stress follows its wear, at the limit), it fits exactly as well: squeeze wear is refused, and the note says why.
TEST(StageHypotheses, SqueezeWearMustBeatTheMapSmoothedLikeTheStress) {
  lw::test::SyntheticSpec spec;
  spec.squeeze_beta = 0.4;
  const std::unique_ptr<Run> r = Build(spec, true);
  const d::ModelEval* chosen = r->hyp.Chosen();
  CHECK_TRUE(chosen != nullptr);
  CHECK_TRUE(chosen->full.spec.effects.front() == d::Effect::kSqueezeWear);
  auto noted = [](const std::vector<std::string>& notes, const char* start) {
    for (const auto& n : notes)
      if (n.rfind(start, 0) == 0) return true;
    return false;
  };
  CHECK_TRUE(noted(r->result.notes, "squeeze_wear follows the normal stress"));

  d::Problem same = r->setup.prob;
  for (d::ModelPoint& p : same.points) p.broad_i = p.normal_i;
  d::Hypotheses h = r->hyp;
  std::vector<std::string> notes;
  d::RequireStressShape(h, same, r->null, r->folds, r->base.k_scale, notes);
  for (const d::ModelEval& ev : h.evals)
    if (ev.full.spec.effects.front() == d::Effect::kSqueezeWear) CHECK_FALSE(ev.accepted);
  CHECK_TRUE(noted(notes, "squeeze_wear not named"));
}

// A hardness gradient case the information criterion gave to profile evolution (one parameter
// against three; dem-heldout4): fitted together, the profile's drift falls to nothing while the
// hardness gradient stays, and hardness alone predicts the held-out data better. The encompassing
// rule names the hardness gradient; without either piece of evidence the choice stands.
TEST(StageHypotheses, AnEffectExplainedAwayInTheJointFitGivesWayToTheOneThatExplainsIt) {
  d::Hypotheses h;
  const auto single = [](d::Effect e, double score, double ho_chi2) {
    d::ModelEval ev;
    ev.full.spec.effects = {e};
    ev.accepted = true;
    ev.score = score;
    ev.ho_chi2 = ho_chi2;
    return ev;
  };
  h.evals.push_back(single(d::Effect::kProfileEvolution, 79.9, 49.96));  // A, the best score
  h.evals.push_back(single(d::Effect::kHardnessGradient, 75.3, 45.11));  // B
  h.singles = 2;
  d::ModelEval pair;
  pair.full.spec.effects = {d::Effect::kProfileEvolution, d::Effect::kHardnessGradient};
  const auto n = static_cast<Eigen::Index>(pair.full.spec.ParamCount());
  pair.full.x = Eigen::VectorXd::Constant(n, 0.5);
  pair.full.stderr_given_shape = Eigen::VectorXd::Constant(n, 0.01);
  const int p = pair.full.spec.Offset(d::Effect::kProfileEvolution), g = pair.full.spec.Offset(d::Effect::kHardnessGradient);
  pair.full.x[p] = -0.018;
  pair.full.stderr_given_shape[p] = 0.09;  // 0.2 standard errors: explained away
  pair.full.x[g] = 0.045;
  pair.full.stderr_given_shape[g] = 0.0233;  // 1.93: kept
  h.evals.push_back(pair);
  h.pair_parts.push_back({0, 1});
  h.best = 0;
  d::Encompassing e = d::PreferEncompassing(h, 1.0, 0.0);
  LONGS_EQUAL(1, e.best);
  LONGS_EQUAL(0, e.explained_away);
  LONGS_EQUAL(1, e.by);
  // B predicting the held-out data worse than A: A stands.
  h.evals[1].ho_chi2 = 50.0;
  LONGS_EQUAL(0, d::PreferEncompassing(h, 1.0, 0.0).best);
  h.evals[1].ho_chi2 = 45.11;
  // A keeping its size in the joint fit (both needed): A stands.
  h.evals[2].full.stderr_given_shape[p] = 0.01;
  LONGS_EQUAL(0, d::PreferEncompassing(h, 1.0, 0.0).best);
  h.evals[2].full.stderr_given_shape[p] = 0.09;
  // B not accepted on its own: nothing is named (what A fitted is real, its cause not determined).
  h.evals[1].accepted = false;
  e = d::PreferEncompassing(h, 1.0, 0.0);
  LONGS_EQUAL(-1, e.best);
  LONGS_EQUAL(0, e.explained_away);
  LONGS_EQUAL(1, e.by);
  h.evals[1].accepted = true;
  // A pair chosen, or nothing chosen: unchanged.
  h.best = 2;
  LONGS_EQUAL(2, d::PreferEncompassing(h, 1.0, 0.0).best);
  h.best = -1;
  LONGS_EQUAL(-1, d::PreferEncompassing(h, 1.0, 0.0).best);
}

TEST(StageHypotheses, EffectSizeIsTestedWithItsShapeHeldAtTheFit) {
  // Row scale, h, log_tau: h and the time constant trade off (correlation 0.99).
  d::ModelSpec spec;
  spec.effects = {d::Effect::kWorkHardening};
  Eigen::MatrixXd jtj(3, 3);
  jtj << 4, 0, 0, 0, 1, 0.99, 0, 0.99, 1;
  const Eigen::VectorXd given = d::StderrGivenShape(spec, jtj);
  DOUBLES_EQUAL(0.5, given[0], 1e-12);
  DOUBLES_EQUAL(1.0, given[1], 1e-12);  // the marginal one is 1 / sqrt(1 - 0.99^2) = 7.1
  CHECK_TRUE(std::isnan(given[2]));     // log_tau: a shape parameter
  d::FitResult f;
  f.spec = spec;
  f.x = Eigen::Vector3d(1.0, 0.3, std::log(5.0));
  f.stderr_x = jtj.inverse().diagonal().cwiseSqrt();
  f.stderr_given_shape = given;
  DOUBLES_EQUAL(0.3, d::Significance(f, d::Effect::kWorkHardening, 1.0), 1e-12);
  DOUBLES_EQUAL(0.15, d::Significance(f, d::Effect::kWorkHardening, 4.0), 1e-12);  // over-dispersion inflates
  // Without a shape parameter (feed segregation's two amplitudes) nothing is held: the marginal errors.
  d::ModelSpec feed;
  feed.effects = {d::Effect::kFeedSegregation};
  const Eigen::VectorXd marginal = jtj.inverse().diagonal().cwiseSqrt();
  const Eigen::VectorXd same = d::StderrGivenShape(feed, jtj);
  for (Eigen::Index k = 0; k < 3; ++k) DOUBLES_EQUAL(marginal[k], same[k], 1e-9);
}

TEST(StageHypotheses, FeedSegregationIsJudgedAgainstTheMapsOwnAsymmetryAtTheOneParameterLevel) {
  // A two-component amplitude over its per-component error is Rayleigh under the null:
  // P(R > r) = exp(-r^2 / 2); it is converted to the one-parameter z of the same tail.
  DOUBLES_EQUAL(1.959964, d::RayleighToZ(std::sqrt(2.0 * std::log(20.0))), 1e-5);  // p = 0.05
  DOUBLES_EQUAL(0.0, d::RayleighToZ(0.0), 1e-12);
  CHECK_TRUE(d::RayleighToZ(2.0) < 2.0);  // amplitude / error 2 happens 13.5 % of the time by chance
  CHECK_TRUE(d::RayleighToZ(3.0) > d::RayleighToZ(2.5));
  d::ModelSpec feed;
  feed.effects = {d::Effect::kFeedSegregation};
  d::FitResult f;
  f.spec = feed;
  f.x = Eigen::Vector3d(1.0, 0.06, 0.08);  // amplitude 0.1
  f.stderr_given_shape = Eigen::Vector3d(0.01, 0.02, 0.02);
  DOUBLES_EQUAL(d::RayleighToZ(5.0), d::Significance(f, d::Effect::kFeedSegregation, 1.0), 1e-9);
  // The same fit on a map whose own first harmonic is uncertain by 0.04: not significant.
  const double with_map = d::Significance(f, d::Effect::kFeedSegregation, 1.0, 0.04);
  DOUBLES_EQUAL(d::RayleighToZ(0.1 / std::hypot(0.02, 0.04)), with_map, 1e-9);
  CHECK_TRUE(with_map < d::Thresholds{}.min_significance);
}

TEST(StageSetup, TheMapsOwnFirstHarmonicIsMeasured) {
  // The null campaign's map, and the same map made 20 % asymmetric (cos theta, every height).
  lw::core::Bundle bundle = Null().bundle;
  const d::MapFields plain = d::ComputeMapFields(bundle);
  CHECK_TRUE(plain.harmonic1_rel_sd >= d::kHarmonic1PerFaceNoise * plain.face_rel_noise - 1e-12);
  CHECK_TRUE(plain.harmonic1_rel_sd < 0.05);
  for (Eigen::Index i = 0; i < bundle.map.wear.size(); ++i)
    bundle.map.wear[i] *= 1.0 + 0.2 * std::cos(bundle.map.theta_deg[i] * 3.14159265358979323846 / 180.0);
  const d::MapFields skewed = d::ComputeMapFields(bundle);
  DOUBLES_EQUAL(0.2 / std::sqrt(2.0), skewed.harmonic1_rel_sd, 0.02);
}

TEST_GROUP(StageFindings){};

TEST(StageFindings, HardeningIsTheTopFindingWithEvidence) {
  const Run& r = Hardening();
  const auto findings = d::RankFindings({r.bundle, r.setup, r.null, r.hyp});
  CHECK_TRUE(!findings.empty());
  STRCMP_EQUAL("work_hardening", findings.front().effect.c_str());
  CHECK_TRUE(findings.front().confidence > 0.5 && findings.front().confidence < 1);
  CHECK_TRUE(findings.front().explanation.find("hardening") != std::string::npos);
  CHECK_TRUE(findings.front().parameters.contains("tau_days"));
  CHECK_TRUE(findings.front().evidence.contains("holdout_chi2_model"));
  for (size_t k = 1; k < findings.size(); ++k) CHECK_TRUE(findings[k].confidence <= findings[k - 1].confidence);
  CHECK_TRUE(d::MismatchDetected(r.null.mismatch_z, findings));
  const auto table = d::HypothesesTable(r.hyp.evals, r.setup.prob.rows);
  LONGS_EQUAL(r.hyp.evals.size(), table.size());
  STRCMP_EQUAL(r.hyp.evals[0].full.spec.Name().c_str(), table[0]["model"].get<std::string>().c_str());
  // The chosen model explains the observations better than the refit baseline.
  const auto improved = d::ModelMetrics(r.setup.prob, *r.hyp.Chosen());
  const auto refit = d::ModelMetrics(r.setup.prob, r.null.eval);
  CHECK_TRUE(improved.rmse_mm < refit.rmse_mm);
}

TEST(StageFindings, MaterialLossUnexplainedAndConfidence) {
  d::SensorData s = Sensor("S7", "LMID", true);
  s.analysis.rate_mm_per_day = 0.5;
  s.analysis.losses.push_back({40, 5, 5.5});
  const auto losses = d::MaterialLossFindings({s}, {}, 0.1, lw::core::TimePoint{});
  LONGS_EQUAL(1, losses.size());
  STRCMP_EQUAL(lw::diagnosis::kMaterialLoss, losses[0].effect.c_str());
  DOUBLES_EQUAL(0.9, losses[0].confidence, 1e-12);  // 0.5 + 0.08 x 5 mm
  CHECK_TRUE(losses[0].explanation.rfind("Sensor S7 lost 5 mm", 0) == 0);
  const lw::diagnosis::Finding u = d::UnexplainedFinding(12.0, {});
  STRCMP_EQUAL(lw::diagnosis::kUnexplained, u.effect.c_str());
  CHECK_TRUE(u.confidence > 0.3 && u.confidence < 0.95);
  CHECK_FALSE(d::MismatchDetected(3.9, {}));
  CHECK_TRUE(d::MismatchDetected(4.1, {}));
  // Confidence grows with the gain and falls with a strong runner-up.
  d::ModelEval weak, strong;
  weak.delta_bic = 12;
  weak.ho_rel = 0.05;
  weak.score = 20;
  strong = weak;
  strong.delta_bic = 60;
  strong.ho_rel = 0.3;
  strong.score = 100;
  CHECK_TRUE(d::Confidence(strong, 0) > d::Confidence(weak, 0));
  CHECK_TRUE(d::Confidence(strong, 100) < d::Confidence(strong, 0));
  CHECK_TRUE(d::Confidence(strong, 0) <= 0.99);
}

TEST_GROUP(StageRegions){};

TEST(StageRegions, ARunOfThreeEventsBeyondThreeSigmaAtASensor) {
  d::ProblemSetup setup;
  d::SensorData s = Sensor("S1", "LOW", true);
  s.usable_index = 0;
  s.z = 1.0;
  s.theta = 90;
  setup.sensors = {s};
  setup.prob.sensor_obs = {{}};
  d::NullModel null;
  null.fit.u = {0.0};
  null.w = Eigen::MatrixXd::Zero(1, 8);
  // The model predicts 5 mm at every step; events 2-4 measured 4 mm (1 mm = 10 sigma over), the rest 5.
  null.w.setConstant(5.0);
  for (size_t k = 0; k < 7; ++k) {
    d::Obs o;
    o.t = static_cast<double>(k);
    o.j = k;
    o.wear = (k >= 2 && k <= 4) ? 4.0 : 5.0;
    o.sigma = 0.1;
    o.sensor = 0;
    setup.prob.sensor_obs[0].push_back(setup.prob.obs.size());
    setup.prob.obs.push_back(o);
  }
  const auto regions = d::SensorRegions(setup, null, lw::core::TimePoint{});
  LONGS_EQUAL(1, regions.size());
  STRCMP_EQUAL("over", regions[0].sign.c_str());
  DOUBLES_EQUAL(1.0, regions[0].size_mm, 1e-12);
  STRCMP_EQUAL("sensor:S1", regions[0].source.c_str());
  CHECK_TRUE(regions[0].from == lw::core::AddDays(lw::core::TimePoint{}, 2));
  CHECK_TRUE(regions[0].to == lw::core::AddDays(lw::core::TimePoint{}, 4));
  // Two events beyond 3 sigma are not a region.
  setup.prob.obs[4].wear = 5.0;
  CHECK_TRUE(d::SensorRegions(setup, null, lw::core::TimePoint{}).empty());
}

TEST(StageRegions, RegionsOfTheHardenedCampaignAreOrderedAndCapped) {
  const Run& r = Hardening();
  const auto regions = d::FindRegions(r.bundle, r.setup, r.null);
  CHECK_TRUE(!regions.empty());
  CHECK_TRUE(regions.size() <= 30);
  for (size_t k = 1; k < regions.size(); ++k) CHECK_TRUE(regions[k].size_mm <= regions[k - 1].size_mm);
  for (const auto& g : regions) CHECK_TRUE(g.z_min_m < g.z_max_m);
}

TEST_GROUP(StagePredictions){};

TEST(StagePredictions, PredictionFollowsTheReadingsAndStaysPhysical) {
  const Run& r = Hardening();
  const d::ModelEval& chosen = *r.hyp.Chosen();
  const d::PredictionInput in{r.bundle, r.options, r.setup, r.base, r.null, chosen.full, true};
  const lw::core::TimePoint last = r.bundle.scans.back().date;
  const auto faces = d::FacePoints(r.bundle, r.setup);
  LONGS_EQUAL(r.bundle.map.face_count(), faces.size());
  const lw::diagnosis::Prediction p = d::PredictAt(in, faces, {}, last);
  LONGS_EQUAL(r.setup.sensors.size(), p.sensors.size());
  for (double w : p.face_wear_improved_mm) CHECK_TRUE(w >= 0 && w <= 100);
  // At the last scan the improved model reads what the sensors read (within a few mm); the
  // baseline, which misses the hardening, is further off on average.
  double err_improved = 0, err_base = 0;
  for (size_t i = 0; i < p.sensors.size(); ++i) {
    const double measured = r.setup.sensors[i].analysis.last_thickness_mm;
    err_improved += std::fabs(p.sensors[i].improved_thickness_mm - measured);
    err_base += std::fabs(p.sensors[i].baseline_thickness_mm - measured);
  }
  err_improved /= static_cast<double>(p.sensors.size());
  err_base /= static_cast<double>(p.sensors.size());
  CHECK_TRUE(err_improved < 3.0);
  CHECK_TRUE(err_improved < err_base);
  const auto curves = d::SensorCurves(in);
  LONGS_EQUAL(r.setup.sensors.size(), curves.size());
  for (const auto& c : curves)
    for (size_t k = 1; k < c.baseline_thickness_mm.size(); ++k)
      CHECK_TRUE(c.baseline_thickness_mm[k] <= c.baseline_thickness_mm[k - 1]);
  const auto grids = d::ResidualGrids(in);
  LONGS_EQUAL(r.bundle.scans.size(), grids.size());
}

TEST_GROUP(ModelFit){};

TEST(ModelFit, ASensorsIntensityErrorMovesItsHardnessOnsetInTime) {
  // Under a hardness gradient a sensor whose map intensity is 30 % low in fact wears faster and so
  // reaches the softer layer earlier: its curve is simulated at its own rate (factor 1.3), not the
  // plain curve scaled by 1.3. Without a depth-dependent effect both are the same.
  const d::Problem& prob = Null().setup.prob;
  const std::vector<double> u(prob.sensor_obs.size(), 0.3);
  const size_t point = prob.obs[prob.sensor_obs[0].front()].point;
  const auto last = static_cast<Eigen::Index>(prob.grid.steps);
  for (const bool gradient : {false, true}) {
    d::ModelSpec spec;
    spec.rows = prob.rows;
    if (gradient) spec.effects = {d::Effect::kHardnessGradient};
    Eigen::VectorXd lower, upper, scale, x;
    spec.Bounds(lower, upper, scale, x, 0.3);
    if (gradient) {
      const int o = spec.Offset(d::Effect::kHardnessGradient);
      x[o] = 0.5;      // g
      x[o + 1] = 0.9;  // onset: 90 % of half the thickness, reached late in the campaign
      x[o + 2] = 0.1;  // a step
    }
    Eigen::MatrixXd plain, own;
    d::Simulate(spec, x, prob.points, prob.grid, plain);
    own = plain;
    d::SensorDepthRows(prob, spec, x, u, own);
    const double ratio = own(static_cast<Eigen::Index>(point), last) / plain(static_cast<Eigen::Index>(point), last);
    if (gradient)
      CHECK_TRUE(ratio > 1.02);  // earlier onset: more wear per unit of rate
    else
      DOUBLES_EQUAL(1.0, ratio, 1e-12);
    // The other rows are untouched.
    DOUBLES_EQUAL(plain(static_cast<Eigen::Index>(prob.points.size() - 1), last),
                  own(static_cast<Eigen::Index>(prob.points.size() - 1), last), 1e-12);
  }
}

TEST(ModelFit, AScanBandsProfileErrorIsProfiledOutWithItsPrior) {
  // Scan cells of one height band 20 % above the model, the rest on it: that band's offset is the
  // 20 % shrunk by its prior (sum a^2 / (sum a^2 + 1 / band_sd^2), a = pred / sigma), the others 0.
  d::Problem prob = Null().setup.prob;
  CHECK_FALSE(prob.scan_obs.empty());
  const Eigen::MatrixXd& w = Null().null.w;
  const d::Obs& first = prob.obs[prob.scan_obs.front()];
  const int g0 = d::BandIndex(prob, first);
  CHECK_TRUE(g0 >= 0);
  LONGS_EQUAL(-1, d::BandIndex(prob, prob.obs[prob.sensor_obs[0].front()]));
  double sum_a2 = 0;
  for (size_t i : prob.scan_obs) {
    d::Obs& o = prob.obs[i];
    const double pred = d::Interp(w, o);
    const bool in = d::BandIndex(prob, o) == g0;
    o.wear = o.raw = pred * (in ? 1.2 : 1.0);
    if (in) sum_a2 += pred * pred / (o.sigma * o.sigma);
  }
  const d::Mask all(prob.obs.size(), true);
  std::vector<bool> present;
  prob.band_sd = 0;  // no profile error: nothing profiled
  for (double b : d::ProfiledBandOffsets(prob, w, all, false, present)) DOUBLES_EQUAL(0.0, b, 0);
  CHECK_TRUE(std::none_of(present.begin(), present.end(), [](bool v) { return v; }));
  prob.band_sd = 0.1;
  const std::vector<double> b = d::ProfiledBandOffsets(prob, w, all, false, present);
  LONGS_EQUAL(d::BandCount(prob), b.size());
  DOUBLES_EQUAL(0.2 * sum_a2 / (sum_a2 + 100.0), b[static_cast<size_t>(g0)], 1e-9);
  CHECK_TRUE(b[static_cast<size_t>(g0)] > 0.1);
  for (size_t g = 0; g < b.size(); ++g)
    if (static_cast<int>(g) != g0) DOUBLES_EQUAL(0.0, b[g], 1e-9);
  // Only the scan cells' groups are present, and each adds its prior term to the residuals.
  size_t groups = 0;
  for (size_t g = 0; g < present.size(); ++g) groups += present[g] ? 1 : 0;
  CHECK_TRUE(groups >= 2);
  const d::ModelSpec spec = Null().base.spec;
  const d::EvalOptions opt{true, false};
  Eigen::VectorXd r_with, r_without;
  Eigen::MatrixXd w_fit;
  d::Residuals(prob, spec, Null().null.fit.x, all, opt, r_with, nullptr, w_fit);
  prob.band_sd = 0;
  d::Residuals(prob, spec, Null().null.fit.x, all, opt, r_without, nullptr, w_fit);
  LONGS_EQUAL(r_without.size() + static_cast<Eigen::Index>(groups), r_with.size());
  CHECK_TRUE(r_with.squaredNorm() < r_without.squaredNorm());
}

TEST_GROUP(StageReport){};

TEST(StageReport, TheNoiseModelFitsOrSaysWhyNotAndWhenTheTestIsBlind) {
  // The test's noise as learned per observation type (noise.mismatch_calibration).
  auto calibrated = [](double events, double cells) {
    nlohmann::ordered_json c = {{"sensor_events", {{"learned", true}, {"chi2_per_observation", events}}}};
    if (cells >= 0) c["scan_cells"] = {{"learned", false}, {"chi2_per_observation", cells}};
    return c;
  };
  nlohmann::ordered_json noise = {{"mismatch_calibration", calibrated(1.1, -1)},
                                  {"map_pattern_error_relative", 0.2},
                                  {"map_pattern_error_source", "sensors"},
                                  {"map_model", {{"smoothing_error_relative", 0.3}}}};
  lw::diagnosis::SensorNoise s;
  s.used = true;
  s.predicted_wear_mm = 30;
  s.noise_sd_mm = 6;
  const std::vector<lw::diagnosis::SensorNoise> sensors(3, s);
  lw::diagnosis::NoiseFit f = d::JudgeNoiseFit(noise, 0.5, sensors);
  CHECK_TRUE(f.fits);
  CHECK_TRUE(f.detail.empty());
  CHECK_FALSE(f.blind);
  CHECK_TRUE(f.blind_detail.empty());
  // The demo's figures (issue 41): each one named with its value.
  noise["mismatch_calibration"] = calibrated(0.004, -1);
  noise["map_pattern_error_relative"] = 0.87;
  noise["map_model"]["smoothing_error_relative"] = 1.07;
  f = d::JudgeNoiseFit(noise, -10.3, sensors);
  CHECK_FALSE(f.fits);
  STRCMP_CONTAINS("chi-square per sensor event 0.004", f.detail.c_str());
  STRCMP_CONTAINS("16 times", f.detail.c_str());
  STRCMP_CONTAINS("z -10.3", f.detail.c_str());
  CHECK_TRUE(f.blind);
  STRCMP_CONTAINS("pattern error is 87 % of the predicted wear (measured from the sensors' spread", f.blind_detail.c_str());
  STRCMP_CONTAINS("smoothing error is 107 %", f.blind_detail.c_str());
  // A noise model wider than the scatter is not yet blind; a noise sd above half the wear at the
  // median sensor is, whatever the pattern error.
  noise["map_pattern_error_relative"] = 0.2;
  f = d::JudgeNoiseFit(noise, -10.3, sensors);
  CHECK_FALSE(f.fits);
  CHECK_FALSE(f.blind);
  std::vector<lw::diagnosis::SensorNoise> noisy = sensors;
  for (auto& n : noisy) n.noise_sd_mm = 20;
  f = d::JudgeNoiseFit(noise, 0.5, noisy);
  CHECK_TRUE(f.blind);
  STRCMP_CONTAINS("at the median sensor the noise model allows 67 % of the predicted wear", f.blind_detail.c_str());
  // Scan cells count only when there are any; a type whose calibrated chi-square is still far
  // below 1 (too few groups to learn its scale) says the noise model does not fit.
  noise = {{"mismatch_calibration", calibrated(1.0, -1)}};
  CHECK_TRUE(d::JudgeNoiseFit(noise, 0, sensors).fits);
  noise["mismatch_calibration"] = calibrated(1.0, 0.1);
  f = d::JudgeNoiseFit(noise, 0, sensors);
  CHECK_FALSE(f.fits);
  STRCMP_CONTAINS("chi-square per scan cell 0.1", f.detail.c_str());
}

TEST(StageReport, ExcludedSensorsSayWhyAndUsedOnesTheirNoise) {
  d::SensorData never = Sensor("S1", "LMID", false);
  STRCMP_CONTAINS("never reported", d::ExcludedBecause(never, {}).c_str());
  d::SensorData old = never;
  STRCMP_CONTAINS("previous liner",
                  d::ExcludedBecause(old, {{"S1", "previous_liner", lw::core::TimePoint{}, lw::core::TimePoint{}, ""}}).c_str());
  d::SensorData flat = never;
  flat.analysis.readings = {{1, 100}, {2, 100}, {3, 99}};
  flat.analysis.used = {true, true, true};
  flat.analysis.events.resize(1);
  flat.field.intensity = 1;
  const std::string why = d::ExcludedBecause(flat, {});
  STRCMP_CONTAINS("1 loop crossing, at least 2 needed", why.c_str());
  STRCMP_CONTAINS("3 kept readings lie between 99 and 100 mm", why.c_str());
  flat.analysis.used = {false, false, false};
  flat.analysis.issues.push_back({"stuck", 1, 3, ""});
  STRCMP_CONTAINS("all 3 readings were excluded as faults (stuck)", d::ExcludedBecause(flat, {}).c_str());
  d::SensorData dark = flat;
  dark.analysis.used = {true, true, true};
  dark.field.intensity = 0;
  STRCMP_CONTAINS("predicts no wear at its position", d::ExcludedBecause(dark, {}).c_str());
  // The null campaign: every sensor used, its noise part by part.
  const Run& r = Null();
  const auto sensors = d::ExplainSensors(r.setup, r.base, r.null, {}, "sensors");
  LONGS_EQUAL(r.setup.sensors.size(), sensors.size());
  for (const auto& n : sensors) {
    CHECK_TRUE(n.used);
    CHECK_TRUE(n.excluded_because.empty());
    CHECK_TRUE(n.noise_sd_mm > n.reading_mm);
    CHECK_TRUE(n.predicted_wear_mm > 0);
    DOUBLES_EQUAL(n.measured_wear_mm - n.predicted_wear_mm, n.residual_mm, 1e-9);
  }
}

TEST(StageReport, EveryRejectedHypothesisNamesTheTestItFailed) {
  const Run& r = Hardening();
  auto table = d::HypothesesTable(r.hyp.evals, r.setup.prob.rows);
  d::AnnotateHypotheses(table, r.hyp, r.null.log_n);
  size_t chosen = 0, rejected = 0;
  for (size_t k = 0; k < table.size(); ++k) {
    const auto& row = table[k];
    const std::string verdict = row["verdict"].get<std::string>();
    if (verdict == "chosen") {
      ++chosen;
      LONGS_EQUAL(r.hyp.best, static_cast<long>(k));
      CHECK_FALSE(row.contains("rejected_because"));
      continue;
    }
    if (verdict == "accepted") continue;
    STRCMP_EQUAL("rejected", verdict.c_str());
    CHECK_FALSE(r.hyp.evals[k].accepted);
    ++rejected;
    CHECK_FALSE(row["rejected_because"].get<std::string>().empty());
    CHECK_FALSE(row["failed_tests"].empty());
    // A failed threshold test carries the value that failed it.
    for (const auto& t : row["failed_tests"]) {
      const std::string test = t["test"].get<std::string>();
      if (test == "delta_bic") CHECK_TRUE(t["value"].get<double>() <= 10.0 + 1e-3);
      if (test == "significance") CHECK_TRUE(t["value"].get<double>() <= 2.0 + 1e-3);
    }
  }
  LONGS_EQUAL(1, chosen);
  CHECK_TRUE(rejected > 0);
}

namespace {

// A sensor at (z, theta) on `fields`' map, as the set-up stage places it.
d::SensorData SensorAt(const lw::core::Bundle& bundle, const d::MapFields& fields, double z, double theta) {
  d::SensorData s = Sensor("X", "LDWN", true);
  s.z = z;
  s.theta = theta;
  s.field = d::FieldAt(bundle.map, fields, z, theta);
  return s;
}

lw::core::Bundle QuietMapBundle() {
  lw::test::SyntheticSpec spec;
  spec.seed = 11;
  spec.with_scan = false;
  spec.map_noise = 0.01;  // little sampling noise: the smoothing's error is what is left
  const lw::test::TempDirectory tmp("lw-diag-maperror");
  lw::test::WriteSyntheticBundle(tmp.path(), spec);
  return lw::core::LoadBundle(tmp.path());
}

}  // namespace

// "Within the noise" at a sensor names the map's own standard error there and why it has that
// size: the parts add up, and the reason follows what the map shows around the sensor.
TEST(StageReport, EachSensorGetsTheMapsOwnStandardErrorAndWhy) {
  const Run& r = Null();
  const auto sensors = d::ExplainSensors(r.setup, r.base, r.null, {}, "sensors");
  for (size_t k = 0; k < sensors.size(); ++k) {
    const auto& n = sensors[k];
    CHECK_TRUE(n.map_sd_mm > 0);
    DOUBLES_EQUAL(n.map_sd_mm, std::hypot(n.map_sd_sampling_mm, n.map_sd_smoothing_mm), 1e-6 * n.map_sd_mm);
    const d::MapError e = d::ExplainMapError(r.setup.fields, r.setup.sensors[k]);
    DOUBLES_EQUAL(e.sd_rel * n.predicted_wear_mm, n.map_sd_mm, 1e-9 * n.map_sd_mm);
    STRCMP_EQUAL(e.why.c_str(), n.map_error_why.c_str());
    CHECK_FALSE(n.map_error_detail.empty());
    char own[160];
    std::snprintf(own, sizeof own, "the map's own standard error at sensor %s is %.1f mm", n.sensor_id.c_str(), n.map_sd_mm);
    STRCMP_CONTAINS(own, n.explanation.c_str());
    STRCMP_CONTAINS(n.map_error_detail.c_str(), n.explanation.c_str());
    STRCMP_CONTAINS(n.noise_detail.c_str(), n.explanation.c_str());
  }

  // A sharp discharge-edge band (the lowest faces wear 6 times as much): a sensor just above it,
  // inside the kernel's reach, is told that band is unresolved; one at mid-height is not.
  lw::core::Bundle edge = QuietMapBundle();
  const double z0 = edge.map.z.minCoeff();
  const d::MapFields plain = d::ComputeMapFields(edge);
  const double band = 2 * plain.face_size_m;
  for (Eigen::Index i = 0; i < edge.map.z.size(); ++i)
    if (edge.map.z[i] < z0 + band) edge.map.wear[i] *= 6;
  const d::MapFields fe = d::ComputeMapFields(edge);
  const double h = std::max(fe.model.bandwidth_m, fe.face_size_m);
  const d::MapError near = d::ExplainMapError(fe, SensorAt(edge, fe, z0 + band + 0.5 * h, 100));
  CHECK_TRUE(near.smoothing_rel >= near.sampling_rel * (1 - 1e-9));  // equal where the local scale stopped early
  STRCMP_EQUAL("edge_band", near.why.c_str());
  STRCMP_CONTAINS("the discharge-edge band is unresolved", near.detail.c_str());
  const double mid = 0.5 * (fe.z_bottom + fe.z_top);
  const d::MapError far = d::ExplainMapError(fe, SensorAt(edge, fe, mid, 100));
  CHECK_FALSE(far.why == "edge_band");

  // A spot of raw faces finer than the kernel around a sensor: named as local structure, with
  // its sign, when the smoothing's error is the larger part there.
  lw::core::Bundle spot = QuietMapBundle();
  const d::MapFields ps = d::ComputeMapFields(spot);
  const double zs = mid, ts = 200, reach = 1.5 * ps.face_size_m;
  for (Eigen::Index i = 0; i < spot.map.z.size(); ++i) {
    const double arc = spot.map.radius[i] * d::AngleDiffDeg(spot.map.theta_deg[i], ts) * M_PI / 180.0;
    if (std::fabs(spot.map.z[i] - zs) < reach && std::fabs(arc) < reach) spot.map.wear[i] *= 3;
  }
  const d::MapFields fs = d::ComputeMapFields(spot);
  const d::MapError hot = d::ExplainMapError(fs, SensorAt(spot, fs, zs, ts));
  CHECK_TRUE(hot.smoothing_rel >= hot.sampling_rel * (1 - 1e-9));
  STRCMP_EQUAL("local_structure", hot.why.c_str());
  STRCMP_CONTAINS("more than the smoothed map says there", hot.detail.c_str());

  // Sampling noise dominates on a noisy map: named with the run's per-face noise.
  lw::test::SyntheticSpec noisy;
  noisy.seed = 12;
  noisy.with_scan = false;
  noisy.map_noise = 0.6;
  const lw::test::TempDirectory tmp("lw-diag-maperror-noisy");
  lw::test::WriteSyntheticBundle(tmp.path(), noisy);
  const lw::core::Bundle nb = lw::core::LoadBundle(tmp.path());
  const d::MapFields fn = d::ComputeMapFields(nb);
  const d::MapError sn = d::ExplainMapError(fn, SensorAt(nb, fn, mid, 100));
  if (sn.sampling_rel > sn.smoothing_rel) {
    STRCMP_EQUAL("sampling_noise", sn.why.c_str());
    STRCMP_CONTAINS("a longer DEM run narrows it", sn.detail.c_str());
  } else {
    CHECK_FALSE(sn.why == "sampling_noise");
  }
}

// What "no mismatch" could have seen: the chi-square the threshold needs from the z found, spread
// over the used sensors as a static error.
TEST(StageReport, TheDetectionLimitFollowsFromTheZAndTheSensorsNoise) {
  lw::diagnosis::SensorNoise s;
  s.used = true;
  s.predicted_wear_mm = 30;
  std::vector<lw::diagnosis::SensorNoise> sensors(3, s);
  sensors[0].noise_sd_mm = 4;
  sensors[1].noise_sd_mm = 6;
  sensors[2].noise_sd_mm = 9;
  lw::diagnosis::SensorNoise unused;
  unused.noise_sd_mm = 100;  // not used: not counted
  sensors.push_back(unused);
  lw::diagnosis::NoiseFit f;
  d::AddDetectionLimit(f, -10.3, 800, sensors);
  const double chi2 = (4 + 10.3) * std::sqrt(1600.0);
  DOUBLES_EQUAL(chi2, f.chi2_to_detect, 1e-9);
  DOUBLES_EQUAL(std::sqrt(chi2 / 3), f.detectable_sd_per_sensor, 1e-9);
  DOUBLES_EQUAL(6 * std::sqrt(chi2 / 3), f.detectable_mm_median_sensor, 1e-9);
  DOUBLES_EQUAL(30, f.median_predicted_wear_mm, 1e-12);
  // A calibrated null (z 0) needs less; a z already beyond the threshold needs nothing more.
  lw::diagnosis::NoiseFit g;
  d::AddDetectionLimit(g, 0, 800, sensors);
  CHECK_TRUE(g.detectable_mm_median_sensor < f.detectable_mm_median_sensor);
  d::AddDetectionLimit(g, 6, 800, sensors);
  DOUBLES_EQUAL(0, g.chi2_to_detect, 1e-12);
}

// A rejected hypothesis says which test failed and by how much: an effect pinned at its physical
// limit says so (not "0 standard errors"), and a held-out gain that passed is named as passing.
TEST(StageReport, ARejectedHypothesisAtItsLimitOrWithAHeldOutGainSaysSo) {
  const Run& r = Hardening();
  d::Hypotheses h = r.hyp;
  // The first single effect other than the chosen one, pushed to the top of its range.
  size_t k = 0;
  while (k < h.singles && static_cast<long>(k) == h.best) ++k;
  CHECK_TRUE(k < h.singles);
  d::ModelEval& ev = h.evals[k];
  const d::Effect e = ev.full.spec.effects.front();
  const d::ParamSpec main = d::EffectParams(e).front();
  const int o = ev.full.spec.Offset(e);
  ev.full.x[o] = main.upper;
  if (e == d::Effect::kFeedSegregation) ev.full.x[o + 1] = 0;
  ev.significance = 0;
  ev.accepted = false;
  ev.delta_bic = -9.8;
  ev.ho_gain = 50;
  ev.ho_rel = 0.875;
  auto table = d::HypothesesTable(h.evals, r.setup.prob.rows);
  d::AnnotateHypotheses(table, h, r.null.log_n);
  const std::string why = table[k]["rejected_because"].get<std::string>();
  STRCMP_CONTAINS("the held-out improvement 87.5 % passes, but information gain delta BIC -9.8 (needs > 10)", why.c_str());
  STRCMP_CONTAINS("sits at the limit of its physical range", why.c_str());
  STRCMP_CONTAINS(main.name.c_str(), why.c_str());
  CHECK_TRUE(why.find("standard errors from zero") == std::string::npos);
  bool at_limit = false;
  for (const auto& t : table[k]["failed_tests"]) at_limit = at_limit || t["test"].get<std::string>() == "at_limit";
  CHECK_TRUE(at_limit);
}
