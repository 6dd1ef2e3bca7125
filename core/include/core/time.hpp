#pragma once
/// ISO-8601 UTC time handling shared by every host component.
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace lw::core {

using TimePoint = std::chrono::sys_seconds;

/// Parses "YYYY-MM-DDTHH:MM:SS[.fff]Z", "YYYY-MM-DDTHH:MM:SS[.fff]+HH:MM", "YYYY-MM-DD HH:MM:SS"
/// (taken as UTC) and "YYYY-MM-DD" (midnight UTC). Fractions are truncated to seconds.
/// Returns nullopt on anything else (including impossible dates such as 2026-02-30).
std::optional<TimePoint> ParseIsoTime(std::string_view text);

/// Formats as "YYYY-MM-DDTHH:MM:SSZ".
std::string FormatIsoTime(TimePoint t);

/// The store and the wire keep whole Unix seconds; the domain keeps TimePoints.
inline TimePoint FromUnixSeconds(int64_t s) {
  return TimePoint(std::chrono::seconds(s));
}
inline int64_t ToUnixSeconds(TimePoint t) {
  return t.time_since_epoch().count();
}
/// FormatIsoTime of whole Unix seconds.
inline std::string FormatIsoSeconds(int64_t s) {
  return FormatIsoTime(FromUnixSeconds(s));
}

/// A wall-time length for progress lines: "12m05s" under an hour, "3h07m" from an hour on; "?"
/// when not finite (not known yet). Negative lengths count as 0.
std::string FormatDuration(double seconds);

/// Days (fractional) from a to b.
inline double DaysBetween(TimePoint a, TimePoint b) {
  return std::chrono::duration<double>(b - a).count() / 86400.0;
}
inline TimePoint AddDays(TimePoint t, double days) {
  return t + std::chrono::seconds(static_cast<long long>(days * 86400.0));
}

}  // namespace lw::core
