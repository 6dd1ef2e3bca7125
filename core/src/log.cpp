#include "core/log.hpp"

#include <algorithm>

namespace lw::core {

std::string SanitizeForLog(std::string_view text, size_t max_bytes) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string out;
  const size_t n = std::min(text.size(), max_bytes);
  out.reserve(n + 16);
  for (size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c == '\\') {
      out += "\\\\";
    } else if (c < 0x20 || c >= 0x7F) {
      out += "\\x";
      out.push_back(kHex[c >> 4]);
      out.push_back(kHex[c & 0xF]);
    } else {
      out.push_back(static_cast<char>(c));
    }
  }
  if (text.size() > n) out += "... (" + std::to_string(text.size()) + " bytes)";
  return out;
}

std::optional<std::string> LogLimiter::Admit(const std::string& kind, const std::string& line) {
  uint64_t n = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    n = ++counts_[kind];
  }
  if (n <= kFirst) return line;
  if (n % kEvery != 0) return std::nullopt;
  return line + " (" + std::to_string(n) + " so far)";
}

void Logger::operator()(const std::string& line) {
  Write(SanitizeForLog(line));
}

void Logger::Limited(const std::string& kind, const std::string& line) {
  // Cut before the count is added, so that a long line keeps its count.
  if (const auto admitted = limiter_.Admit(kind, SanitizeForLog(line))) Write(*admitted);
}

void Logger::Write(const std::string& safe) {
  const std::string stamp = stamp_ ? stamp_() + " " : std::string();
  std::lock_guard<std::mutex> lock(mutex_);
  out_ << stamp << program_ << ": " << safe << std::endl;
}

}  // namespace lw::core
