#include "core/time.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>

namespace lw::core {
namespace {

bool Digits(std::string_view s, size_t pos, size_t n, int* out) {
  if (pos + n > s.size()) return false;
  int v = 0;
  for (size_t i = pos; i < pos + n; ++i) {
    if (!std::isdigit(static_cast<unsigned char>(s[i]))) return false;
    v = v * 10 + (s[i] - '0');
  }
  *out = v;
  return true;
}

}  // namespace

std::optional<TimePoint> ParseIsoTime(std::string_view text) {
  while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back()))) text.remove_suffix(1);
  while (!text.empty() && std::isspace(static_cast<unsigned char>(text.front()))) text.remove_prefix(1);
  int y, mo, d;
  if (!Digits(text, 0, 4, &y) || text.size() < 10 || text[4] != '-' || !Digits(text, 5, 2, &mo) || text[7] != '-' ||
      !Digits(text, 8, 2, &d)) {
    return std::nullopt;
  }
  const std::chrono::year_month_day ymd{std::chrono::year{y}, std::chrono::month{static_cast<unsigned>(mo)},
                                        std::chrono::day{static_cast<unsigned>(d)}};
  if (!ymd.ok()) return std::nullopt;
  TimePoint t = std::chrono::sys_days{ymd};
  if (text.size() == 10) return t;
  if (text[10] != 'T' && text[10] != ' ') return std::nullopt;
  int h, mi, s = 0;
  if (!Digits(text, 11, 2, &h) || text.size() < 16 || text[13] != ':' || !Digits(text, 14, 2, &mi)) return std::nullopt;
  size_t pos = 16;
  if (pos < text.size() && text[pos] == ':') {
    if (!Digits(text, pos + 1, 2, &s)) return std::nullopt;
    pos += 3;
    if (pos < text.size() && text[pos] == '.') {
      ++pos;
      while (pos < text.size() && std::isdigit(static_cast<unsigned char>(text[pos]))) ++pos;
    }
  }
  if (h > 23 || mi > 59 || s > 60) return std::nullopt;
  t += std::chrono::hours{h} + std::chrono::minutes{mi} + std::chrono::seconds{s};
  if (pos == text.size()) return t;  // no zone: UTC
  if (text[pos] == 'Z' && pos + 1 == text.size()) return t;
  if (text[pos] == '+' || text[pos] == '-') {
    int oh, om = 0;
    if (!Digits(text, pos + 1, 2, &oh)) return std::nullopt;
    size_t p = pos + 3;
    if (p < text.size() && text[p] == ':') ++p;
    if (p < text.size()) {
      if (!Digits(text, p, 2, &om)) return std::nullopt;
      p += 2;
    }
    if (p != text.size() || oh > 23 || om > 59) return std::nullopt;
    const auto offset = std::chrono::hours{oh} + std::chrono::minutes{om};
    return text[pos] == '+' ? t - offset : t + offset;
  }
  return std::nullopt;
}

std::string FormatIsoTime(TimePoint t) {
  const auto day = std::chrono::floor<std::chrono::days>(t);
  const std::chrono::year_month_day ymd{day};
  const std::chrono::hh_mm_ss hms{t - day};
  const int year = static_cast<int>(ymd.year());
  if (year >= 0 && year <= 9999) {
    // Written digit by digit: a readings page formats two times per reading, and snprintf's
    // format parsing was most of that page's text writing (docs/performance.md).
    char out[20];
    const auto put = [&out](size_t at, unsigned v, size_t width) {
      for (size_t i = width; i-- > 0; v /= 10) out[at + i] = static_cast<char>('0' + v % 10);
    };
    put(0, static_cast<unsigned>(year), 4);
    out[4] = '-';
    put(5, static_cast<unsigned>(ymd.month()), 2);
    out[7] = '-';
    put(8, static_cast<unsigned>(ymd.day()), 2);
    out[10] = 'T';
    put(11, static_cast<unsigned>(hms.hours().count()), 2);
    out[13] = ':';
    put(14, static_cast<unsigned>(hms.minutes().count()), 2);
    out[16] = ':';
    put(17, static_cast<unsigned>(hms.seconds().count()), 2);
    return std::string(out, 19) + 'Z';
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, "%04d-%02u-%02uT%02d:%02d:%02dZ", static_cast<int>(ymd.year()),
                static_cast<unsigned>(ymd.month()), static_cast<unsigned>(ymd.day()), static_cast<int>(hms.hours().count()),
                static_cast<int>(hms.minutes().count()), static_cast<int>(hms.seconds().count()));
  return buf;
}

std::string FormatDuration(double seconds) {
  if (!std::isfinite(seconds)) return "?";
  char b[40];
  const long v = std::lround(std::max(0.0, seconds));
  if (v >= 3600)
    std::snprintf(b, sizeof b, "%ldh%02ldm", v / 3600, (v % 3600) / 60);
  else
    std::snprintf(b, sizeof b, "%ldm%02lds", v / 60, v % 60);
  return b;
}

}  // namespace lw::core
