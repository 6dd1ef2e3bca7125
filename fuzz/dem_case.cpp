// The LIGGGHTS import of `linerwatch dem --stage map` (dem::BuildMap): a finished case folder of a
// real LIGGGHTS-PUBLIC 3.8 run (tests/data/dem/tiny_case: the tiny chamber of tests/data/dem, its mass
// series, attempts, log and the last seven concave mesh dumps) with one file replaced by the input.
// The input's first byte picks the file: the mass series, attempts.txt, the log, one of the seven
// dumps, or an extra dump at a step of its own; the rest is that file's bytes.
// Properties: a bad case is refused with std::runtime_error (core::InputError for a dump) naming
// what was wrong, nothing else is thrown, nothing crashes (ASan, UBSan); a map that is built is
// finite, has non-negative standard errors and loads back with its windows.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/wear_map.hpp"
#include "dem/case_writer.hpp"
#include "dem/chamber.hpp"
#include "dem/map_builder.hpp"
#include "fuzz_support.hpp"

using namespace lw;
using lw::fuzz::Check;
namespace fs = std::filesystem;

namespace {

const fs::path kCase = LW_DEM_CASE_DIR;
const std::vector<long> kDumpSteps = {9600, 10000, 10400, 10800, 11200, 11600, 12000};

const dem::ChamberSpec& Spec() {
  static const dem::ChamberSpec spec = [] {
    std::ifstream in(kCase / "crusher.json");
    return dem::ChamberFromCrusherJson(nlohmann::json::parse(in), (kCase / "crusher.json").string());
  }();
  return spec;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const dem::ChamberSpec& spec = Spec();
  const fs::path dir = fuzz::ScratchDir() / "case", out = fuzz::ScratchDir() / "map";
  std::error_code ec;
  fs::remove_all(dir, ec);
  fs::remove_all(out, ec);
  fs::copy(kCase, dir, fs::copy_options::recursive, ec);
  if (ec) fuzz::Fail("cannot copy " + kCase.string() + ": " + ec.message());

  const std::string_view bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  const unsigned pick = data[0] % 11;
  fs::path file;
  if (pick == 0)
    file = dir / dem::CaseLayout::kMassSeries;
  else if (pick == 1)
    file = dir / "attempts.txt";
  else if (pick == 2)
    file = dir / "log.1.liggghts";
  else if (pick < 10)
    file = dir / dem::CaseLayout::kDumpDir / ("concave_" + std::to_string(kDumpSteps[pick - 3]) + ".vtk");
  else
    file = dir / dem::CaseLayout::kDumpDir / ("concave_" + std::to_string(9600 + 200 * (data[0] / 11)) + ".vtk");
  if (!fuzz::WriteFile(file, bytes)) fuzz::Fail("cannot write " + file.string());

  try {
    (void)dem::BuildMap(spec, dir, {}, out);
  } catch (const std::runtime_error& e) {
    Check(*e.what() != '\0', "BuildMap refused a case without a message");
    return 0;
  } catch (const std::exception& e) {
    fuzz::Fail(std::string("BuildMap threw something other than std::runtime_error: ") + e.what());
  }
  const core::WearMap map = core::LoadWearMap(out / dem::MapFiles::kMap);
  Check(map.wear.allFinite(), "the built map's wear is not finite");
  Check(map.has_wear_stderr() && map.wear_stderr.allFinite() && map.wear_stderr.minCoeff() >= 0,
        "the built map's standard errors are not finite and non-negative");
  const core::WearMap windows = core::LoadWearMap(out / dem::MapFiles::kWindows);
  Check(windows.face_count() == map.face_count(), "the windows file has another mesh than the map");
  return 0;
}
