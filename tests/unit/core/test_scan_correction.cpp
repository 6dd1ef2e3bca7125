// A laser scan corrects the live map between the sensors (core/scan_correction.hpp): the DEM map's
// pattern is wrong, the scan measured the right one, and Eq. 9 after the scan follows the scan.
#include <cmath>
#include <random>

#include "core/reconstruction.hpp"
#include "core/scan_correction.hpp"
#include "unit/core/bundle_fixture.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw::core;
using lw::test::TwoRows;

namespace {

// True wear (mm) at height z after `days`: the DEM map (uniform) missed that wear doubles towards
// the discharge edge.
double TrueWear(double z, double days) {
  return 0.4 * days * (2.0 - 0.5 * z) * (1.0 + 0.5 * std::max(0.0, 0.6 - z));
}

Scan MakeScan(const WearMap& m, double days, double noise_mm, unsigned seed, long skip_face = -1) {
  Scan s;
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, noise_mm);
  for (size_t f = 0; f < m.faces.size(); ++f) {
    if (static_cast<long>(f) == skip_face) continue;  // no point fell on this face
    const double w = TrueWear(m.z[static_cast<Eigen::Index>(f)], days);
    for (int k = 0; k < 3; ++k) s.points.push_back(m.centroids[f] - m.normals[f] * (w + g(rng)) / 1000.0);
  }
  return s;
}

std::vector<SensorWear> SensorsAt(const CrusherConfig& c, double days) {
  std::vector<SensorWear> out;
  for (const auto& s : c.sensors) out.push_back({s.id, TrueWear(s.z_m, days)});
  return out;
}

double Rms(const Reconstruction& r, const WearMap& m, double days) {
  double ss = 0;
  for (Eigen::Index i = 0; i < m.z.size(); ++i) ss += std::pow(r.wear_mm[i] - TrueWear(m.z[i], days), 2);
  return std::sqrt(ss / static_cast<double>(m.z.size()));
}

}  // namespace

TEST_GROUP(ScanCorrection){};

TEST(ScanCorrection, ProjectionRecoversEachFacesDepth) {
  const WearMap m = lw::test::CylinderMap(36, 40, [](double) { return 1.0; });
  const Scan s = MakeScan(m, 50, 0.0, 1);
  const ScanFaces f = ProjectScanToFaces(m, s);
  LONGS_EQUAL(s.points.size(), f.points_used);
  for (Eigen::Index i = 0; i < m.z.size(); i += 37) {
    DOUBLES_EQUAL(TrueWear(m.z[i], 50), f.wear_mm[i], 1e-6);
    LONGS_EQUAL(3, f.points[static_cast<size_t>(i)]);
  }
}

TEST(ScanCorrection, LaterLiveWearFollowsTheScannedPatternNotTheMaps) {
  const CrusherConfig c = TwoRows();
  const WearMap m = lw::test::CylinderMap(36, 40, [](double) { return 1.0; });
  ReconstructionPlan plan = PrepareReconstruction(c, m);
  const Reconstruction before = Reconstruct(plan, SensorsAt(c, 80));
  const ScanFaces f = ProjectScanToFaces(m, MakeScan(m, 50, 0.3, 2));
  const ScanCorrection corr = ApplyScan(plan, f, SensorsAt(c, 50));
  CHECK(corr.detail.empty());
  LONGS_EQUAL(m.face_count(), corr.faces_corrected);
  const Reconstruction after = Reconstruct(plan, SensorsAt(c, 80));
  // The uniform map puts the same wear on every face of a row; the scan's pattern is right.
  const double truth_min = 120.0 - TrueWear(m.z.minCoeff(), 80);
  CHECK(std::fabs(before.min_thickness_mm - truth_min) > 10.0);
  DOUBLES_EQUAL(truth_min, after.min_thickness_mm, 1.5);
  const double rms_before = Rms(before, m, 80), rms_after = Rms(after, m, 80);
  CHECK_TEXT(rms_after < 0.25 * rms_before, (std::to_string(rms_after) + " vs " + std::to_string(rms_before)).c_str());
  CHECK(after.min_thickness_lo_mm <= truth_min && truth_min <= after.min_thickness_hi_mm);
}

TEST(ScanCorrection, ScanOfAnotherMapOrWithoutSensorReadingsLeavesThePlanAlone) {
  const CrusherConfig c = TwoRows();
  const WearMap m = lw::test::CylinderMap(36, 40, [](double) { return 1.0; });
  const WearMap other = lw::test::CylinderMap(12, 10, [](double) { return 1.0; });
  ReconstructionPlan plan = PrepareReconstruction(c, m);
  const Eigen::VectorXd before = plan.intensity;
  const ScanCorrection a = ApplyScan(plan, ProjectScanToFaces(other, MakeScan(other, 50, 0.3, 3)), SensorsAt(c, 50));
  CHECK(!a.detail.empty());
  const ScanCorrection b = ApplyScan(plan, ProjectScanToFaces(m, MakeScan(m, 50, 0.3, 4)), {});
  CHECK(!b.detail.empty());
  CHECK((plan.intensity - before).cwiseAbs().maxCoeff() == 0.0);
}

TEST(ScanCorrection, AFaceNoScanPointFellOnTakesItsNeighboursCorrection) {
  // The map model has a hot spot (up to 3x, a few faces across, as its smoothing makes any) in the
  // lowest ring that the truth does not have, and the scan (3 points a face) happens to put no point
  // on the face at its centre: that face must not stay the thinnest point of the liner.
  const CrusherConfig c = TwoRows();
  const WearMap m = lw::test::CylinderMap(36, 40, [](double) { return 1.0; });
  ReconstructionPlan plan = PrepareReconstruction(c, m);
  Eigen::Index hot = 0;
  for (Eigen::Index i = 0; i < m.z.size(); ++i)
    if (m.z[i] < m.z[hot] || (m.z[i] == m.z[hot] && std::fabs(m.theta_deg[i] - 100.0) < std::fabs(m.theta_deg[hot] - 100.0)))
      hot = i;
  for (Eigen::Index i = 0; i < m.z.size(); ++i) {
    const double dz = m.z[i] - m.z[hot], da = std::remainder(m.theta_deg[i] - m.theta_deg[hot], 360.0) * 3.14159265 / 180.0;
    plan.intensity[i] *= 1.0 + 2.0 * std::exp(-0.5 * (dz * dz + da * da) / (0.15 * 0.15));
  }
  const ScanFaces f = ProjectScanToFaces(m, MakeScan(m, 50, 0.3, 5, static_cast<long>(hot)));
  CHECK_FALSE(std::isfinite(f.wear_mm[hot]));
  const Eigen::VectorXd map_intensity = plan.intensity;
  const ScanCorrection corr = ApplyScan(plan, f, SensorsAt(c, 50));
  CHECK(corr.detail.empty());
  LONGS_EQUAL(m.face_count() - 1, corr.faces_corrected);
  LONGS_EQUAL(1, corr.faces_filled);
  // Per face, what other models need: the scan's weight (none where no point fell) and the ratio
  // the live map's intensity was corrected by (the filled face's from its neighbours).
  LONGS_EQUAL(m.z.size(), corr.face_weight.size());
  for (Eigen::Index i = 0; i < m.z.size(); ++i) {
    DOUBLES_EQUAL(plan.intensity[i] / map_intensity[i], corr.face_ratio[i], 1e-12);
    if (i == hot) continue;
    CHECK(corr.face_weight[i] > 0.0 && corr.face_weight[i] <= 1.0);
  }
  DOUBLES_EQUAL(0.0, corr.face_weight[hot], 0.0);
  CHECK(corr.face_ratio[hot] < 0.6);  // the 3x hot spot the scan does not see
  const Reconstruction after = Reconstruct(plan, SensorsAt(c, 80));
  const double truth_min = 120.0 - TrueWear(m.z.minCoeff(), 80);
  DOUBLES_EQUAL(truth_min, after.min_thickness_mm, 1.5);
  // Its neighbours' scanned intensities, interpolated: within 5 mm of the truth at the bottom edge,
  // where the neighbours all lie above it and the truth wears more downwards (was 3x: worn through).
  DOUBLES_EQUAL(TrueWear(m.z[hot], 80), after.wear_mm[hot], 5.0);
}

TEST(ScanCorrection, AFaceEq9HadWornThroughAtTheScanIsCorrectedByTheScan) {
  // A hot spot so strong (20x) that Eq. 9 has the face worn through at the scan's date: its wear is
  // clamped there, so the scan's intensity must use the row's scale, not the clamped wear.
  const CrusherConfig c = TwoRows();
  const WearMap m = lw::test::CylinderMap(36, 40, [](double) { return 1.0; });
  ReconstructionPlan plan = PrepareReconstruction(c, m);
  const Eigen::Index hot = 5;
  plan.intensity[hot] *= 20.0;
  CHECK(Reconstruct(plan, SensorsAt(c, 50)).wear_mm[hot] >= c.thickness_new_mm);
  const ScanCorrection corr = ApplyScan(plan, ProjectScanToFaces(m, MakeScan(m, 50, 0.3, 6)), SensorsAt(c, 50));
  LONGS_EQUAL(m.face_count(), corr.faces_corrected);
  const Reconstruction after = Reconstruct(plan, SensorsAt(c, 80));
  DOUBLES_EQUAL(TrueWear(m.z[hot], 80), after.wear_mm[hot], 1.5);
}

TEST(ScanCorrection, AHotSpotNarrowerThanTheMapsKernelFollowsTheScan) {
  // The truth's wear is 30 % higher on a narrow sector of the lowest ring (a few faces), which the
  // map, and the map model's smoothing, do not show. Too few faces to raise the band's or the scan's
  // model-error figure: the scan, ground truth at its date, must still win there.
  const CrusherConfig c = TwoRows();
  // The map has the truth's pattern along z, so the scan finds it right everywhere but the sector.
  const WearMap m = lw::test::CylinderMap(36, 40, [](double z) { return TrueWear(z, 1.0); });
  auto hot = [&](Eigen::Index i) { return m.z[i] <= m.z.minCoeff() + 1e-9 && std::fabs(m.theta_deg[i] - 100.0) < 12.0; };
  auto truth = [&](Eigen::Index i, double days) { return TrueWear(m.z[i], days) * (hot(i) ? 1.3 : 1.0); };
  Scan s;
  std::mt19937 rng(7);
  std::normal_distribution<double> g(0.0, 0.3);
  for (size_t f = 0; f < m.faces.size(); ++f)
    for (int k = 0; k < 3; ++k)
      s.points.push_back(m.centroids[f] - m.normals[f] * (truth(static_cast<Eigen::Index>(f), 50) + g(rng)) / 1000.0);
  ReconstructionPlan plan = PrepareReconstruction(c, m);
  const ScanCorrection corr = ApplyScan(plan, ProjectScanToFaces(m, s), SensorsAt(c, 50));
  CHECK(corr.detail.empty());
  const Reconstruction after = Reconstruct(plan, SensorsAt(c, 80));
  double truth_max = 0;
  for (Eigen::Index i = 0; i < m.z.size(); ++i) truth_max = std::max(truth_max, truth(i, 80));
  DOUBLES_EQUAL(120.0 - truth_max, after.min_thickness_mm, 3.0);
}
