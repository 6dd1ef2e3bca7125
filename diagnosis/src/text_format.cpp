#include "text_format.hpp"

#include <cstdio>
#include <vector>

namespace lw::diagnosis::detail {

std::string VFormat(size_t max_chars, const char* format, va_list args) {
  std::vector<char> buffer(max_chars + 1);
  std::vsnprintf(buffer.data(), buffer.size(), format, args);
  return buffer.data();
}

std::string Fmt(const char* format, ...) {
  va_list args;
  va_start(args, format);
  std::string s = VFormat(511, format, args);
  va_end(args);
  return s;
}

}  // namespace lw::diagnosis::detail
