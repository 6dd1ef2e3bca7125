// dem/until.hpp: when `linerwatch dem --until-band` stops, and how far its next step goes.
#include "dem/until.hpp"

#include <cmath>
#include <limits>
#include <vector>

#include <CppUTest/TestHarness.h>

using lw::dem::BandAfter;
using lw::dem::PlanUntilStep;
using lw::dem::UntilBudget;
using Verdict = lw::dem::UntilStep::Verdict;

TEST_GROUP(Until){};

TEST(Until, DoneWhenTheLastBandIsWithinTheTarget) {
  const auto s = PlanUntilStep({{10, 8, 6.0}, {20, 18, 4.0}}, 4.0, UntilBudget{});
  CHECK(s.verdict == Verdict::kDone);
  DOUBLES_EQUAL(20, s.next_simulated_s, 1e-12);
}

TEST(Until, OneStepProjectsWithTheInverseSquareRootLaw) {
  UntilBudget b;
  b.wall_per_simulated_s = 60;  // a minute per simulated second
  b.resume_from_s = 8;
  b.dump_interval_s = 0.5;
  // Band 10 mm after a 4 s steady span (run 6 s), target 5 mm: 4 x the span, 16 s steady.
  const auto s = PlanUntilStep({{6, 4, 10.0}}, 5.0, b);
  CHECK(s.verdict == Verdict::kStep);
  CHECK_FALSE(s.measured);
  DOUBLES_EQUAL(0.5, s.exponent, 1e-12);
  DOUBLES_EQUAL(16, s.needed_steady_s, 1e-9);
  DOUBLES_EQUAL(18, s.projected_simulated_s, 1e-9);
  DOUBLES_EQUAL(60 * (18 - 8), s.projected_wall_s, 1e-6);
  DOUBLES_EQUAL(12, s.next_simulated_s, 1e-9);  // at most twice the run so far
  DOUBLES_EQUAL(60 * (12 - 8), s.step_wall_s, 1e-6);
}

TEST(Until, TwoOrMoreStepsMeasureHowFastTheBandFalls) {
  // The band falls as steady^-0.25 here: a target at half the band needs 16 x the span.
  const double b1 = 8.0, b2 = 8.0 * std::pow(2.0, -0.25);
  const auto s = PlanUntilStep({{6, 4, b1}, {10, 8, b2}}, b1 / 2, UntilBudget{});
  CHECK(s.measured);
  DOUBLES_EQUAL(0.25, s.exponent, 1e-9);
  DOUBLES_EQUAL(64, s.needed_steady_s, 1e-6);  // 8 s x (b2 / (b1/2))^4 = 8 x 8
  DOUBLES_EQUAL(66, s.projected_simulated_s, 1e-6);
  CHECK(std::isnan(s.projected_wall_s));  // no rate measured yet
  DOUBLES_EQUAL(20, s.next_simulated_s, 1e-9);
  // A band that does not fall is projected at the slowest exponent allowed, not as never.
  const auto flat = PlanUntilStep({{6, 4, 8.0}, {10, 8, 8.0}}, 4.0, UntilBudget{});
  DOUBLES_EQUAL(0.05, flat.exponent, 1e-12);
  CHECK(std::isfinite(flat.projected_simulated_s));
}

TEST(Until, TheStepShrinksToTheBudgetAndStopsWhenNothingFits) {
  UntilBudget b;
  b.wall_per_simulated_s = 100;
  b.resume_from_s = 10;
  b.dump_interval_s = 0.5;
  b.min_step_s = 1;
  b.remaining_wall_s = 500;  // 4.5 s of simulated time with the tenth spare, from the restart at 10 s
  const auto s = PlanUntilStep({{12, 9, 10.0}}, 1.0, b);
  CHECK(s.verdict == Verdict::kStep);
  DOUBLES_EQUAL(14.5, s.next_simulated_s, 1e-9);
  CHECK(s.step_wall_s <= b.remaining_wall_s);
  b.remaining_wall_s = 250;  // 2.25 s from 10 s ends before 12 s + 1 s
  CHECK(PlanUntilStep({{12, 9, 10.0}}, 1.0, b).verdict == Verdict::kBudget);
  b.remaining_wall_s = 0;
  b.wall_per_simulated_s = std::numeric_limits<double>::quiet_NaN();  // no time left, rate unknown
  CHECK(PlanUntilStep({{12, 9, 10.0}}, 1.0, b).verdict == Verdict::kBudget);
}
