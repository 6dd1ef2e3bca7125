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

const char* kCampaignHelp = R"(linerwatch-sim campaign: write a synthetic campaign bundle.

Usage: linerwatch-sim campaign --out DIR [options]

  --out DIR              bundle folder to create (must not exist or be empty)
  --truth FILE           also write the truth (effects, faults, daily true thickness) as JSON
  --seed N               random seed (default 1); the same seed gives the same bundle
  --days N               campaign length in days (default 95)
  --preset NAME          reference (default) or paper (Ou & Chen 2023: hardening + softer core)
  --effect NAME[:k=v,..] add a physical effect DEM leaves out (repeatable); names and
                         parameters in docs/sim.md, e.g. --effect feed_segregation:amplitude=0.2,theta_deg=60
  --fault S:KIND:DAY[:SIZE]  sensor fault (repeatable): dropout, flicker, crack, stuck, dead
  --scan-day D           day of the laser scan (default: last day); --no-scan to omit it
  --no-operations        omit operations.csv
  --config FILE          JSON with any campaign key (docs/sim.md) and the options above
  --help                 this text
)";

int Fail(const std::string& why) {
  std::fprintf(stderr, "linerwatch-sim: %s\n", why.c_str());
  return 2;
}

int Campaign(const std::vector<std::string>& args) {
  using namespace lw::sim;
  nlohmann::json config = nlohmann::json::object();
  std::string out, truth, preset = "reference";
  uint64_t seed = 1;
  std::vector<EffectSpec> effects;
  std::vector<FaultSpec> faults;
  std::map<std::string, std::string> flags;
  try {
    for (size_t i = 0; i < args.size(); ++i) {
      const std::string& a = args[i];
      if (a == "--help" || a == "-h") {
        std::cout << kCampaignHelp;
        return 0;
      }
      if (a == "--no-scan") {
        config["write_scan"] = false;
        continue;
      }
      if (a == "--no-operations") {
        config["write_operations"] = false;
        continue;
      }
      if (a.rfind("--", 0) != 0) return Fail("campaign: unexpected argument '" + a + "'");
      if (i + 1 >= args.size()) return Fail("campaign: " + a + " needs a value");
      const std::string v = args[++i];
      if (a == "--config") {
        std::ifstream in(v);
        if (!in) return Fail("campaign: --config: cannot read '" + v + "'");
        nlohmann::json j;
        try {
          j = nlohmann::json::parse(in);
        } catch (const std::exception& e) {
          return Fail("campaign: --config '" + v + "' is not valid JSON: " + e.what());
        }
        for (const auto& [k, val] : j.items()) {
          if (k == "out") out = val.get<std::string>();
          else if (k == "truth") truth = val.get<std::string>();
          else if (k == "seed") seed = lw::core::ParseInteger<uint64_t>("seed", val.is_number() ? val.dump() : val.get<std::string>());
          else if (k == "preset") preset = val.get<std::string>();
          else if (k == "effect") for (const auto& e : val) effects.push_back(ParseEffect(e.get<std::string>()));
          else if (k == "fault") for (const auto& f : val) faults.push_back(ParseFault(f.get<std::string>()));
          else config[k] = val;
        }
      } else if (a == "--out") out = v;
      else if (a == "--truth") truth = v;
      else if (a == "--seed") seed = lw::core::ParseInteger<uint64_t>("seed", v);
      else if (a == "--days") config["days"] = lw::core::ParseNumber("days", v);
      else if (a == "--preset") preset = v;
      else if (a == "--effect") effects.push_back(ParseEffect(v));
      else if (a == "--fault") faults.push_back(ParseFault(v));
      else if (a == "--scan-day") config["scan_day"] = lw::core::ParseNumber("scan-day", v);
      else return Fail("campaign: unknown option " + a + " (see --help)");
    }
    if (out.empty()) return Fail("campaign: --out DIR is required");
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
  const std::map<std::string, std::function<int(const std::vector<std::string>&)>> commands = {{"campaign", Campaign}, {"run", lw::sim::RunCommand}};
  auto it = commands.find(args[0]);
  if (it == commands.end()) return Fail("unknown command '" + args[0] + "' (see --help)");
  return it->second(std::vector<std::string>(args.begin() + 1, args.end()));
}
