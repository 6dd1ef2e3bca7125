#pragma once
/// printf-style formatting for the diagnosis' texts (notes, explanations, data-quality details).
#include <cstdarg>
#include <cstddef>
#include <string>

namespace lw::diagnosis::detail {

/// `format` with `args`, at most `max_chars` characters (the rest cut off).
__attribute__((format(printf, 2, 0))) std::string VFormat(size_t max_chars, const char* format, va_list args);
/// printf into a std::string of at most 511 characters.
__attribute__((format(printf, 1, 2))) std::string Fmt(const char* format, ...);

}  // namespace lw::diagnosis::detail
