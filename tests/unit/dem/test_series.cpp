// Steady-window detection and window splitting (dem/series.hpp), on a chamber-mass series recorded
// from a real LIGGGHTS run (tests/data/dem/tiny_mass.txt, written by `linerwatch dem`) and on
// constructed series for the edge cases.
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "dem/series.hpp"

#include <CppUTest/TestHarness.h>

namespace {

struct Series {
  std::vector<double> t, m;
};

Series Recorded() {
  Series s;
  std::ifstream in(std::string(LW_TEST_DATA_DIR) + "/dem/tiny_mass.txt");
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    double t, n, m;
    if (ls >> t >> n >> m) s.t.push_back(t), s.m.push_back(m);
  }
  return s;
}

Series Ramp(double fill_s, double end_s, double level, double dt = 0.1) {
  Series s;
  for (double t = 0; t <= end_s + 1e-9; t += dt) {
    s.t.push_back(t);
    s.m.push_back(t < fill_s ? level * t / fill_s : level * (1 + 0.01 * std::sin(7 * t)));
  }
  return s;
}

}  // namespace

TEST_GROUP(SteadyWindow){};

TEST(SteadyWindow, RecordedRunFillsThenHoldsSteady) {
  const Series s = Recorded();
  CHECK(s.t.size() > 100);
  const auto w = lw::dem::DetectSteadyWindow(s.t, s.m);
  CHECK_TRUE(w.found);
  // The chamber of this run fills in about a second (the particle count flattens near 1.2-1.4 s)
  // and stays within 5 % of its level to the end (3 s).
  CHECK(w.t_start > 0.9 && w.t_start < 1.6);
  DOUBLES_EQUAL(3.0, w.t_end, 1e-9);
  CHECK(w.level > 400 && w.level < 500);
  for (size_t i = 0; i < s.t.size(); ++i)
    if (s.t[i] >= w.t_start) CHECK(std::abs(s.m[i] - w.level) <= w.band);
}

TEST(SteadyWindow, StartIsWhereTheFillEnds) {
  const Series s = Ramp(4.0, 16.0, 30000);
  const auto w = lw::dem::DetectSteadyWindow(s.t, s.m);
  CHECK_TRUE(w.found);
  CHECK(w.t_start >= 3.7 && w.t_start <= 4.1);
  CHECK(std::abs(w.drift) < 0.05);
  STRCMP_EQUAL("", w.reason.c_str());
}

TEST(SteadyWindow, NeverFilledIsRefusedWithAReason) {
  Series s;
  for (int i = 0; i < 20; ++i) s.t.push_back(i * 0.1), s.m.push_back(0.0);
  const auto w = lw::dem::DetectSteadyWindow(s.t, s.m);
  CHECK_FALSE(w.found);
  CHECK(w.reason.find("never filled") != std::string::npos);
}

TEST(SteadyWindow, StillFillingAtTheEndIsNotSteady) {
  // Filling all the way: the last quarter is not a plateau, the steady span is a sliver.
  const Series s = Ramp(20.0, 16.0, 30000);
  const auto w = lw::dem::DetectSteadyWindow(s.t, s.m);
  CHECK_FALSE(w.found);
  CHECK(w.reason.find("simulate longer") != std::string::npos);
}

TEST(SteadyWindow, TooFewSamples) {
  const auto w = lw::dem::DetectSteadyWindow({0, 1, 2}, {1, 1, 1});
  CHECK_FALSE(w.found);
  CHECK(w.reason.find("samples") != std::string::npos);
}

TEST(SteadyWindow, LengthMismatchThrows) {
  CHECK_THROWS(std::invalid_argument, lw::dem::DetectSteadyWindow({0, 1}, {1}));
}

TEST_GROUP(Windows){};

TEST(Windows, CountFromSpan) {
  LONGS_EQUAL(6, lw::dem::ChooseWindowCount(12.0, 2.0, 0));
  LONGS_EQUAL(8, lw::dem::ChooseWindowCount(40.0, 2.0, 0));  // capped
  LONGS_EQUAL(4, lw::dem::ChooseWindowCount(12.0, 2.0, 4));  // as asked
  LONGS_EQUAL(0, lw::dem::ChooseWindowCount(12.0, 2.0, 7));  // asked for more than fit
  LONGS_EQUAL(0, lw::dem::ChooseWindowCount(3.0, 2.0, 0));   // not even 2
}

TEST(Windows, SplitCoversTheSpanContiguously) {
  const auto w = lw::dem::SplitWindows(8, 31, 5);  // 23 intervals
  LONGS_EQUAL(5, w.size());
  LONGS_EQUAL(8, w.front().first);
  LONGS_EQUAL(31, w.back().second);
  size_t intervals = 0;
  for (size_t i = 0; i < w.size(); ++i) {
    CHECK(w[i].second > w[i].first);
    if (i > 0) LONGS_EQUAL(w[i - 1].second, w[i].first);
    const size_t len = w[i].second - w[i].first;
    CHECK(len == 4 || len == 5);
    intervals += len;
  }
  LONGS_EQUAL(23, intervals);
}

TEST(Windows, OneIntervalEach) {
  const auto w = lw::dem::SplitWindows(0, 4, 4);
  LONGS_EQUAL(4, w.size());
  for (size_t i = 0; i < 4; ++i) LONGS_EQUAL(1, w[i].second - w[i].first);
}

TEST(Windows, MoreWindowsThanIntervalsThrows) {
  CHECK_THROWS(std::invalid_argument, lw::dem::SplitWindows(3, 5, 3));
  CHECK_THROWS(std::invalid_argument, lw::dem::SplitWindows(3, 9, 0));
}
