#include <cmath>
#include <functional>
#include <cstdlib>
#include <unistd.h>
#include <filesystem>
#include <map>

#include "core/bundle.hpp"
#include "sim/campaign.hpp"
#include "support/temp_directory.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw;
using sim::CampaignSpec;
using sim::GenerateCampaign;

namespace {
CampaignSpec Small() {
  CampaignSpec s;
  s.n_theta = 36;
  s.n_z = 18;
  s.scan_points = 3000;
  return s;
}
std::map<std::string, std::vector<double>> BySensor(const sim::Campaign& c) {
  std::map<std::string, std::vector<double>> m;
  for (const auto& r : c.readings()) m[r.sensor_id].push_back(r.thickness_mm);
  return m;
}
size_t Index(const sim::Campaign& c, const std::string& id) {
  for (size_t i = 0; i < c.crusher().sensors.size(); ++i) {
    if (c.crusher().sensors[i].id == id) return i;
  }
  return 0;
}
}  // namespace

TEST_GROUP(SimCampaign){};

TEST(SimCampaign, SameSeedSameCampaignOtherSeedOtherMap) {
  const auto a = GenerateCampaign(Small(), 7), b = GenerateCampaign(Small(), 7), c = GenerateCampaign(Small(), 8);
  CHECK(a.map().wear.isApprox(b.map().wear));
  LONGS_EQUAL(a.readings().size(), b.readings().size());
  CHECK_FALSE(a.map().wear.isApprox(c.map().wear));
}

TEST(SimCampaign, ReadingsAreFloorsOfTheTruthAndNeverRiseWithoutFaults) {
  const auto c = GenerateCampaign(Small(), 3);
  const auto t0 = c.crusher().installed_at;
  for (const auto& r : c.readings()) {
    const double day = core::DaysBetween(t0, r.time);
    const double truth = c.TrueSensorThickness(Index(c, r.sensor_id), std::floor(day * 96.0 + 1e-6) / 96.0);
    DOUBLES_EQUAL(std::floor(truth), r.thickness_mm, 1e-9);
  }
  for (const auto& [id, v] : BySensor(c)) {
    for (size_t i = 1; i < v.size(); ++i) CHECK(v[i] <= v[i - 1]);
  }
}

TEST(SimCampaign, ReferenceCampaignMatchesThePapersRowRatios) {
  const auto c = GenerateCampaign(Small(), 1);
  std::map<std::string, std::pair<double, int>> rows;
  for (size_t i = 0; i < c.crusher().sensors.size(); ++i) {
    auto& r = rows[c.crusher().sensors[i].row];
    r.first += 120.0 - c.TrueSensorThickness(i, 95);
    ++r.second;
  }
  const double ldwn = rows["LDWN"].first / rows["LDWN"].second, lmid = rows["LMID"].first / rows["LMID"].second,
               lup = rows["LUP"].first / rows["LUP"].second;
  DOUBLES_EQUAL(85.0, ldwn, 0.5);
  DOUBLES_EQUAL(6.0, ldwn / lup, 1.0);
  DOUBLES_EQUAL(2.0, ldwn / lmid, 0.35);
}

TEST(SimCampaign, EachEffectMovesTheTruthTheDocumentedWay) {
  const auto base = GenerateCampaign(Small(), 5);
  auto with = [](const std::string& effect) {
    CampaignSpec s = Small();
    s.effects.push_back(sim::ParseEffect(effect));
    return GenerateCampaign(s, 5);
  };
  const size_t ldwn = Index(base, "1007");  // LDWN at 45 deg
  // Hardening: less wear where normal stress is high; saturating, so early wear is hit hardest.
  const auto hard = with("work_hardening:h=0.4,tau_days=6");
  CHECK(hard.TrueSensorThickness(ldwn, 95) > base.TrueSensorThickness(ldwn, 95) + 3);
  // Softer core: wear accelerates once the worn depth passes the onset.
  const auto grad = with("hardness_gradient:c=0.3,onset_mm=20,width_mm=20");
  CHECK(grad.TrueSensorThickness(ldwn, 95) < base.TrueSensorThickness(ldwn, 95) - 5);
  DOUBLES_EQUAL(base.TrueSensorThickness(ldwn, 10), grad.TrueSensorThickness(ldwn, 10), 1e-9);
  // Feed segregation: the feed side (theta_f) wears more than the far side.
  const auto feed = with("feed_segregation:amplitude=0.2,theta_deg=45");
  CHECK(120 - feed.TrueSensorThickness(ldwn, 95) > 1.3 * (120 - feed.TrueSensorThickness(Index(base, "1009"), 95)));
  // Squeeze adds wear; material loss steps one place down at once.
  CHECK(with("squeeze_wear:beta=0.3").TrueSensorThickness(ldwn, 95) < base.TrueSensorThickness(ldwn, 95) - 2);
  const auto loss = with("material_loss:depth_mm=10,day=40,sensor_index=6");
  CHECK(loss.TrueSensorThickness(6, 39.9) - loss.TrueSensorThickness(6, 40.1) > 9.5);
  // Throughput variation: operations.csv varies and wear stops during stops.
  const auto tp = with("throughput_variation:amplitude=0.5");
  double lo = 1e9, hi = 0;
  for (const auto& o : tp.operations()) {
    lo = std::min(lo, o.throughput_tph);
    hi = std::max(hi, o.throughput_tph);
  }
  DOUBLES_EQUAL(0.0, lo, 1e-9);
  CHECK(hi > 4000);
}

TEST(SimCampaign, FaultsShowInTheReadings) {
  CampaignSpec s = Small();
  s.faults = {{"1005", "stuck", 30, 0}, {"1008", "crack", 20, 4}, {"1003", "dropout", 10, 5}};
  const auto c = GenerateCampaign(s, 2);
  const auto t0 = c.crusher().installed_at;
  double last_stuck = -1;
  bool gap = true;
  for (const auto& r : c.readings()) {
    const double day = core::DaysBetween(t0, r.time);
    if (r.sensor_id == "1005" && day > 31) {
      if (last_stuck >= 0) DOUBLES_EQUAL(last_stuck, r.thickness_mm, 1e-9);
      last_stuck = r.thickness_mm;
    }
    if (r.sensor_id == "1003" && day > 10.1 && day < 14.9) gap = false;
  }
  CHECK(gap);
  CHECK(last_stuck > 0);
}

// A flicker from day 0 (found by fuzz_sim_campaign): the unworn ladder cannot read a loop above
// its top, so no reading is thicker than a new liner.
TEST(SimCampaign, AFlickerOnANewLinerNeverReadsAboveItsTop) {
  CampaignSpec s = Small();
  s.days = 10;
  s.poll_minutes = 67;
  s.faults = {{"1001", "flicker", 0, 2}};
  const auto c = GenerateCampaign(s, 1);
  size_t flicker_readings = 0;
  for (const auto& r : c.readings()) {
    CHECK(r.thickness_mm <= s.thickness_new_mm);
    if (r.sensor_id == "1001") ++flicker_readings;
  }
  CHECK(flicker_readings > 0);
}

TEST(SimCampaign, BundleReadsBackAndIsWrittenAtomically) {
  const lw::test::TempDirectory tmp("lw-sim");
  const auto dir = tmp.path() / "bundle";
  const auto c = GenerateCampaign(Small(), 4);
  c.WriteBundle(dir);
  const core::Bundle b = core::LoadBundle(dir);
  LONGS_EQUAL(c.readings().size(), b.readings.size());
  LONGS_EQUAL(c.map().face_count(), b.map.face_count());
  CHECK(b.map.has_normal_stress());
  LONGS_EQUAL(1, b.scans.size());
  CHECK(b.scans[0].points.size() > 2000);
  CHECK(!b.operations.empty());
  CHECK_THROWS(std::runtime_error, c.WriteBundle(dir));  // never overwrites a bundle
}

TEST(SimCampaign, BadSpecsAreRefusedNamingTheField) {
  CampaignSpec s = Small();
  s.effects.push_back({"warp_drive", {}});
  try {
    GenerateCampaign(s, 1);
    FAIL("expected invalid_argument");
  } catch (const std::invalid_argument& e) {
    CHECK(std::string(e.what()).find("warp_drive") != std::string::npos);
  }
  CHECK_THROWS(std::invalid_argument, sim::ParseFault("1001:stuck"));
  CHECK_THROWS(std::invalid_argument, sim::ParseEffect("feed_segregation:amplitude=x"));
  // Numbers are whole and finite: trailing text, nan and inf are refused, not read as a prefix.
  CHECK_THROWS(std::invalid_argument, sim::ParseEffect("feed_segregation:amplitude=0.3x"));
  CHECK_THROWS(std::invalid_argument, sim::ParseEffect("feed_segregation:amplitude=nan"));
  CHECK_THROWS(std::invalid_argument, sim::ParseFault("1001:stuck:40days"));
  CHECK_THROWS(std::invalid_argument, sim::ParseFault("1001:stuck:40:inf"));
  DOUBLES_EQUAL(0.3, sim::ParseEffect("feed_segregation:amplitude=0.3").params.at("amplitude"), 0);
  CHECK_THROWS(std::invalid_argument, sim::CampaignSpec::FromJson(nlohmann::json{{"dayz", 3}}));
}

namespace {
/// The message of the refusal `Complete()` gives for `s`, or "" when it accepts it.
std::string Refusal(CampaignSpec s) {
  try {
    s.Complete();
    return "";
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
}
bool Mentions(const std::string& text, const char* what) {
  return text.find(what) != std::string::npos;
}
}  // namespace

// Found by fuzz/sim_campaign: parameters that turn the wear rate negative (a liner that grows
// thicker), index past the sensors (out-of-bounds read), or overflow int were accepted.
TEST(SimCampaign, EffectParametersOutsideTheirPhysicalRangeAreRefused) {
  CampaignSpec s = Small();
  s.effects = {{"work_hardening", {{"h", 5.4}}}};
  CHECK_TEXT(Mentions(Refusal(s), "work_hardening': h = 5.4 is outside [0, 1)"), Refusal(s).c_str());
  s.effects = {{"work_hardening", {{"h", 0.99}}}};
  CHECK_EQUAL("", Refusal(s));
  s.effects = {{"feed_segregation", {{"amplitude", 1.0}}}};
  CHECK(Mentions(Refusal(s), "amplitude = 1 is outside [0, 1)"));
  s.effects = {{"material_loss", {{"sensor_index", -1}}}};
  CHECK(Mentions(Refusal(s), "sensor_index = -1"));
  s.effects = {{"material_loss", {{"sensor_index", 1.5}}}};
  CHECK(Mentions(Refusal(s), "not a whole number"));
  s.effects = {{"squeeze_wear", {{"betta", 0.2}}}};
  CHECK_TEXT(Mentions(Refusal(s), "has no parameter 'betta' (it has beta)"), Refusal(s).c_str());
}

TEST(SimCampaign, SpecFieldsOutsideTheirRangeAreRefusedNamingTheField) {
  const std::vector<std::pair<std::function<void(CampaignSpec&)>, const char*>> cases = {
      {[](CampaignSpec& s) { s.n_theta = 2000000000, s.n_z = 2000000000; }, "n_theta * n_z"},
      {[](CampaignSpec& s) { s.poll_minutes = 1e-6; }, "poll_minutes"},
      {[](CampaignSpec& s) { s.reference_day = 0; }, "reference_day"},
      {[](CampaignSpec& s) { s.throughput_tph = -1; }, "throughput_tph"},
      {[](CampaignSpec& s) { s.ore_ai = -0.3; }, "ore_ai"},
      {[](CampaignSpec& s) { s.scan_noise_mm = -1; }, "scan_noise_mm"},
      {[](CampaignSpec& s) { s.scan_points = -5; }, "scan_points"},
      {[](CampaignSpec& s) { s.scan_occluded_deg = 400; }, "scan_occluded_deg"},
      {[](CampaignSpec& s) { s.scan_day = s.days + 1; }, "scan_day"},
      {[](CampaignSpec& s) {
         s.rows = {{"A", 1.0, 0.5}};
       },
       "row 'A' needs z_min_m < z_max_m"},
      {[](CampaignSpec& s) {
         s.sensors = {{"x", "NOPE", 0.5, 0}};
       },
       "unknown row 'NOPE'"},
      {[](CampaignSpec& s) {
         s.days = 2000, s.poll_minutes = 1, s.sensors.clear();
         s.Complete();  // the 10 default sensors
         const std::vector<sim::SensorSpec> ten = s.sensors;
         s.sensors.insert(s.sensors.end(), ten.begin(), ten.end());  // 20
         for (size_t i = 0; i < s.sensors.size(); ++i) s.sensors[i].id = std::to_string(i);
       },
       "50,000,000 readings"},
  };
  for (const auto& [change, what] : cases) {
    CampaignSpec s = Small();
    change(s);
    const std::string r = Refusal(s);
    CHECK_TEXT(Mentions(r, what), (std::string(what) + " -> '" + r + "'").c_str());
  }
  CHECK_EQUAL("", Refusal(Small()));
  // Counts in the JSON must be whole numbers that fit (2.4e98 was converted to int unchecked).
  for (const char* bad : {R"({"n_theta": 2.4e98})", R"({"n_z": 12.5})", R"({"scan_points": "many"})"}) {
    try {
      (void)CampaignSpec::FromJson(nlohmann::json::parse(bad));
      FAIL(bad);
    } catch (const std::invalid_argument& e) {
      CHECK_TEXT(Mentions(e.what(), "whole number"), e.what());
    }
  }
  LONGS_EQUAL(40, CampaignSpec::FromJson(nlohmann::json::parse(R"({"n_theta": 40.0})")).n_theta);
}
