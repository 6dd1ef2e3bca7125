#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <vector>

#include "core/wear_map.hpp"
#include "support/temp_directory.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw::core;

namespace {
// A small cone section: n_theta x n_z quads split into triangles, wound outward on purpose for
// half of them so orientation repair is exercised.
WearMap Cone(int nt, int nz) {
  WearMap m;
  for (int k = 0; k <= nz; ++k) {
    for (int j = 0; j < nt; ++j) {
      const double th = 2 * M_PI * j / nt, z = 0.1 * k, r = 1.0 + 0.2 * z;
      m.points.emplace_back(r * std::cos(th), r * std::sin(th), z);
    }
  }
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < nt; ++j) {
      const auto a = static_cast<uint32_t>(k * nt + j), b = static_cast<uint32_t>(k * nt + (j + 1) % nt);
      const auto c = a + static_cast<uint32_t>(nt), d = b + static_cast<uint32_t>(nt);
      m.faces.push_back({a, b, d});
      m.faces.push_back({a, c, d});
    }
  }
  m.wear = Eigen::VectorXd::LinSpaced(static_cast<Eigen::Index>(m.faces.size()), 0.5, 2.0);
  m.normal_stress = Eigen::VectorXd::Constant(static_cast<Eigen::Index>(m.faces.size()), 3.0);
  return m;
}
/// Writes `text` as `name` and loads it: the InputError's message, "" when it loaded, and any
/// other exception named as such (a map must be refused with file, line and rule, not crash).
std::string LoadError(const lw::test::TempDirectory& dir, const std::string& name, const std::string& text) {
  dir.Write(name, text);
  try {
    LoadWearMap(dir.path() / name);
  } catch (const InputError& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("not an InputError: ") + e.what();
  }
  return "";
}
}  // namespace

TEST_GROUP(WearMap){};

TEST(WearMap, ReadsTheLiggghtsSampleExactly) {
  MapValidation v;
  const WearMap m = LoadWearMap(std::string(LW_SAMPLES_DIR) + "/liggghts_plate_wear.vtk", &v);
  LONGS_EQUAL(2, m.face_count());
  LONGS_EQUAL(6, m.points.size());
  CHECK(m.has_normal_stress());
  CHECK(m.has_shear_stress());
  DOUBLES_EQUAL(419.82358891, m.normal_stress[0], 1e-9);
  DOUBLES_EQUAL(48.331700187, m.shear_stress[0], 1e-9);
  DOUBLES_EQUAL(0.0, m.normal_stress[1], 1e-12);
  LONGS_EQUAL(64, m.sha256.size());
  DOUBLES_EQUAL(0.5 * std::sqrt(1.0 + 0.16), m.areas[0], 1e-6);  // half of the 1 x 1.077 m plate
}

TEST(WearMap, WriterOutputReadsBackIdentically) {
  lw::test::TempDirectory dir;
  WearMap m = Cone(12, 5);
  const Eigen::VectorXd extra = m.wear * 2.0;
  WriteWearMapVtk(dir.path() / "m.vtk", m, {{"wear", &m.wear}, {"normal_stress_average", &m.normal_stress}, {"wear_mm", &extra}});
  // Written through a temporary that is gone afterwards: the folder holds the map alone.
  LONGS_EQUAL(1, std::distance(std::filesystem::directory_iterator(dir.path()), std::filesystem::directory_iterator()));
  MapValidation v;
  const WearMap back = LoadWearMap(dir.path() / "m.vtk", &v);
  LONGS_EQUAL(m.face_count(), back.face_count());
  CHECK(back.wear.isApprox(m.wear, 1e-9));
  CHECK(back.normal_stress.isApprox(m.normal_stress, 1e-9));
  CHECK(back.extra.at("wear_mm").isApprox(extra, 1e-9));
  // Every normal points towards the axis, whatever the winding in the file.
  for (size_t i = 0; i < back.face_count(); ++i) {
    const Eigen::Vector3d radial(back.centroids[i].x(), back.centroids[i].y(), 0);
    CHECK(back.normals[i].dot(radial) < 0);
  }
  CHECK(v.outward_faces_flipped > 0);
}

TEST(WearMap, Vtk42ScalarsAndFieldFormsBothRead) {
  lw::test::TempDirectory dir;
  const std::string head =
      "# vtk DataFile Version 4.2\nmap\nASCII\nDATASET POLYDATA\nPOINTS 4 float\n"
      "1 0 0  0 1 0  1 0 1  0 1 1\nPOLYGONS 2 8\n3 0 1 2\n3 1 3 2\nCELL_DATA 2\n";
  dir.Write("a.vtk", head + "SCALARS wear float 1\nLOOKUP_TABLE default\n0.5\n1.5\n");
  dir.Write("b.vtk", head + "FIELD FieldData 2\nwear 1 2 double\n0.5 1.5\nnormal_stress_average 1 2 double\n7 8\n");
  const WearMap a = LoadWearMap(dir.path() / "a.vtk");
  const WearMap b = LoadWearMap(dir.path() / "b.vtk");
  DOUBLES_EQUAL(1.5, a.wear[1], 1e-12);
  DOUBLES_EQUAL(1.5, b.wear[1], 1e-12);
  DOUBLES_EQUAL(8.0, b.normal_stress[1], 1e-12);
  CHECK(a.sha256 != b.sha256);
}

// The parser reads numbers in place (from_chars): every spelling a VTK writer uses gives the same
// double as strtod, to the last bit (both round correctly), and the rest is refused as before.
TEST(WearMap, NumbersReadToTheSameDoubleAsStrtod) {
  lw::test::TempDirectory dir;
  std::vector<std::string> spellings = {"0.5",
                                        "+1.25",
                                        "3",
                                        "1e-5",
                                        "2.5E+02",
                                        ".75",
                                        "7.",
                                        "0.1",
                                        "1e-320",
                                        "4.9406564584124654e-324",
                                        "1.7976931348623157e308",
                                        "123456789012345678901234567890",
                                        "0.30000000000000004"};
  std::mt19937_64 rng(16);
  std::uniform_real_distribution<double> u(0.0, 5.0);
  for (int i = 0; i < 200; ++i) {
    char b[40];
    std::snprintf(b, sizeof b, i % 2 ? "%.17g" : "%.6e", u(rng) * std::pow(10.0, i % 9 - 4));
    spellings.push_back(b);
  }
  const size_t n = spellings.size();
  std::string text = "# vtk DataFile Version 4.2\nmap\nASCII\nDATASET POLYDATA\nPOINTS " + std::to_string(n + 2) + " double\n";
  for (size_t i = 0; i < n + 2; ++i) text += std::to_string(i % 2) + " " + std::to_string(i / 2) + " 0.5\n";
  text += "POLYGONS " + std::to_string(n) + " " + std::to_string(4 * n) + "\n";
  for (size_t i = 0; i < n; ++i)
    text += "3 " + std::to_string(i) + " " + std::to_string(i + 1) + " " + std::to_string(i + 2) + "\n";
  // The spellings go in a stress array: `wear` itself must lie on a usable scale (its own test).
  text += "CELL_DATA " + std::to_string(n) + "\nSCALARS wear double 1\nLOOKUP_TABLE default\n";
  for (size_t i = 0; i < n; ++i) text += "1\n";
  text += "SCALARS normal_stress_average double 1\nLOOKUP_TABLE default\n";
  for (const std::string& w : spellings) text += w + "\n";
  dir.Write("n.vtk", text);
  const WearMap m = LoadWearMap(dir.path() / "n.vtk");
  for (size_t i = 0; i < n; ++i) {
    const double expected = std::strtod(spellings[i].c_str(), nullptr);
    CHECK_TEXT(m.normal_stress[static_cast<Eigen::Index>(i)] == expected, spellings[i].c_str());
  }
  // Beyond double's range, and not numbers at all: refused, naming the line.
  const std::string head = "# vtk DataFile Version 4.2\nmap\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n";
  STRCMP_CONTAINS("n.vtk:6: x '1e999' is not finite", LoadError(dir, "n.vtk", head + "1e999 0 0\n0 1 0\n1 1 0\n").c_str());
  STRCMP_CONTAINS("n.vtk:7: y '0x10' is not a number", LoadError(dir, "n.vtk", head + "1 0 0\n0 0x10 0\n1 1 0\n").c_str());
  STRCMP_CONTAINS("n.vtk:6: z '1.5.2' is not a number", LoadError(dir, "n.vtk", head + "1 0 1.5.2\n0 1 0\n1 1 0\n").c_str());
}

TEST(WearMap, CsvExportReads) {
  lw::test::TempDirectory dir;
  dir.Write("m.csv",
            "x1,y1,z1,x2,y2,z2,x3,y3,z3,wear,normal_stress_average\n"
            "1,0,0,0,1,0,1,0,1,0.25,3\n0,1,0,0,1,1,1,0,1,0.75,4\n");
  const WearMap m = LoadWearMap(dir.path() / "m.csv");
  LONGS_EQUAL(2, m.face_count());
  DOUBLES_EQUAL(0.75, m.wear[1], 1e-12);
  DOUBLES_EQUAL(4.0, m.normal_stress[1], 1e-12);
}

TEST(WearMap, BadMapsNameFileLineAndRule) {
  lw::test::TempDirectory dir;
  auto message = [&](const std::string& name, const std::string& text) { return LoadError(dir, name, text); };
  const std::string head = "# vtk DataFile Version 4.2\nmap\nASCII\nDATASET POLYDATA\nPOINTS 4 float\n1 0 0 0 1 0 1 0 1 0 1 1\n";
  std::string m =
      message("quad.vtk", head + "POLYGONS 1 5\n4 0 1 3 2\nCELL_DATA 1\nSCALARS wear float\nLOOKUP_TABLE default\n1\n");
  CHECK(m.find("quad.vtk:8") != std::string::npos);
  CHECK(m.find("only triangles") != std::string::npos);
  m = message("nowear.vtk", head + "POLYGONS 1 4\n3 0 1 2\nCELL_DATA 1\nSCALARS other float\nLOOKUP_TABLE default\n1\n");
  CHECK(m.find("'wear'") != std::string::npos);
  m = message("nan.vtk", head + "POLYGONS 1 4\n3 0 1 2\nCELL_DATA 1\nSCALARS wear float\nLOOKUP_TABLE default\nabc\n");
  CHECK(m.find("nan.vtk:12") != std::string::npos);
  m = message("binary.vtk", "# vtk DataFile Version 4.2\nmap\nBINARY\n");
  CHECK(m.find("ASCII") != std::string::npos);
  m = message("range.vtk", head + "POLYGONS 1 4\n3 0 1 9\nCELL_DATA 1\nSCALARS wear float\nLOOKUP_TABLE default\n1\n");
  CHECK(m.find("point 9") != std::string::npos);
  m = message("short.csv", "x1,y1,z1,x2,y2,z2,x3,y3,z3,wear\n1,0,0,0,1,0,1,0,1\n");
  CHECK(m.find("short.csv:2") != std::string::npos);
  CHECK(message("m.stl", "solid").find("unknown map format") != std::string::npos);
}

// Found by fuzz/ (fuzz_wear_map_vtk): counts the file cannot hold were allocated before reading
// (a 4e9-point header asked for 96 GB), counts above 2^63 were cast to integers (undefined
// behaviour), VTK 5.1 OFFSETS past CONNECTIVITY were read out of bounds, and huge coordinates made
// areas and normals infinite. Each must be a clear InputError naming the rule.
TEST(WearMap, AbsurdCountsOffsetsAndCoordinatesAreInputErrors) {
  lw::test::TempDirectory dir;
  auto message = [&](const std::string& name, const std::string& text) { return LoadError(dir, name, text); };
  const std::string v42 = "# vtk DataFile Version 4.2\nmap\nASCII\nDATASET POLYDATA\n";
  const std::string tail = "POLYGONS 1 4\n3 0 1 2\nCELL_DATA 1\nSCALARS wear float\nLOOKUP_TABLE default\n1\n";
  std::string m = message("points.vtk", v42 + "POINTS 4000000000 float\n1 0 0 0 1 0 1 0 1\n" + tail);
  CHECK_TEXT(m.find("points.vtk:5") != std::string::npos && m.find("point count 4000000000 needs 3") != std::string::npos,
             m.c_str());
  m = message("cast.vtk", v42 + "POINTS 1e19 float\n1 0 0\n");
  CHECK_TEXT(m.find("[0, 4294967295]") != std::string::npos, m.c_str());
  m = message("cells.vtk", v42 + "POINTS 3 float\n1 0 0 0 1 0 1 0 1\nPOLYGONS 1 4\n3000000000 0 1 2\n");
  CHECK_TEXT(m.find("vertex count") != std::string::npos, m.c_str());
  m = message("scalars.vtk", v42 +
                                 "POINTS 3 float\n1 0 0 0 1 0 1 0 1\nPOLYGONS 1 4\n3 0 1 2\nCELL_DATA 3000000000\n"
                                 "SCALARS wear float 3000000000\nLOOKUP_TABLE default\n1\n");
  CHECK_TEXT(m.find("SCALARS wear: component count must be 1-9") != std::string::npos, m.c_str());
  m = message("field.vtk", v42 +
                               "POINTS 3 float\n1 0 0 0 1 0 1 0 1\nPOLYGONS 1 4\n3 0 1 2\nCELL_DATA 1\n"
                               "FIELD FieldData 1\nwear 4000000000 1 double\n1\n");
  CHECK_TEXT(m.find("component count 4000000000 needs") != std::string::npos, m.c_str());
  const std::string v51 = "# vtk DataFile Version 5.1\nmap\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n1 0 0 0 1 0 1 0 1\n";
  m = message("offsets.vtk", v51 +
                                 "POLYGONS 2 3\nOFFSETS vtktypeint64\n4000 4003\nCONNECTIVITY vtktypeint64\n0 1 2\n"
                                 "CELL_DATA 1\nFIELD FieldData 1\nwear 1 1 double\n1\n");
  CHECK_TEXT(m.find("OFFSETS") != std::string::npos, m.c_str());
  m = message("far.vtk", v42 + "POINTS 3 float\n1e200 0 0 0 1e200 0 1 0 1e200\n" + tail);
  CHECK_TEXT(m.find("far.vtk:6: vertex (1e+200, 0, 0) is more than 1000 m") != std::string::npos, m.c_str());
  m = message("far.csv", "x1,y1,z1,x2,y2,z2,x3,y3,z3,wear\n1,0,0,0,1,0,1,0,2e6,1\n");
  CHECK_TEXT(m.find("is more than 1000 m from the crusher origin") != std::string::npos, m.c_str());
}

TEST(WearMap, ParsesFromMemoryLikeFromAFile) {
  lw::test::TempDirectory dir;
  const std::string csv = "x1,y1,z1,x2,y2,z2,x3,y3,z3,wear\n1,0,0,0,1,0,1,0,1,0.5\n";
  dir.Write("m.csv", csv);
  const WearMap from_file = LoadWearMap(dir.path() / "m.csv");
  const WearMap from_memory = ParseWearMap(csv, "m.csv");
  CHECK_EQUAL(from_file.sha256, from_memory.sha256);
  LONGS_EQUAL(1, from_memory.face_count());
  DOUBLES_EQUAL(0.5, from_memory.wear[0], 0);
  try {
    ParseWearMap(csv, "m.stl");
    FAIL("an unknown extension was accepted");
  } catch (const InputError& e) {
    CHECK_EQUAL(std::string("m.stl"), e.file());
  }
}

TEST(WearMap, ValidationFlagsZeroAndTruncatedMaps) {
  lw::test::TempDirectory dir;
  WearMap m = Cone(12, 5);
  for (Eigen::Index i = 0; i < m.wear.size(); ++i) m.wear[i] = (i % 3 == 0) ? 0.0 : 0.000001 * static_cast<double>(i % 4 + 1);
  WriteWearMapVtk(dir.path() / "t.vtk", m, {{"wear", &m.wear}});
  MapValidation v;
  LoadWearMap(dir.path() / "t.vtk", &v);
  CHECK(v.zero_wear_fraction > 0.3);
  CHECK(v.looks_truncated);
  CHECK(v.warnings.size() >= 2);
}

// Maps that would load and then give plausible wrong answers are refused with file, line and rule.
TEST(WearMap, ImplausibleMapsAreRefusedNotLoaded) {
  lw::test::TempDirectory dir;
  auto message = [&](const std::string& name, const std::string& text) { return LoadError(dir, name, text); };
  const std::string head = "# vtk DataFile Version 4.2\nmap\nASCII\nDATASET POLYDATA\n";
  const std::string tri =
      "POINTS 3 float\n1 0 0 0 1 0 1 0 1\nPOLYGONS 1 4\n3 0 1 2\nCELL_DATA 1\nSCALARS wear float\nLOOKUP_TABLE default\n";
  std::string m = message("neg.vtk", head + tri + "-0.5\n");
  CHECK(m.find("neg.vtk:12") != std::string::npos);
  CHECK(m.find(">= 0") != std::string::npos);
  m = message("zero.vtk", head + tri + "0\n");
  CHECK(m.find("zero.vtk") != std::string::npos);
  CHECK(m.find("zero wear") != std::string::npos);
  m = message("far.vtk", head +
                             "POINTS 3 float\n1 0 0 0 1 0 1e308 0 1\nPOLYGONS 1 4\n3 0 1 2\nCELL_DATA 1\nSCALARS wear "
                             "float\nLOOKUP_TABLE default\n1\n");
  CHECK(m.find("far.vtk:6") != std::string::npos);
  CHECK(m.find("from the crusher origin") != std::string::npos);
  m = message("huge.vtk", head + "POINTS 4000000000000 float\n1 0 0\n");
  CHECK(m.find("huge.vtk:5") != std::string::npos);
  CHECK(m.find("[0, 4294967295]") != std::string::npos);
  m = message("many.vtk", head + "POINTS 4000000 float\n1 0 0\n");
  CHECK(m.find("the file holds only") != std::string::npos);
  m = message("cells.vtk", head + "POINTS 3 float\n1 0 0 0 1 0 1 0 1\nPOLYGONS 99999999999 4\n3 0 1 2\n");
  CHECK(m.find("[0, 4294967295]") != std::string::npos);
  // Findings: "Version 99.0" was read as a legacy file, and a second wear array replaced the first unseen.
  m = message("v99.vtk", "# vtk DataFile Version 99.0\nmap\nASCII\nDATASET POLYDATA\n" + tri + "1\n");
  CHECK_TEXT(m.find("v99.vtk:1") != std::string::npos && m.find("VTK version '99.0'") != std::string::npos, m.c_str());
  m = message("v5.vtk", "# vtk DataFile Version 5.9\nmap\nASCII\nDATASET POLYDATA\n" + tri + "1\n");
  CHECK_TEXT(m.find("VTK version '5.9'") != std::string::npos, m.c_str());
  m = message("twice.vtk", head + tri + "1\nFIELD FieldData 1\nwear 1 1 double\n1000\n");
  CHECK_TEXT(m.find("twice.vtk:14") != std::string::npos && m.find("cell array 'wear' appears twice") != std::string::npos,
             m.c_str());
  m = message("neg.csv", "x1,y1,z1,x2,y2,z2,x3,y3,z3,wear\n1,0,0,0,1,0,1,0,1,1\n1,0,0,0,1,0,1,0,1,-2\n");
  CHECK(m.find("neg.csv:3") != std::string::npos);
  m = message("far.csv", "x1,y1,z1,x2,y2,z2,x3,y3,z3,wear\n1,0,0,0,1,0,1,0,5e3,1\n");
  CHECK(m.find("far.csv:2") != std::string::npos);
}

// Wear is relative, but not any number: a scale whose squares overflow or underflow, or one face a
// trillion times the rest, would turn into a liner reported new or a false alarm downstream.
TEST(WearMap, WearBeyondAUsableScaleOrOneCorruptFaceIsRefused) {
  lw::test::TempDirectory dir;
  WearMap m = Cone(24, 10);
  const Eigen::VectorXd good = m.wear;
  auto error_with = [&](const Eigen::VectorXd& wear) {
    m.wear = wear;
    WriteWearMapVtk(dir.path() / "m.vtk", m, {{"wear", &m.wear}});
    try {
      LoadWearMap(dir.path() / "m.vtk");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  std::string e = error_with(Eigen::VectorXd::Constant(good.size(), 1e308));
  CHECK_TEXT(e.find("m.vtk: 'wear' values reach 1e+308, outside 1e-100..1e+100") != std::string::npos, e.c_str());
  e = error_with(Eigen::VectorXd::Constant(good.size(), 1e-310));  // denormal: above zero, squares vanish
  CHECK_TEXT(e.find("'wear' values reach 1e-310") != std::string::npos, e.c_str());
  Eigen::VectorXd one = good;
  one[7] = 1e308;
  e = error_with(one);
  CHECK_TEXT(e.find("outside") != std::string::npos, e.c_str());
  one[7] = 1e30;
  e = error_with(one);
  CHECK_TEXT(e.find("face 7's 'wear' 1e+30 is more than 1e+12 times the median") != std::string::npos, e.c_str());
  // Any unit in range loads, and a strong hot spot (a thousand times the median) is a hot spot.
  STRCMP_EQUAL("", error_with(good * 1e-40).c_str());
  STRCMP_EQUAL("", error_with(good * 1e40).c_str());
  one = good;
  one[7] = 1000 * good.maxCoeff();
  STRCMP_EQUAL("", error_with(one).c_str());
}

TEST(WearMap, WearStderrAndTheTitlesWindowCountAreRead) {
  const lw::test::TempDirectory dir;
  std::ofstream(dir.path() / "m.vtk") << "# vtk DataFile Version 4.2\nlinerwatch dem c1 windows=5 window_s=1.4\nASCII\n"
                                         "DATASET POLYDATA\nPOINTS 3 double\n0 1 0\n1 1 0\n0 1 1\nPOLYGONS 1 4\n3 0 1 2\n"
                                         "CELL_DATA 1\nSCALARS wear double 1\nLOOKUP_TABLE default\n2.5\n"
                                         "SCALARS wear_stderr double 1\nLOOKUP_TABLE default\n0.7\n";
  const WearMap m = LoadWearMap(dir.path() / "m.vtk");
  LONGS_EQUAL(5, m.windows);
  CHECK(m.has_wear_stderr());
  DOUBLES_EQUAL(0.7, m.wear_stderr[0], 1e-12);
  CHECK(m.extra.count("wear_stderr") == 0);
}
