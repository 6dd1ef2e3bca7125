// The steps of AnalyseSensor() (diagnosis/src/sensor_steps.hpp) on hand-made reading series: each
// step's typed result, and the whole analysis on a series with a material loss.
#include <cmath>
#include <string>
#include <vector>

#include "sensor_steps.hpp"

// CppUTest last: its leak-detector macros redefine new.
#include <CppUTest/TestHarness.h>

namespace {

using lw::diagnosis::detail::RawReading;

// A sensor wearing `rate` mm/day from 100 mm, read every `period` days (floored to the ladder).
std::vector<RawReading> Wearing(double days, double period, double rate) {
  std::vector<RawReading> r;
  for (double t = 0; t <= days + 1e-9; t += period) r.push_back({t, std::floor(100.0 - rate * t)});
  return r;
}

size_t Count(const std::vector<lw::diagnosis::detail::QualityIssue>& issues, const std::string& kind) {
  size_t n = 0;
  for (const auto& q : issues)
    if (q.issue == kind) ++n;
  return n;
}

}  // namespace

TEST_GROUP(SensorSteps){};

TEST(SensorSteps, SortReadingsOrdersByTimeAndDropsExactDuplicates) {
  const auto r = lw::diagnosis::detail::SortReadings({{2, 98}, {1, 99}, {2, 98}, {2, 97}, {0, 100}});
  LONGS_EQUAL(4, r.size());
  DOUBLES_EQUAL(0, r[0].t_days, 0);
  DOUBLES_EQUAL(1, r[1].t_days, 0);
  DOUBLES_EQUAL(98, r[2].value_mm, 0);  // stable: the first of equal times stays first
  DOUBLES_EQUAL(97, r[3].value_mm, 0);
}

TEST(SensorSteps, DropoutIsReportedButNothingExcluded) {
  std::vector<RawReading> r = Wearing(10, 0.25, 0.5);
  std::vector<RawReading> gap;
  for (const auto& x : r)
    if (x.t_days < 3 || x.t_days > 6) gap.push_back(x);
  const auto f = lw::diagnosis::detail::DetectFaults(gap, 100);
  LONGS_EQUAL(1, Count(f.issues, "dropout"));
  DOUBLES_EQUAL(2.75, f.issues[0].from_days, 1e-9);
  DOUBLES_EQUAL(6.25, f.issues[0].to_days, 1e-9);
  for (bool u : f.used) CHECK_TRUE(u);
}

TEST(SensorSteps, NonPhysicalZeroDeadAndSpikeAreExcluded) {
  std::vector<RawReading> r = Wearing(20, 0.5, 1.0);  // 41 readings, 100 .. 80
  r[5].value_mm = -3;                                 // non-physical
  r[10].value_mm = 0;                                 // zero while far from worn out, valid readings follow
  r[20].value_mm = 60;                                // a spike: both neighbours agree, it is far from both
  r[39].value_mm = 0;                                 // zero to the end: dead
  r[40].value_mm = 0;
  const auto f = lw::diagnosis::detail::DetectFaults(r, 100);
  LONGS_EQUAL(1, Count(f.issues, "non_physical"));
  LONGS_EQUAL(1, Count(f.issues, "zero"));
  LONGS_EQUAL(1, Count(f.issues, "dead"));
  LONGS_EQUAL(1, Count(f.issues, "spike"));
  for (size_t i : {5, 10, 20, 39, 40}) CHECK_FALSE(f.used[i]);
  size_t used = 0;
  for (bool u : f.used) used += u ? 1 : 0;
  LONGS_EQUAL(36, used);
}

TEST(SensorSteps, EnvelopeKeepsFlickerAndExcludesThicknessGoingUp) {
  std::vector<RawReading> r = Wearing(20, 0.5, 1.0);
  r[10].value_mm += 1;                                  // one reading one loop above: flicker, kept at the envelope
  for (size_t i = 30; i < 36; ++i) r[i].value_mm += 5;  // three days 5 mm thicker: a fault
  std::vector<bool> used(r.size(), true);
  const auto e = lw::diagnosis::detail::MonotoneEnvelope(r, used);
  LONGS_EQUAL(1, Count(e.issues, "flicker"));
  LONGS_EQUAL(1, Count(e.issues, "thickness_up"));
  CHECK_TRUE(used[10]);
  DOUBLES_EQUAL(r[9].value_mm, e.level[10], 0);
  for (size_t i = 30; i < 36; ++i) CHECK_FALSE(used[i]);
  for (size_t i = 1; i < r.size(); ++i)
    if (used[i] && used[i - 1]) CHECK_TRUE(e.level[i] <= e.level[i - 1]);
}

TEST(SensorSteps, SegmentsAndRobustRate) {
  const std::vector<RawReading> r = Wearing(40, 0.25, 0.5);
  std::vector<bool> used(r.size(), true);
  const auto e = lw::diagnosis::detail::MonotoneEnvelope(r, used);
  const auto segments = lw::diagnosis::detail::LevelSegments(r, used, e.level);
  LONGS_EQUAL(21, segments.size());  // 100 .. 80
  DOUBLES_EQUAL(100, segments.front().level, 0);
  DOUBLES_EQUAL(80, segments.back().level, 0);
  LONGS_EQUAL(8, segments[1].count);  // 2 days per mm, 4 readings per day
  DOUBLES_EQUAL(0.5, lw::diagnosis::detail::RobustRate(r, segments, 100), 0.03);
}

TEST(SensorSteps, BriefLevelsOfASpreadStepAreFolded) {
  using lw::diagnosis::detail::Segment;
  // 90 for 10 days, 89 and 88 for one poll each, then 84 onwards: one 6 mm step.
  const std::vector<Segment> s = {
      {90, 0, 10, 40, {}}, {89, 10.01, 10.01, 1, {}}, {88, 10.02, 10.02, 1, {}}, {84, 10.03, 20, 40, {}}};
  const auto folded = lw::diagnosis::detail::FoldBriefLevels(s, 0.1);
  LONGS_EQUAL(2, folded.size());
  DOUBLES_EQUAL(90, folded[0].level, 0);
  DOUBLES_EQUAL(84, folded[1].level, 0);
  // At a rate that explains the levels, nothing is folded.
  LONGS_EQUAL(4, lw::diagnosis::detail::FoldBriefLevels(s, 500).size());
}

TEST(SensorSteps, MaterialLossIsAStepWithWearContinuingAfterIt) {
  std::vector<RawReading> r = Wearing(40, 0.25, 0.5);
  for (auto& x : r)
    if (x.t_days >= 20) x.value_mm = std::floor(100.0 - 0.5 * x.t_days - 8.0);
  const auto a = lw::diagnosis::detail::AnalyseSensor(r, 100);
  LONGS_EQUAL(1, a.losses.size());
  DOUBLES_EQUAL(20, a.losses[0].t_days, 0.2);
  DOUBLES_EQUAL(8, a.losses[0].depth_mm, 1.0);
  CHECK_TRUE(a.issues.empty());
  // Events after the loss carry the lost material as offset: wear - offset follows the rate.
  for (const auto& e : a.events) {
    if (e.t_days > 21) {
      DOUBLES_EQUAL(a.losses[0].depth_mm, e.offset_mm, 1e-9);
      DOUBLES_EQUAL(0.5 * e.t_days, e.wear_mm - e.offset_mm, 1.5);
    } else {
      DOUBLES_EQUAL(0, e.offset_mm, 0);
    }
  }
}

TEST(SensorSteps, CrackAndStuckAreFaultsNotLoss) {
  using lw::diagnosis::detail::Segment;
  using lw::diagnosis::detail::Transition;
  // Crack: a premature 5 mm step after wearing normally, then flat for 10 days until the wear
  // (0.5 mm/day) catches up.
  const std::vector<Segment> crack = {{95, 8, 10, 8, {}}, {90, 10.1, 20, 40, {}}, {89, 22, 24, 8, {}}};
  std::vector<bool> used(200, true);
  const auto c = lw::diagnosis::detail::ClassifySteps(crack, 0.5, used);
  LONGS_EQUAL(1, Count(c.issues, "crack"));
  CHECK_TRUE(c.transition[0] == Transition::kDropped);
  CHECK_TRUE(c.classified[1]);
  CHECK_TRUE(c.losses.empty());
  // Stuck: flat for 10 days at 0.5 mm/day, then a 6 mm jump.
  const std::vector<Segment> stuck = {{95, 0, 10, 40, {}}, {89, 10.1, 11, 4, {}}, {88, 12, 14, 8, {}}};
  const auto s = lw::diagnosis::detail::ClassifySteps(stuck, 0.5, used);
  LONGS_EQUAL(1, Count(s.issues, "stuck"));
  CHECK_TRUE(s.classified[0]);
  CHECK_TRUE(s.losses.empty());
}

TEST(SensorSteps, CrossingEventsOnePerLoopSpreadOverTheGap) {
  using lw::diagnosis::detail::Segment;
  using lw::diagnosis::detail::StepAnalysis;
  using lw::diagnosis::detail::Transition;
  // 100 -> 97 between day 1 and day 4: loops 100, 99, 98 crossed (wear 0 is skipped) ... and 97 -> 96.
  const std::vector<Segment> s = {{97, 4, 5, 4, {}}, {96, 6, 7, 4, {}}};
  StepAnalysis steps;
  steps.transition.assign(2, Transition::kNormal);
  steps.loss_depth.assign(2, 0.0);
  steps.classified.assign(2, false);
  const auto ev = lw::diagnosis::detail::CrossingEvents(s, steps, 100, 100);
  LONGS_EQUAL(3, ev.size());  // from the top: 99 and 98 (100 is wear 0); then 97 -> 96
  DOUBLES_EQUAL(1, ev[0].wear_mm, 0);
  DOUBLES_EQUAL(2, ev[1].wear_mm, 0);
  DOUBLES_EQUAL(3, ev[2].wear_mm, 0);
  DOUBLES_EQUAL(5.5, ev[2].t_days, 1e-12);
  CHECK_TRUE(ev[0].t_days < ev[1].t_days);
  // A loss transition adds its depth as offset to the events after it, and has no events itself.
  steps.transition[0] = Transition::kLoss;
  steps.loss_depth[0] = 4;
  const auto lost = lw::diagnosis::detail::CrossingEvents(s, steps, 100, 100);
  LONGS_EQUAL(2, lost.size());
}
