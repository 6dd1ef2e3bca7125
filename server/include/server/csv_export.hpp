#pragma once
/// The REST API's CSV exports (`?format=csv`, docs/server.md, *CSV*): made from the JSON the same
/// request answers, so both carry the same values; RFC 4180 records (core/csv.hpp).
#include <initializer_list>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "server/query.hpp"

namespace lw::server {

/// The `format` query parameter: "json" when absent, else one of `accepted`. nullopt with `*error`
/// set (the 400 message, naming the value and the accepted ones) otherwise.
std::optional<std::string> FormatParam(const QueryParams& params, std::initializer_list<const char*> accepted,
                                       std::string* error);

/// One JSON value as a CSV field: a string as it is, a number as JSON writes it, true/false, null empty.
std::string CsvCell(const nlohmann::ordered_json& value);

/// The `readings` array of GET .../readings: a header row, then one record per reading.
std::string ReadingsCsv(const nlohmann::ordered_json& readings);
/// GET .../forecast's JSON: a header row, one record per row (kind `row`), then per sensor (kind `sensor`).
std::string ForecastCsv(const nlohmann::ordered_json& forecast);

}  // namespace lw::server
