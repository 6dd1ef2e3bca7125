// linerwatch-sim campaign configurations: the JSON of `linerwatch-sim campaign --config FILE`
// (sim::CampaignSpec::FromJson, then the checks of Complete()), its --effect and --fault texts
// (ParseEffect, ParseFault) and, for a spec small enough to make quickly, the campaign itself.
// Properties: a bad configuration is refused with std::invalid_argument and a message, nothing else
// is thrown and nothing crashes (ASan, UBSan); a spec that is accepted generates a campaign whose
// readings and truth are finite and whose thickness never exceeds the new liner's.
#include <cmath>
#include <nlohmann/json.hpp>
#include <string>

#include "fuzz_support.hpp"
#include "sim/campaign.hpp"

using namespace lw;
using lw::fuzz::Check;

namespace {

// The harness's own bound on the work of one input (the generator's limits are far larger: a
// campaign of 2,000 days is valid, it just takes longer than a fuzzer's input should).
bool QuickToGenerate(const sim::CampaignSpec& s) {
  return s.days <= 12 && static_cast<double>(s.n_theta) * s.n_z <= 1500 && s.poll_minutes >= 30 && s.heartbeat_hours >= 1 &&
         s.scan_points <= 2000 && s.sensors.size() <= 16 && s.faults.size() <= 16 && s.effects.size() <= 8;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const nlohmann::json j = nlohmann::json::parse(data, data + size, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) return 0;
  sim::CampaignSpec spec;
  try {
    if (!j.is_object()) throw std::invalid_argument("not an object");
    spec = sim::CampaignSpec::FromJson(j);
    // The CLI's repeatable --effect/--fault texts, when the config lists them as strings.
    for (const char* key : {"effect", "fault"}) {
      if (!j.contains(key) || !j[key].is_array()) continue;
      for (const auto& t : j[key]) {
        if (!t.is_string()) continue;
        if (key[0] == 'e')
          spec.effects.push_back(sim::ParseEffect(t.get<std::string>()));
        else
          spec.faults.push_back(sim::ParseFault(t.get<std::string>()));
      }
    }
    if (j.contains("preset") && j["preset"].is_string()) sim::ApplyPreset(j["preset"].get<std::string>(), &spec);
    spec.Complete();
  } catch (const std::invalid_argument& e) {
    Check(*e.what() != '\0', "campaign refusal without a message");
    return 0;
  }
  if (!QuickToGenerate(spec)) return 0;
  try {
    const sim::Campaign c = sim::GenerateCampaign(spec, 1);
    for (const core::Reading& r : c.readings()) {
      Check(std::isfinite(r.thickness_mm), "a generated reading is not finite");
      Check(r.thickness_mm <= spec.thickness_new_mm + 1e-9, "a generated reading is thicker than a new liner");
    }
    const Eigen::VectorXd w = c.TrueFaceWear(spec.days);
    Check(w.allFinite(), "the true face wear is not finite");
    for (size_t i = 0; i < c.crusher().sensors.size(); ++i)
      Check(std::isfinite(c.TrueSensorThickness(i, spec.days)), "a true sensor thickness is not finite");
  } catch (const std::invalid_argument& e) {
    Check(*e.what() != '\0', "campaign refusal without a message");
  }
  return 0;
}
