// Diagnosis on real-DEM-like maps: LIGGGHTS' own VTK layout, no stress arrays, patchy or
// %f-truncated intensity, and the real LIGGGHTS output in tests/data. Nothing may crash, hypotheses
// that need a missing field are skipped with a note, and map defects are no physics finding.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/bundle.hpp"
#include "diagnosis/diagnose.hpp"
#include "support/temp_directory.hpp"
#include "unit/diagnosis/synthetic_bundle.hpp"

// CppUTest last: its leak-detector macros redefine new.
#include <CppUTest/TestHarness.h>

namespace {

lw::diagnosis::DiagnosisResult Run(const lw::test::SyntheticSpec& spec) {
  const lw::test::TempDirectory tmp("lw-diag-map");
  const auto& dir = tmp.path();
  lw::test::WriteSyntheticBundle(dir, spec);
  const lw::core::Bundle bundle = lw::core::LoadBundle(dir);
  lw::diagnosis::DiagnoseOptions options;
  options.try_pairs = false;
  return lw::diagnosis::Diagnose(bundle, options);
}

bool HasNote(const lw::diagnosis::DiagnosisResult& r, const std::string& text) {
  for (const auto& n : r.notes)
    if (n.find(text) != std::string::npos) return true;
  return false;
}

bool Tried(const lw::diagnosis::DiagnosisResult& r, const std::string& model) {
  for (const auto& h : r.hypotheses)
    if (h.at("model").get<std::string>().find(model) != std::string::npos) return true;
  return false;
}

}  // namespace

TEST_GROUP(DiagnoseMaps){};

TEST(DiagnoseMaps, LiggghtsMapWithoutStressArraysSkipsStressHypothesesWithANote) {
  lw::test::SyntheticSpec spec;
  spec.seed = 11;
  spec.map_format = "liggghts";
  spec.with_normal_stress = false;
  spec.map_noise = 0.3;          // count-limited DEM: patchy per-face intensity
  spec.map_zero_fraction = 0.2;  // faces no particle hit
  const auto r = Run(spec);
  CHECK_TRUE(HasNote(r, "no normal_stress_average"));
  CHECK_FALSE(Tried(r, "squeeze_wear"));
  CHECK_TRUE(Tried(r, "work_hardening"));  // still tried, as a uniform time effect
  // A patchy map: the map model sees its noise and smooths it (every intensity, the sensors' too,
  // comes from the smoothed map); it is no physics finding.
  CHECK_TRUE(r.noise.at("map_model").at("face_relative_noise").get<double>() > 0.15);
  CHECK_TRUE(r.noise.at("map_model").at("bandwidth_m").get<double>() > 0.0);
  CHECK_TRUE(r.findings.empty());
  CHECK_FALSE(r.mismatch_detected);
}

TEST(DiagnoseMaps, WorkHardeningIsFoundOnAMapWithoutStressArrays) {
  lw::test::SyntheticSpec spec;
  spec.map_format = "liggghts";
  spec.with_normal_stress = false;
  spec.hardening_h = 0.5;
  const auto r = Run(spec);
  CHECK_FALSE(r.findings.empty());
  STRCMP_EQUAL("work_hardening", r.findings[0].effect.c_str());
  STRCMP_EQUAL("uniform (map has no normal stress)", r.findings[0].parameters.at("weighted_by").get<std::string>().c_str());
}

TEST(DiagnoseMaps, TruncatedMapIsNotedAndGivesNoFalseFinding) {
  lw::test::SyntheticSpec spec;
  spec.seed = 12;
  spec.map_format = "liggghts";
  spec.map_printf_f = true;  // "%f": 6 decimals
  spec.map_scale = 4e-6;     // so each face's wear keeps only one or two significant digits
  const lw::test::TempDirectory tmp("lw-diag-trunc");
  const auto& dir = tmp.path();
  lw::test::WriteSyntheticBundle(dir, spec);
  const lw::core::Bundle bundle = lw::core::LoadBundle(dir);
  CHECK_TRUE(bundle.map_validation.looks_truncated);
  const auto r = lw::diagnosis::Diagnose(bundle);
  CHECK_TRUE(HasNote(r, "truncated"));
  CHECK_TRUE(r.findings.empty());
}

TEST(DiagnoseMaps, RealLiggghtsOutputAsTheMapDoesNotCrash) {
  // The two-triangle plate LIGGGHTS wrote (tests/data): not a liner, one face with zero stress and wear
  // far from the other; the diagnosis must run, report the sensors and name no physics.
  const lw::test::TempDirectory tmp("lw-diag-liggghts");
  const auto& dir = tmp.path();
  std::filesystem::copy_file(std::filesystem::path(LW_SAMPLES_DIR) / "liggghts_plate_wear.vtk", dir / "wear_map.vtk");
  {
    std::ofstream c(dir / "crusher.json");
    c << R"({"crusher_id": "plate", "installed_at": "2024-01-01T00:00:00Z", "concave": {"thickness_new_mm": 100,
          "thickness_min_mm": 20, "rows": [{"name": "R1", "z_min_m": -0.2, "z_max_m": 0.2}]},
          "sensors": [{"id": "S1", "row": "R1", "z_m": -0.1, "theta_deg": 300, "thickness_new_mm": 100},
                      {"id": "S2", "row": "R1", "z_m": 0.1, "theta_deg": 60, "thickness_new_mm": 100}]})";
    std::ofstream rd(dir / "readings.csv");
    rd << "time,sensor_id,thickness_mm\n";
    // Every 6 hours for 40 days; a reading n means thickness in [n, n + 1).
    for (int q = 1; q <= 160; ++q) {
      const int day = (q / 4) % 31 + 1, month = q / 4 < 31 ? 1 : 2;
      char t[32];
      std::snprintf(t, sizeof t, "2024-%02d-%02dT%02d:00:00Z", month, month == 1 ? day : q / 4 - 30, 6 * (q % 4));
      rd << t << ",S1," << std::floor(100 - 0.5 * q / 4.0) << "\n" << t << ",S2," << std::floor(100 - q / 12.0) << "\n";
    }
  }
  const lw::core::Bundle bundle = lw::core::LoadBundle(dir);
  lw::diagnosis::DiagnoseOptions options;
  options.predict_at = lw::core::AddDays(bundle.crusher.installed_at, 60);
  const auto r = lw::diagnosis::Diagnose(bundle, options);
  for (const auto& f : r.findings) CHECK_TRUE(f.effect == "unexplained");
  CHECK_TRUE(r.prediction.has_value());
  LONGS_EQUAL(2, r.prediction->sensors.size());
  for (const auto& s : r.prediction->sensors) CHECK_TRUE(std::isfinite(s.improved_thickness_mm));
  const auto j = lw::diagnosis::ToJson(r);
  CHECK_TRUE(j.at("findings").is_array());
}
