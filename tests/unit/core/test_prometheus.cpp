// The Prometheus text format writer (core/prometheus.hpp): the lines it writes, the escaping the
// format asks for, and the mistakes it refuses instead of writing text a scraper rejects.
#include "core/prometheus.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

#include <CppUTest/TestHarness.h>  // last

using namespace lw::core::prometheus;

TEST_GROUP(Prometheus){};

TEST(Prometheus, EachFamilyHasHelpAndTypeBeforeItsSamples) {
  Writer w;
  w.Counter("lw_things_total", "Things seen", 3);
  w.Family("lw_depth", "Records waiting", Type::kGauge);
  w.Sample({{"crusher", "c1"}}, 2.5);
  w.Sample({{"crusher", "c2"}, {"row", "lower"}}, 0);
  STRCMP_EQUAL(
      "# HELP lw_things_total Things seen\n"
      "# TYPE lw_things_total counter\n"
      "lw_things_total 3\n"
      "# HELP lw_depth Records waiting\n"
      "# TYPE lw_depth gauge\n"
      "lw_depth{crusher=\"c1\"} 2.5\n"
      "lw_depth{crusher=\"c2\",row=\"lower\"} 0\n",
      w.Take().c_str());
  STRCMP_EQUAL("", w.Take().c_str());
}

TEST(Prometheus, LabelValuesAndHelpAreEscapedAsTheFormatSays) {
  STRCMP_EQUAL("a\\\\b\\\"c\\nd", EscapeLabelValue("a\\b\"c\nd").c_str());
  STRCMP_EQUAL("say \"hi\" \\\\ twice\\n", EscapeHelp("say \"hi\" \\ twice\n").c_str());  // quotes stay in HELP
  STRCMP_EQUAL("{x}/é", EscapeLabelValue("{x}/é").c_str());
  Writer w;
  w.Family("lw_requests_total", "Line one\nline \\two", Type::kCounter);
  w.Sample({{"route", "/api/v1/crushers/{crusher}"}, {"path", "a\"b\\c\nd"}}, 1);
  STRCMP_EQUAL(
      "# HELP lw_requests_total Line one\\nline \\\\two\n"
      "# TYPE lw_requests_total counter\n"
      "lw_requests_total{route=\"/api/v1/crushers/{crusher}\",path=\"a\\\"b\\\\c\\nd\"} 1\n",
      w.Take().c_str());
}

TEST(Prometheus, ValuesAreWholeNumbersOrFloatsOrTheFormatsInfAndNaN) {
  STRCMP_EQUAL("0", FormatValue(0).c_str());
  STRCMP_EQUAL("1234567890123", FormatValue(1234567890123.0).c_str());
  STRCMP_EQUAL("-7", FormatValue(-7).c_str());
  STRCMP_EQUAL("0.25", FormatValue(0.25).c_str());
  STRCMP_EQUAL("+Inf", FormatValue(std::numeric_limits<double>::infinity()).c_str());
  STRCMP_EQUAL("-Inf", FormatValue(-std::numeric_limits<double>::infinity()).c_str());
  STRCMP_EQUAL("NaN", FormatValue(std::nan("")).c_str());
  DOUBLES_EQUAL(0.1, std::stod(FormatValue(0.1)), 0);  // round trips
  DOUBLES_EQUAL(1e300, std::stod(FormatValue(1e300)), 0);
}

TEST(Prometheus, HistogramBucketsAreCumulativeUpToInfWithSumAndCount) {
  Histogram h({1, 5});
  for (double v : {0.5, 1.0, 3.0, 100.0}) h.Observe(v);  // 1.0 falls in le="1"
  Writer w;
  w.Family("lw_lag_seconds", "Lag", Type::kHistogram);
  w.HistogramSample({{"crusher", "c1"}}, h.Snapshot());
  STRCMP_EQUAL(
      "# HELP lw_lag_seconds Lag\n"
      "# TYPE lw_lag_seconds histogram\n"
      "lw_lag_seconds_bucket{crusher=\"c1\",le=\"1\"} 2\n"
      "lw_lag_seconds_bucket{crusher=\"c1\",le=\"5\"} 3\n"
      "lw_lag_seconds_bucket{crusher=\"c1\",le=\"+Inf\"} 4\n"
      "lw_lag_seconds_sum{crusher=\"c1\"} 104.5\n"
      "lw_lag_seconds_count{crusher=\"c1\"} 4\n",
      w.Take().c_str());
  CHECK_THROWS(std::invalid_argument, Histogram({5, 1}));
  CHECK_THROWS(std::invalid_argument, Histogram({1, std::numeric_limits<double>::infinity()}));
}

TEST(Prometheus, RefusesWhatAParserWouldReject) {
  Writer w;
  CHECK_THROWS(std::invalid_argument, w.Sample(1));                                 // no family yet
  CHECK_THROWS(std::invalid_argument, w.Family("9lives", "x", Type::kGauge));       // bad first character
  CHECK_THROWS(std::invalid_argument, w.Family("lw-dash", "x", Type::kGauge));      // bad character
  CHECK_THROWS(std::invalid_argument, w.Family("lw_things", "x", Type::kCounter));  // a counter without _total
  w.Family("lw_ok", "x", Type::kGauge);
  CHECK_THROWS(std::invalid_argument, w.Family("lw_ok", "again", Type::kGauge));  // a family twice
  CHECK_THROWS(std::invalid_argument, w.Sample({{"bad-name", "v"}}, 1));          // bad label name
  CHECK_THROWS(std::invalid_argument, w.Sample({{"__reserved", "v"}}, 1));        // reserved label name
  CHECK_THROWS(std::invalid_argument, w.Sample({{"le", "1"}}, 1));                // le is the histograms'
  CHECK_THROWS(std::invalid_argument, w.Sample({{"a", "1"}, {"a", "2"}}, 1));     // a label twice
  w.Sample({{"a", "1"}, {"b", "2"}}, 1);
  CHECK_THROWS(std::invalid_argument, w.Sample({{"b", "2"}, {"a", "1"}}, 1));             // the same series twice
  CHECK_THROWS(std::invalid_argument, w.HistogramSample({}, Histogram({1}).Snapshot()));  // not a histogram family
  w.Family("lw_h", "x", Type::kHistogram);
  CHECK_THROWS(std::invalid_argument, w.Sample(1));  // a histogram's plain sample
}
