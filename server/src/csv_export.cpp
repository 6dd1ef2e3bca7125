#include "server/csv_export.hpp"

#include <vector>

#include "core/csv.hpp"

namespace lw::server {

using nlohmann::ordered_json;

std::optional<std::string> FormatParam(const QueryParams& params, std::initializer_list<const char*> accepted,
                                       std::string* error) {
  const std::string* given = FindParam(params, "format");
  if (!given) return std::string("json");
  std::string names;
  for (const char* a : accepted) {
    if (*given == a) return *given;
    names += std::string(names.empty() ? "" : ", ") + a;
  }
  *error = "format='" + *given + "': use one of " + names;
  return std::nullopt;
}

std::string CsvCell(const ordered_json& value) {
  if (value.is_null()) return {};
  if (value.is_string()) return value.get<std::string>();
  return value.dump(-1, ' ', false, ordered_json::error_handler_t::replace);
}

namespace {

/// `o[key]`, or null when `o` is not an object or lacks it.
const ordered_json& Field(const ordered_json& o, const char* key) {
  static const ordered_json kNull;
  if (!o.is_object()) return kNull;
  const auto it = o.find(key);
  return it == o.end() ? kNull : *it;
}

/// `o[key][i]` of a [lo, hi] pair, or null.
const ordered_json& BandEnd(const ordered_json& o, const char* key, size_t i) {
  static const ordered_json kNull;
  const ordered_json& band = Field(o, key);
  return band.is_array() && band.size() > i ? band[i] : kNull;
}

}  // namespace

std::string ReadingsCsv(const ordered_json& readings) {
  static const std::vector<const char*> kColumns = {"time",  "seq",        "thickness_mm", "loops_intact",
                                                    "flags", "battery_mv", "received",     "previous_liner"};
  std::string out;
  core::AppendCsvRecord(&out, {kColumns.begin(), kColumns.end()});
  for (const ordered_json& r : readings) {
    std::vector<std::string> fields;
    for (const char* c : kColumns) {
      const ordered_json& v = Field(r, c);
      fields.push_back(std::string(c) == "previous_liner" ? (v.is_boolean() && v.get<bool>() ? "true" : "false") : CsvCell(v));
    }
    core::AppendCsvRecord(&out, fields);
  }
  return out;
}

std::string ForecastCsv(const ordered_json& forecast) {
  std::string out;
  core::AppendCsvRecord(&out, {"kind", "id", "thickness_mm", "thickness_lo_mm", "thickness_hi_mm", "rate_mm_per_day",
                               "reach_date", "reach_earliest", "reach_latest", "last_time", "last_reading_mm", "note"});
  for (const ordered_json& r : Field(forecast, "rows")) {
    core::AppendCsvRecord(
        &out,
        {"row", CsvCell(Field(r, "row")), CsvCell(Field(r, "min_thickness_mm")), CsvCell(BandEnd(r, "min_thickness_band_mm", 0)),
         CsvCell(BandEnd(r, "min_thickness_band_mm", 1)), CsvCell(Field(r, "rate_mm_per_day")), CsvCell(Field(r, "reach_date")),
         CsvCell(Field(r, "reach_earliest")), CsvCell(Field(r, "reach_latest")), "", "", CsvCell(Field(r, "note"))});
  }
  for (const ordered_json& s : Field(forecast, "sensors")) {
    core::AppendCsvRecord(
        &out, {"sensor", CsvCell(Field(s, "id")), CsvCell(Field(s, "thickness_mm")), "", "", CsvCell(Field(s, "rate_mm_per_day")),
               CsvCell(Field(s, "reach_date")), CsvCell(Field(s, "reach_earliest")), CsvCell(Field(s, "reach_latest")),
               CsvCell(Field(s, "last_time")), CsvCell(Field(s, "last_reading_mm")), CsvCell(Field(s, "note"))});
  }
  return out;
}

}  // namespace lw::server
