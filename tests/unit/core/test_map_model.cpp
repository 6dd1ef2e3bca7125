// BuildMapModel's per-face results do not depend on how the work is split over threads, and its
// standard errors equal a brute-force computation over every face of the map (the variance comes
// from the local-scale pass's top step when that runs; issue 16).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "core/map_model.hpp"
#include "unit/core/bundle_fixture.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw::core;

namespace {

/// A noisy cone with a sharp band at the bottom (the local scale stops below the top there).
WearMap NoisyBandedCone(int nt, int nz) {
  WearMap m =
      lw::test::ConeMap(nt, nz, 0.9, 1.4, [](double z) { return 0.2 + std::pow(1.0 - z / 2.0, 1.5) + (z < 0.25 ? 2.0 : 0.0); });
  std::mt19937 rng(11);
  std::gamma_distribution<double> noise(10.0, 0.1);
  for (Eigen::Index i = 0; i < m.wear.size(); ++i) m.wear[i] *= noise(rng);
  return m;
}

bool Same(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  if (a.size() != b.size()) return false;
  for (Eigen::Index i = 0; i < a.size(); ++i)
    if (!(a[i] == b[i])) return false;  // bit for bit
  return true;
}

}  // namespace

TEST_GROUP(MapModel){};

TEST(MapModel, SameResultWithOneOrTwoThreads) {
  const WearMap m = NoisyBandedCone(64, 36);  // 4608 faces: three work chunks
  MapModelOptions one, two;
  one.threads = 1;
  two.threads = 2;
  const MapModel a = BuildMapModel(m, one), b = BuildMapModel(m, two);
  CHECK(a.local_ladder_m.size() > 1);
  CHECK(a.bandwidth_m == b.bandwidth_m && a.bandwidth_arc_m == b.bandwidth_arc_m && a.local_linear == b.local_linear);
  CHECK(a.smoothing_error_rel == b.smoothing_error_rel);
  CHECK(Same(a.clean, b.clean));
  CHECK(Same(a.intensity, b.intensity));
  CHECK(Same(a.intensity_sd, b.intensity_sd));
  CHECK(Same(a.intensity_noise_sd, b.intensity_noise_sd));
  CHECK(Same(a.local_bandwidth_m, b.local_bandwidth_m));
  CHECK(Same(a.face_var, b.face_var));
}

// At the faces that keep the cross-validated scale, the standard error is the noise carried
// through the kernel (every face's variance at its smoothed value) plus the smoothing's own
// error: recomputed here by looking at every face of the map.
TEST(MapModel, StandardErrorsEqualABruteForceSumOverEveryFace) {
  const WearMap m = NoisyBandedCone(48, 24);
  const MapModel model = BuildMapModel(m);
  CHECK(model.local_ladder_m.size() > 1);
  const double h = model.bandwidth_m, ha = model.bandwidth_arc_m;
  const Eigen::Index n = m.z.size();
  // Each face's neighbours and weights, by brute force.
  auto weights = [&](Eigen::Index i) {
    std::vector<std::pair<Eigen::Index, std::pair<double, double>>> out;  // (j, (w, dz))
    for (Eigen::Index j = 0; j < n; ++j) {
      double dth = std::fmod(m.theta_deg[j] - m.theta_deg[i], 360.0);
      if (dth > 180.0) dth -= 360.0;
      if (dth < -180.0) dth += 360.0;
      const double dz = m.z[j] - m.z[i], arc = 0.5 * (m.radius[i] + m.radius[j]) * dth * 0.017453292519943295;
      const double q = dz * dz / (h * h) + arc * arc / (ha * ha);
      if (q <= 6.25) out.push_back({j, {m.areas[j] * std::exp(-0.5 * q), dz}});
    }
    return out;
  };
  struct S {
    double s0 = 0, s1 = 0, s2 = 0, t0 = 0, t1 = 0;
  };
  std::vector<S> sums(static_cast<size_t>(n));
  Eigen::VectorXd smooth(n);
  auto linear = [&](const S& s) { return model.local_linear && s.s0 * s.s2 - s.s1 * s.s1 > 1e-6 * s.s0 * s.s2 && s.s2 > 0; };
  for (Eigen::Index i = 0; i < n; ++i) {
    S& s = sums[static_cast<size_t>(i)];
    for (const auto& [j, wd] : weights(i)) {
      const auto [w, dz] = wd;
      s.s0 += w, s.s1 += w * dz, s.s2 += w * dz * dz, s.t0 += w * model.clean[j], s.t1 += w * dz * model.clean[j];
    }
    smooth[i] = std::max(0.0, linear(s) ? (s.s2 * s.t0 - s.s1 * s.t1) / (s.s0 * s.s2 - s.s1 * s.s1) : s.t0 / s.s0);
  }
  size_t top = 0, below = 0;
  double worst = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (model.local_bandwidth_m[i] != model.bandwidth_m) {
      ++below;
      continue;
    }
    ++top;
    const S& s = sums[static_cast<size_t>(i)];
    double v = 0;
    for (const auto& [j, wd] : weights(i)) {
      const auto [w, dz] = wd;
      const double l = linear(s) ? w * (s.s2 - s.s1 * dz) / (s.s0 * s.s2 - s.s1 * s.s1) : w / s.s0;
      v += l * l * model.FaceVariance(smooth[j]);
    }
    const double sd = std::sqrt(v + std::pow(model.smoothing_error_rel * smooth[i], 2));
    CHECK(std::fabs(model.intensity[i] - smooth[i]) <= 1e-12 * smooth[i]);
    worst = std::max(worst, std::fabs(model.intensity_sd[i] - sd) / sd);
    worst = std::max(worst, std::fabs(model.intensity_noise_sd[i] - std::sqrt(v)) / std::sqrt(v));
  }
  CHECK(top > static_cast<size_t>(n) / 2);
  CHECK(below > 0);  // the band: a smaller scale there
  CHECK(worst < 1e-12);
}

// Large maps compute the smoothed field, its standard errors and the local scale from kernel sums
// on a grid (linear binning); forced here on a medium map with a sharp band and compared with the
// face-by-face sums. The pilot, the noise law, the outlier caps and the cross-validation are the
// same code on both paths, so the chosen model is identical. Measured when written (57,600 faces):
// intensity differs by median 0.017 / p99 0.17 exact noise sd, intensity_noise_sd by median 0.15 % /
// p99 0.45 %, 16 faces (0.03 %) at the adjacent step of the local-scale ladder (where the ICI rule
// is on the edge of stopping, a small change of the sums moves a face by one step, and its value by
// up to ~5 sd); the tolerances below are about 3-4x those.
TEST(MapModel, BinnedSumsAgreeWithTheFaceByFaceSums) {
  const WearMap m = NoisyBandedCone(240, 120);  // 57,600 faces
  MapModelOptions exact_opt, binned_opt;
  binned_opt.binned_above_faces = 1000;
  const MapModel a = BuildMapModel(m, exact_opt), b = BuildMapModel(m, binned_opt);
  CHECK(a.local_ladder_m.size() > 1);
  CHECK(a.bandwidth_m == b.bandwidth_m && a.bandwidth_arc_m == b.bandwidth_arc_m && a.local_linear == b.local_linear);
  CHECK(a.smoothing_error_rel == b.smoothing_error_rel && a.noise_phi == b.noise_phi && a.outlier_faces == b.outlier_faces);
  CHECK(a.cv_curve == b.cv_curve && a.local_ladder_m == b.local_ladder_m);
  CHECK(Same(a.clean, b.clean));
  const Eigen::Index n = m.z.size();
  std::vector<double> d_int, d_sd, d_noise;
  double d_int_same_scale = 0;  // the largest intensity difference where both chose the same scale
  size_t other_scale = 0, far_scale = 0, stopped = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    // Differences in units of the exact noise sd (the noise the smoothing leaves).
    const double di = std::fabs(a.intensity[i] - b.intensity[i]) / a.intensity_noise_sd[i];
    d_int.push_back(di);
    d_sd.push_back(std::fabs(a.intensity_sd[i] - b.intensity_sd[i]) / a.intensity_sd[i]);
    d_noise.push_back(std::fabs(a.intensity_noise_sd[i] - b.intensity_noise_sd[i]) / a.intensity_noise_sd[i]);
    const double la = a.local_bandwidth_m[i], lb = b.local_bandwidth_m[i];
    if (la < a.bandwidth_m) ++stopped;
    if (la != lb) {
      ++other_scale;
      if (std::max(la, lb) > 1.5 * std::min(la, lb)) ++far_scale;  // ladder steps are 1.4x apart
    } else {
      d_int_same_scale = std::max(d_int_same_scale, di);
    }
  }
  auto q = [](std::vector<double> v, double p) {
    std::sort(v.begin(), v.end());
    return v[static_cast<size_t>(p * static_cast<double>(v.size() - 1))];
  };
  std::printf(
      "\n  binned vs face by face: intensity / noise sd median %.3g p99 %.3g (same scale: max %.3g); noise sd rel median %.3g "
      "p99 %.3g; sd rel median %.3g p99 %.3g; %zu faces at another scale (%zu stopped below the top)\n",
      q(d_int, 0.5), q(d_int, 0.99), d_int_same_scale, q(d_noise, 0.5), q(d_noise, 0.99), q(d_sd, 0.5), q(d_sd, 0.99),
      other_scale, stopped);
  CHECK(stopped > 1000);  // the band: the local scale is exercised
  CHECK(q(d_int, 0.5) < 0.05);
  CHECK(q(d_int, 0.99) < 0.5);
  CHECK(d_int_same_scale < 1.0);
  CHECK(q(d_noise, 0.5) < 0.005);
  CHECK(q(d_noise, 0.99) < 0.02);
  CHECK(q(d_sd, 0.5) < 0.005);
  CHECK(q(d_sd, 0.99) < 0.02);
  CHECK(other_scale < static_cast<size_t>(n) / 1000);  // < 0.1 % of the faces
  CHECK_EQUAL(0u, far_scale);
}

// binned_above_faces: a map with that many faces is still summed face by face (bit for bit the
// default result), one more face's worth of threshold lower and it is binned.
TEST(MapModel, MapsAtOrBelowTheThresholdAreSummedFaceByFace) {
  const WearMap m = NoisyBandedCone(48, 24);  // 2,304 faces
  MapModelOptions at, below;
  at.binned_above_faces = 2304;
  below.binned_above_faces = 2303;
  const MapModel d = BuildMapModel(m), a = BuildMapModel(m, at), b = BuildMapModel(m, below);
  CHECK(MapModelOptions{}.binned_above_faces == 200000);
  CHECK(Same(d.intensity, a.intensity) && Same(d.intensity_sd, a.intensity_sd) && Same(d.local_bandwidth_m, a.local_bandwidth_m));
  CHECK_FALSE(Same(d.intensity, b.intensity));
}

TEST(MapModel, BinnedSameResultWithOneOrTwoThreads) {
  const WearMap m = NoisyBandedCone(64, 36);
  MapModelOptions one, two;
  one.threads = 1;
  two.threads = 2;
  one.binned_above_faces = two.binned_above_faces = 0;
  const MapModel a = BuildMapModel(m, one), b = BuildMapModel(m, two);
  CHECK(a.local_ladder_m.size() > 1);
  CHECK(Same(a.intensity, b.intensity));
  CHECK(Same(a.intensity_sd, b.intensity_sd));
  CHECK(Same(a.intensity_noise_sd, b.intensity_noise_sd));
  CHECK(Same(a.local_bandwidth_m, b.local_bandwidth_m));
}

// A fixed kernel may be anisotropic: bandwidth_arc_m sets its scale around the circumference (a
// chamber's wear changes much faster along z than around), and each face's value is then the
// kernel mean over an ellipse 3x wider around than along z (compared with an isotropic kernel of
// the same z scale, which averages fewer faces around: a different value where the wear varies
// around the circumference).
TEST(MapModel, AFixedKernelTakesItsOwnScaleAroundTheCircumference) {
  WearMap m = lw::test::ConeMap(48, 24, 0.9, 1.4, [](double z) { return 1.0 + z; });
  for (Eigen::Index i = 0; i < m.wear.size(); ++i) m.wear[i] *= 1.0 + 0.5 * std::cos(3.0 * m.theta_deg[i] * M_PI / 180.0);
  MapModelOptions iso, wide;
  iso.bandwidth_m = wide.bandwidth_m = 0.1;
  wide.bandwidth_arc_m = 0.3;
  const MapModel a = BuildMapModel(m, iso), b = BuildMapModel(m, wide);
  CHECK_EQUAL(std::string("fixed"), b.bandwidth_method);
  DOUBLES_EQUAL(0.1, a.bandwidth_arc_m, 1e-15);
  DOUBLES_EQUAL(0.3, b.bandwidth_arc_m, 1e-15);
  DOUBLES_EQUAL(0.1, b.bandwidth_m, 1e-15);
  // The wider kernel around flattens the cos(3 theta) pattern more.
  auto spread = [&](const Eigen::VectorXd& v) {
    double lo = 1e300, hi = -1e300;
    for (Eigen::Index i = 0; i < v.size(); ++i)
      if (std::fabs(m.z[i] - 1.0) < 0.05) lo = std::min(lo, v[i]), hi = std::max(hi, v[i]);
    return hi - lo;
  };
  CHECK(spread(b.intensity) < 0.9 * spread(a.intensity));
}

// The smoothing's own error is what the cross-validated error holds beyond the noise law. A map
// whose faces carry structure no smoothing follows (here each face 6 % above or below the field, at
// random) and noise with a heavy tail (8 % of faces with three times the typical spread, as on the
// small faces of a finely meshed LIGGGHTS map) must give about 6 %: the tail must count in the
// error as it does in the noise law (clipped at 3 sd, the error read 0 here). The estimate is noisy
// (the tail) and a little low (the outlier caps at 5 sd take some of the tail out of the map, not of
// the law): seeds 1, 2, 3, 5, 6 gave 0.047, 0.025, 0.051, 0.064, 0.038.
TEST(MapModel, SmoothingErrorCountsTheNoiseTailAsTheNoiseLawDoes) {
  WearMap m = lw::test::ConeMap(96, 60, 0.9, 1.4, [](double z) { return 0.5 + std::pow(1.0 - z / 2.0, 1.5); });
  std::mt19937 rng(1);
  std::bernoulli_distribution sign(0.5), wide(0.08);
  std::normal_distribution<double> unit(0.0, 1.0);
  const double noise_rel = 0.15, narrow = std::sqrt(0.28 / 0.92);  // a mixture of unit variance
  m.wear_stderr.resize(m.wear.size());
  for (Eigen::Index i = 0; i < m.wear.size(); ++i) {
    const double field = m.wear[i];
    const double z = unit(rng) * (wide(rng) ? 3.0 : narrow);
    m.wear[i] = std::max(0.0, field * (sign(rng) ? 1.06 : 0.94) + noise_rel * field * z);
    m.wear_stderr[i] = noise_rel * field;
  }
  MapModelOptions options;
  options.max_cv_faces = 12000;  // every face: the tail makes the error's estimate noisy
  const MapModel model = BuildMapModel(m, options);
  CHECK_TEXT(model.smoothing_error_rel > 0.015 && model.smoothing_error_rel < 0.09,
             ("smoothing_error_rel = " + std::to_string(model.smoothing_error_rel)).c_str());
}

// intensity_broad is the (outlier-capped) wear smoothed with the normal stress's kernel: on a map whose
// stress is its wear and with no cap it equals the smoothed stress, face by face and at a point, on both
// the face-by-face and the binned path; a map without stress has none.
TEST(MapModel, TheBroadIntensityIsTheWearSmoothedLikeTheStress) {
  WearMap m = NoisyBandedCone(64, 36);
  m.normal_stress = m.wear;
  for (size_t binned_above : {size_t{200000}, size_t{0}}) {
    MapModelOptions opt;
    opt.robust = false;
    opt.binned_above_faces = binned_above;
    const MapModel model = BuildMapModel(m, opt);
    LONGS_EQUAL(m.wear.size(), model.intensity_broad.size());
    CHECK(model.normal_bandwidth_m > model.bandwidth_m);
    for (Eigen::Index i = 0; i < m.wear.size(); ++i)
      DOUBLES_EQUAL(model.normal_stress[i], model.intensity_broad[i], 1e-9 * std::fabs(model.normal_stress[i]));
    // Broader than the wear's own smoothing: the bottom band's contrast is lower.
    const MapModel::Point band = model.At(0.1, 45.0), above = model.At(0.6, 45.0);
    DOUBLES_EQUAL(band.normal_stress, band.intensity_broad, 1e-9 * band.normal_stress);
    CHECK(band.intensity_broad / above.intensity_broad < band.intensity / above.intensity);
  }
  WearMap no_stress = NoisyBandedCone(32, 18);
  no_stress.normal_stress.resize(0);
  CHECK(BuildMapModel(no_stress, MapModelOptions{}).intensity_broad.size() == 0);
}
