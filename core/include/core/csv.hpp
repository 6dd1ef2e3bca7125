#pragma once
/// CSV as RFC 4180 writes it: the REST exports (`?format=csv`, docs/server.md, *CSV*).
#include <string>
#include <string_view>
#include <vector>

namespace lw::core {

/// The Content-Type of a CSV export.
inline constexpr const char* kCsvContentType = "text/csv; charset=utf-8";

/// `field` as it goes into a record: quoted (with `"` doubled) when it holds a comma, a quote, a
/// carriage return or a line feed, or starts or ends with a space; as it is otherwise.
std::string CsvField(std::string_view field);
/// Appends one record to `out`: the fields, quoted where needed, separated by commas, ended by CRLF.
void AppendCsvRecord(std::string* out, const std::vector<std::string>& fields);

}  // namespace lw::core
