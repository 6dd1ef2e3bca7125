#include "core/median.hpp"

#include <cmath>
#include <vector>

#include <CppUTest/TestHarness.h>

using namespace lw::core;

TEST_GROUP(Median){};

TEST(Median, TheUpperMedianIsASampleWhateverTheOrder) {
  DOUBLES_EQUAL(3, UpperMedian({5, 1, 3}), 0);
  DOUBLES_EQUAL(4, UpperMedian({4, 1, 9, 2}), 0);  // of 1 2 4 9: the upper of the middle two
  DOUBLES_EQUAL(4, UpperMedian({9, 4, 2, 1}), 0);
  DOUBLES_EQUAL(7, UpperMedian({7}), 0);
}

TEST(Median, TheUpperMedianOfNothingIsWhatTheCallerSays) {
  DOUBLES_EQUAL(0, UpperMedian({}), 0);
  CHECK_TRUE(std::isnan(UpperMedian({}, std::nan(""))));
  DOUBLES_EQUAL(-1, UpperMedian({}, -1), 0);
}

TEST(Median, TheMedianOfAnEvenCountIsTheMeanOfItsMiddleTwo) {
  DOUBLES_EQUAL(3, Median({4, 1, 9, 2}), 1e-12);
  DOUBLES_EQUAL(3, Median({2, 9, 1, 4}), 1e-12);
  DOUBLES_EQUAL(5, Median({5, 1, 8}), 0);
  DOUBLES_EQUAL(2.5, Median({3, 2}), 1e-12);
  CHECK_TRUE(std::isnan(Median({})));
}
