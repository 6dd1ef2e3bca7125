#pragma once
/// The Prometheus text exposition format, version 0.0.4: the one writer behind the server's
/// `GET /metrics` and the gateway's `--metrics` (docs/server.md, docs/gateway.md, *Metrics*).
///
///   core::prometheus::Writer w;
///   w.Family("linerwatch_readings_stored_total", "Readings committed", Type::kCounter);
///   w.Sample(42);
///   w.Family("linerwatch_http_requests_total", "HTTP requests", Type::kCounter);
///   w.Sample({{"route", "/healthz"}, {"code", "200"}}, 3);
///   std::string body = w.Take();   // served as kContentType
///
/// Each family gets its `# HELP` and `# TYPE` lines before its samples; its samples follow it
/// and no other family's. Names, label names and label sets are checked as they are written (a
/// bad one is a bug in the caller: std::invalid_argument naming it), so a scrape never returns
/// text a parser refuses. Not thread-safe: one Writer per scrape.
#include <cstdint>
#include <mutex>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace lw::core::prometheus {

/// The Content-Type of the text format.
inline constexpr const char* kContentType = "text/plain; version=0.0.4; charset=utf-8";

enum class Type { kCounter, kGauge, kHistogram };

/// A sample's labels, in the order written.
using Labels = std::vector<std::pair<std::string, std::string>>;

/// A label value as the format writes it between its quotes: `\` -> `\\`, `"` -> `\"`, a line
/// feed -> `\n`.
std::string EscapeLabelValue(std::string_view value);
/// A HELP text: `\` -> `\\`, a line feed -> `\n`.
std::string EscapeHelp(std::string_view help);
/// A sample value: whole numbers below 2^53 without a fraction or exponent, others with 17
/// significant digits; `+Inf`, `-Inf`, `NaN`.
std::string FormatValue(double value);

/// A histogram's state: per-bucket (not cumulative) counts for `upper_bounds` and one more for
/// the values above the last bound (+Inf).
struct HistogramCounts {
  std::vector<double> upper_bounds;  ///< ascending, finite
  std::vector<uint64_t> counts;      ///< upper_bounds.size() + 1 entries
  double sum = 0;
  uint64_t count = 0;
};

/// A histogram that several threads observe into. Observe() takes a mutex for a few ns.
class Histogram {
 public:
  /// `upper_bounds` ascending and finite; throws std::invalid_argument otherwise.
  explicit Histogram(std::vector<double> upper_bounds);
  void Observe(double value);
  HistogramCounts Snapshot() const;

 private:
  mutable std::mutex mutex_;
  HistogramCounts counts_;
};

class Writer {
 public:
  /// Starts a family: `# HELP name help` and `# TYPE name type`. A counter's name ends in
  /// `_total`. Throws std::invalid_argument on a name that is not `[a-zA-Z_:][a-zA-Z0-9_:]*`, a
  /// counter without `_total`, or a family written before.
  void Family(std::string_view name, std::string_view help, Type type);
  /// A sample of the current counter or gauge family. Throws std::invalid_argument on a bad or
  /// repeated label name, a label set already written in this family, or no family started.
  void Sample(const Labels& labels, double value);
  void Sample(double value) { Sample({}, value); }
  /// The `_bucket` (cumulative, `le` label, up to `+Inf`), `_sum` and `_count` samples of the
  /// current histogram family.
  void HistogramSample(const Labels& labels, const HistogramCounts& h);

  /// A family with its single unlabelled sample.
  void Counter(std::string_view name, std::string_view help, double value);
  void Gauge(std::string_view name, std::string_view help, double value);

  /// The text written so far (every line ends in a line feed); the writer starts empty again.
  std::string Take();

 private:
  void Line(std::string_view suffix, const Labels& labels, const std::string* le, double value);

  std::string out_;
  std::string family_;
  Type type_ = Type::kGauge;
  std::set<std::string> families_;
  std::set<std::string> series_;  ///< label sets written in the current family
};

}  // namespace lw::core::prometheus
