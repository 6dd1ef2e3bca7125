#include "core/prometheus.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace lw::core::prometheus {
namespace {

bool NameChar(char c, bool first, bool colon_ok) {
  const bool alpha = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' || (colon_ok && c == ':');
  return alpha || (!first && c >= '0' && c <= '9');
}

bool ValidName(std::string_view name, bool colon_ok) {
  if (name.empty()) return false;
  for (size_t i = 0; i < name.size(); ++i) {
    if (!NameChar(name[i], i == 0, colon_ok)) return false;
  }
  return true;
}

const char* TypeName(Type type) {
  switch (type) {
    case Type::kCounter:
      return "counter";
    case Type::kGauge:
      return "gauge";
    case Type::kHistogram:
      return "histogram";
  }
  return "untyped";
}

}  // namespace

std::string EscapeLabelValue(std::string_view value) {
  std::string out;
  out.reserve(value.size());
  for (char c : value) {
    if (c == '\\')
      out += "\\\\";
    else if (c == '"')
      out += "\\\"";
    else if (c == '\n')
      out += "\\n";
    else
      out += c;
  }
  return out;
}

std::string EscapeHelp(std::string_view help) {
  std::string out;
  out.reserve(help.size());
  for (char c : help) {
    if (c == '\\')
      out += "\\\\";
    else if (c == '\n')
      out += "\\n";
    else
      out += c;
  }
  return out;
}

std::string FormatValue(double value) {
  if (std::isnan(value)) return "NaN";
  if (std::isinf(value)) return value > 0 ? "+Inf" : "-Inf";
  char buf[40];
  if (value == std::trunc(value) && std::fabs(value) < 9007199254740992.0) {
    std::snprintf(buf, sizeof buf, "%.0f", value);
  } else {
    std::snprintf(buf, sizeof buf, "%.17g", value);
  }
  return buf;
}

Histogram::Histogram(std::vector<double> upper_bounds) {
  for (size_t i = 0; i < upper_bounds.size(); ++i) {
    if (!std::isfinite(upper_bounds[i]) || (i > 0 && !(upper_bounds[i] > upper_bounds[i - 1])))
      throw std::invalid_argument("histogram bounds must be finite and ascending");
  }
  counts_.counts.assign(upper_bounds.size() + 1, 0);
  counts_.upper_bounds = std::move(upper_bounds);
}

void Histogram::Observe(double value) {
  const auto& b = counts_.upper_bounds;  // never changes after construction
  const size_t bucket = static_cast<size_t>(std::lower_bound(b.begin(), b.end(), value) - b.begin());  // le: value <= bound
  std::lock_guard<std::mutex> lock(mutex_);
  ++counts_.counts[bucket];
  counts_.sum += value;
  ++counts_.count;
}

HistogramCounts Histogram::Snapshot() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counts_;
}

void Writer::Family(std::string_view name, std::string_view help, Type type) {
  const std::string n(name);
  if (!ValidName(name, true)) throw std::invalid_argument("metric name '" + n + "' is not [a-zA-Z_:][a-zA-Z0-9_:]*");
  if (type == Type::kCounter && (n.size() < 6 || n.compare(n.size() - 6, 6, "_total") != 0))
    throw std::invalid_argument("counter '" + n + "' must end in _total");
  if (!families_.insert(n).second) throw std::invalid_argument("metric family '" + n + "' written twice");
  family_ = n;
  type_ = type;
  series_.clear();
  out_ += "# HELP " + n + " " + EscapeHelp(help) + "\n";
  out_ += "# TYPE " + n + " " + TypeName(type) + "\n";
}

void Writer::Line(std::string_view suffix, const Labels& labels, const std::string* le, double value) {
  out_ += family_;
  out_ += suffix;
  if (!labels.empty() || le) {
    out_ += '{';
    bool first = true;
    for (const auto& [name, v] : labels) {
      if (!first) out_ += ',';
      first = false;
      out_ += name + "=\"" + EscapeLabelValue(v) + "\"";
    }
    if (le) out_ += std::string(first ? "" : ",") + "le=\"" + *le + "\"";
    out_ += '}';
  }
  out_ += ' ' + FormatValue(value) + '\n';
}

namespace {

/// Checks `labels` (names valid, not reserved, none twice) and returns their canonical key.
std::string SeriesKey(const std::string& family, const Labels& labels) {
  Labels sorted = labels;
  std::sort(sorted.begin(), sorted.end());
  std::string key;
  for (size_t i = 0; i < sorted.size(); ++i) {
    const std::string& name = sorted[i].first;
    if (!ValidName(name, false) || name.rfind("__", 0) == 0 || name == "le")
      throw std::invalid_argument(family + ": label name '" + name + "' is not allowed");
    if (i > 0 && sorted[i - 1].first == name) throw std::invalid_argument(family + ": label '" + name + "' given twice");
    key += name + '\0' + sorted[i].second + '\0';
  }
  return key;
}

}  // namespace

void Writer::Sample(const Labels& labels, double value) {
  if (family_.empty()) throw std::invalid_argument("sample before any metric family");
  if (type_ == Type::kHistogram) throw std::invalid_argument(family_ + ": a histogram's samples are HistogramSample()");
  if (!series_.insert(SeriesKey(family_, labels)).second)
    throw std::invalid_argument(family_ + ": the same labels written twice");
  Line("", labels, nullptr, value);
}

void Writer::HistogramSample(const Labels& labels, const HistogramCounts& h) {
  if (family_.empty() || type_ != Type::kHistogram) throw std::invalid_argument("histogram sample outside a histogram family");
  if (h.counts.size() != h.upper_bounds.size() + 1) throw std::invalid_argument(family_ + ": bucket counts do not match bounds");
  if (!series_.insert(SeriesKey(family_, labels)).second)
    throw std::invalid_argument(family_ + ": the same labels written twice");
  uint64_t cumulative = 0;
  for (size_t i = 0; i < h.counts.size(); ++i) {
    cumulative += h.counts[i];
    const std::string le = i < h.upper_bounds.size() ? FormatValue(h.upper_bounds[i]) : "+Inf";
    Line("_bucket", labels, &le, static_cast<double>(cumulative));
  }
  Line("_sum", labels, nullptr, h.sum);
  Line("_count", labels, nullptr, static_cast<double>(cumulative));
}

void Writer::Counter(std::string_view name, std::string_view help, double value) {
  Family(name, help, Type::kCounter);
  Sample(value);
}

void Writer::Gauge(std::string_view name, std::string_view help, double value) {
  Family(name, help, Type::kGauge);
  Sample(value);
}

std::string Writer::Take() {
  std::string text;
  text.swap(out_);
  family_.clear();
  families_.clear();
  series_.clear();
  return text;
}

}  // namespace lw::core::prometheus
