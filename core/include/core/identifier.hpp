#pragma once
/// The one rule for the names linerwatch puts in MQTT topic levels, URL path segments, file names
/// and dashboard text: site, crusher and sensor ids. crusher.json, the gateway's --site and
/// --crusher, the server and the CLI all apply it, so a name one accepts the others accept.
#include <string_view>

namespace lw::core {

/// 1-64 characters of ASCII letters, digits, '.', '_' and '-' (no '/', '+', '#', spaces, markup,
/// control characters or non-ASCII bytes).
bool IsIdentifier(std::string_view id);

/// The rule in words, for error messages: "1-64 letters, digits, '.', '_' or '-'".
inline constexpr std::string_view kIdentifierRule = "1-64 letters, digits, '.', '_' or '-'";

}  // namespace lw::core
