// linerwatch-sim: host-side simulator. Subcommands: campaign (bundle generator), run (virtual site).
#include <cstdio>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "core/atomic_file.hpp"
#include "core/cmdline.hpp"
#include "run.hpp"
#include "sim/campaign.hpp"

namespace {

const char* kHelp = R"(linerwatch-sim: host-side simulator for linerwatch.

Usage: linerwatch-sim <command> [options]     (linerwatch-sim <command> --help for details)

Commands:
  campaign   generate a synthetic campaign bundle (docs/bundle.md) with a known truth
  run        virtual sensor boards (real firmware) and XBee network feeding a gateway through a pty
)";

using lw::core::NumberRange;
using lw::core::Option;

const lw::core::OptionTable& CampaignTable() {
  static const lw::core::OptionTable table{
      {
          Option::Text("out", "DIR", "bundle folder to create (must not exist or be empty)").Required(),
          Option::Text("truth", "FILE", "also write the truth (effects, faults, daily true thickness) as JSON"),
          Option::Unsigned("seed", "N", "random seed (default 1); the same seed gives the same bundle"),
          Option::Number("days", "N", NumberRange::Any(), "campaign length in days (default 95)"),
          Option::Text("preset", "NAME", "reference (default) or paper (Ou & Chen 2023: hardening + softer core)"),
          Option::Text("effect", "NAME[:k=v,..]",
                       "add a physical effect DEM leaves out (repeatable); names and\n"
                       "parameters in docs/sim.md, e.g. --effect feed_segregation:amplitude=0.2,theta_deg=60")
              .Repeatable(),
          Option::Text("fault", "S:KIND:DAY[:SIZE]", "sensor fault (repeatable): dropout, flicker, crack, stuck, dead")
              .Repeatable(),
          Option::Number("scan-day", "D", NumberRange::Any(), "day of the laser scan (default: last day); --no-scan to omit it"),
          Option::Switch("no-scan", "no laser scan"),
          Option::Switch("no-operations", "omit operations.csv"),
      },
      "",
      "",
      /*other_config_keys=*/true};
  return table;
}

std::string CampaignHelp() {
  return "linerwatch-sim campaign: write a synthetic campaign bundle.\n\n"
         "Usage: linerwatch-sim campaign " +
         CampaignTable().Synopsis(31, 100) + "\n\n" + CampaignTable().Help(25) +
         "A --config file may also hold any campaign key of docs/sim.md; \"effect\" and \"fault\" take lists.\n";
}

int Fail(const std::string& why) {
  std::fprintf(stderr, "linerwatch-sim: %s\n", why.c_str());
  return 2;
}

int Campaign(const std::vector<std::string>& args) {
  using namespace lw::sim;
  try {
    const lw::core::ParsedOptions p = lw::core::ParseOptions(CampaignTable(), args);
    if (p.help()) {
      std::cout << CampaignHelp();
      return 0;
    }
    nlohmann::json config = p.other_config();
    const std::string out = p.Text("out"), truth = p.Text("truth"), preset = p.Text("preset", "reference");
    const uint64_t seed = p.Integer<uint64_t>("seed", 1);
    if (p.Has("days")) config["days"] = p.Number("days", 0);
    if (p.Has("scan-day")) config["scan_day"] = p.Number("scan-day", 0);
    if (p.Switch("no-scan")) config["write_scan"] = false;
    if (p.Switch("no-operations")) config["write_operations"] = false;
    std::vector<EffectSpec> effects;
    std::vector<FaultSpec> faults;
    for (const std::string& e : p.Texts("effect")) effects.push_back(ParseEffect(e));
    for (const std::string& f : p.Texts("fault")) faults.push_back(ParseFault(f));
    CampaignSpec spec = CampaignSpec::FromJson(config);
    ApplyPreset(preset, &spec);
    spec.effects.insert(spec.effects.end(), effects.begin(), effects.end());
    spec.faults.insert(spec.faults.end(), faults.begin(), faults.end());
    if (config.contains("days") && !config.contains("reference_day")) spec.reference_day = std::max(spec.days, 1.0);
    const lw::sim::Campaign c = GenerateCampaign(spec, seed);
    c.WriteBundle(out);
    if (!truth.empty()) {
      try {
        lw::core::WriteFileAtomically(truth, c.TruthJson().dump(1) + "\n");
      } catch (const std::runtime_error& e) {
        return Fail(std::string("campaign: ") + e.what());
      }
    }
    std::fprintf(stderr, "linerwatch-sim: wrote %s (%zu readings, %zu faces, %zu sensors)\n", out.c_str(), c.readings().size(),
                 c.map().face_count(), c.crusher().sensors.size());
  } catch (const std::invalid_argument& e) {
    return Fail(std::string("campaign: ") + e.what());
  } catch (const std::exception& e) {
    return Fail(std::string("campaign: ") + e.what());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "--help" || args[0] == "-h") {
    std::cout << kHelp;
    return args.empty() ? 2 : 0;
  }
  const std::map<std::string, std::function<int(const std::vector<std::string>&)>> commands = {{"campaign", Campaign},
                                                                                               {"run", lw::sim::RunCommand}};
  auto it = commands.find(args[0]);
  if (it == commands.end()) return Fail("unknown command '" + args[0] + "' (see --help)");
  return it->second(std::vector<std::string>(args.begin() + 1, args.end()));
}
