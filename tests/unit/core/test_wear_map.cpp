#include <cmath>
#include <fstream>

#include "core/wear_map.hpp"
#include "unit/core/temp_dir.hpp"

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
}  // namespace

TEST_GROUP(WearMap) {};

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
  lw::test::ScratchDir dir;
  WearMap m = Cone(12, 5);
  const Eigen::VectorXd extra = m.wear * 2.0;
  WriteWearMapVtk(dir.path() / "m.vtk", m, {{"wear", &m.wear}, {"normal_stress_average", &m.normal_stress}, {"wear_mm", &extra}});
  CHECK_FALSE(std::filesystem::exists(dir.path() / "m.vtk.tmp"));
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
  lw::test::ScratchDir dir;
  const std::string head = "# vtk DataFile Version 4.2\nmap\nASCII\nDATASET POLYDATA\nPOINTS 4 float\n"
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

TEST(WearMap, CsvExportReads) {
  lw::test::ScratchDir dir;
  dir.Write("m.csv", "x1,y1,z1,x2,y2,z2,x3,y3,z3,wear,normal_stress_average\n"
                     "1,0,0,0,1,0,1,0,1,0.25,3\n0,1,0,0,1,1,1,0,1,0.75,4\n");
  const WearMap m = LoadWearMap(dir.path() / "m.csv");
  LONGS_EQUAL(2, m.face_count());
  DOUBLES_EQUAL(0.75, m.wear[1], 1e-12);
  DOUBLES_EQUAL(4.0, m.normal_stress[1], 1e-12);
}

TEST(WearMap, BadMapsNameFileLineAndRule) {
  lw::test::ScratchDir dir;
  auto message = [&](const std::string& name, const std::string& text) -> std::string {
    dir.Write(name, text);
    try {
      LoadWearMap(dir.path() / name);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  const std::string head = "# vtk DataFile Version 4.2\nmap\nASCII\nDATASET POLYDATA\nPOINTS 4 float\n1 0 0 0 1 0 1 0 1 0 1 1\n";
  std::string m = message("quad.vtk", head + "POLYGONS 1 5\n4 0 1 3 2\nCELL_DATA 1\nSCALARS wear float\nLOOKUP_TABLE default\n1\n");
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

TEST(WearMap, ValidationFlagsZeroAndTruncatedMaps) {
  lw::test::ScratchDir dir;
  WearMap m = Cone(12, 5);
  for (Eigen::Index i = 0; i < m.wear.size(); ++i) m.wear[i] = (i % 3 == 0) ? 0.0 : 0.000001 * static_cast<double>(i % 4 + 1);
  WriteWearMapVtk(dir.path() / "t.vtk", m, {{"wear", &m.wear}});
  MapValidation v;
  LoadWearMap(dir.path() / "t.vtk", &v);
  CHECK(v.zero_wear_fraction > 0.3);
  CHECK(v.looks_truncated);
  CHECK(v.warnings.size() >= 2);
}

TEST(WearMap, WearStderrAndTheTitlesWindowCountAreRead) {
  const lw::test::ScratchDir dir;
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
