// `?format=csv` of GET .../readings and .../forecast (server/csv_export.hpp) through
// rest::Resources: RFC 4180 records with a header row, the same values, filters, limit and
// cursor as the JSON answer (the next page's cursor in X-Next-Cursor), and a 400 naming the
// accepted formats.
#include <string>
#include <vector>

#include "server/csv_export.hpp"
#include "server/rest.hpp"
#include "unit/server/server_fixture.hpp"

#include <CppUTest/TestHarness.h>  // last

using namespace lw::server;
using nlohmann::json;
using nlohmann::ordered_json;

namespace {

lw::test::CrusherFolder& Folder() {
  static lw::test::CrusherFolder f(10, 5);
  return f;
}

/// RFC 4180 records of `text` (quoted fields with "" for a quote; CRLF between records).
std::vector<std::vector<std::string>> ParseCsv(const std::string& text) {
  std::vector<std::vector<std::string>> records;
  std::vector<std::string> record;
  std::string field;
  bool quoted = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quoted) {
      if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') {
        field += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        field += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      record.push_back(field);
      field.clear();
    } else if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') {
      record.push_back(field);
      field.clear();
      records.push_back(record);
      record.clear();
      ++i;
    } else {
      field += c;
    }
  }
  CHECK_TEXT(record.empty() && field.empty(), "the last record does not end in CRLF");
  return records;
}

struct Fixture {
  lw::test::ServerParts parts{Folder().crushers, false};
  std::unique_ptr<rest::Resources> resources = std::make_unique<rest::Resources>(parts.ctx);
  Fixture() {
    json body = {{"readings", json::array()}};
    for (const auto& m : lw::test::Messages(Folder().bundle)) body["readings"].push_back(json::parse(m.payload));
    const std::string text = body.dump();
    rest::Request post;
    post.path = {Folder().id()};
    post.body = text;
    LONGS_EQUAL(200,
                resources->Call(rest::Resources::Find(rest::Method::kPost, "/api/v1/crushers/{crusher}/readings"), post).status);
  }
  rest::Response Get(const char* route, std::vector<std::string> path, QueryParams query) {
    rest::Request r;
    r.path = std::move(path);
    r.query = std::move(query);
    return lw::test::WithJson(resources->Call(rest::Resources::Find(rest::Method::kGet, route), r));
  }
};

const char* kReadings = "/api/v1/crushers/{crusher}/sensors/{sensor}/readings";

std::string HeaderOf(const rest::Response& r, const std::string& name) {
  for (const auto& [n, v] : r.headers) {
    if (n == name) return v;
  }
  return {};
}

}  // namespace

TEST_GROUP(CsvExport){};

TEST(CsvExport, ReadingsPageLikeTheJsonWithTheCursorInAHeader) {
  Fixture f;
  const std::string sensor = Folder().bundle.crusher.sensors.at(0).id;
  const std::string from = lw::core::FormatIsoTime(lw::core::AddDays(Folder().bundle.crusher.installed_at, 2));
  std::string json_cursor, csv_cursor;
  size_t pages = 0, total = 0;
  do {
    QueryParams q = {{"limit", "5"}, {"from", from}};
    if (!json_cursor.empty()) q.emplace("cursor", json_cursor);
    const rest::Response page = f.Get(kReadings, {Folder().id(), sensor}, q);
    QueryParams qc = {{"limit", "5"}, {"from", from}, {"format", "csv"}};
    if (!csv_cursor.empty()) qc.emplace("cursor", csv_cursor);
    const rest::Response csv = f.Get(kReadings, {Folder().id(), sensor}, qc);
    LONGS_EQUAL(200, csv.status);
    CHECK(csv.raw.has_value());
    STRCMP_EQUAL("text/csv; charset=utf-8", csv.raw->content_type.c_str());
    const auto records = ParseCsv(csv.raw->content);
    CHECK((std::vector<std::string>{"time", "seq", "thickness_mm", "loops_intact", "flags", "battery_mv", "received",
                                    "previous_liner"}) == records.at(0));
    const json& readings = page.json["readings"];
    LONGS_EQUAL(readings.size() + 1, records.size());
    for (size_t i = 0; i < readings.size(); ++i) {
      STRCMP_EQUAL(readings[i]["time"].get<std::string>().c_str(), records[i + 1][0].c_str());
      LONGS_EQUAL(readings[i]["seq"].get<long>(), std::stol(records[i + 1][1]));
      DOUBLES_EQUAL(readings[i]["thickness_mm"].get<double>(), std::stod(records[i + 1][2]), 0);
      STRCMP_EQUAL("false", records[i + 1][7].c_str());
    }
    json_cursor = page.json["next_cursor"].is_null() ? "" : page.json["next_cursor"].get<std::string>();
    csv_cursor = HeaderOf(csv, "X-Next-Cursor");
    STRCMP_EQUAL(json_cursor.c_str(), csv_cursor.c_str());  // absent on the last page, as next_cursor is null
    total += readings.size();
    ++pages;
  } while (!json_cursor.empty());
  CHECK(pages > 1);
  size_t expected = 0;
  for (const auto& r : Folder().bundle.readings) expected += r.sensor_id == sensor && r.time >= *lw::core::ParseIsoTime(from);
  LONGS_EQUAL(expected, total);
  // The query's own checks come first, as for JSON.
  LONGS_EQUAL(400, f.Get(kReadings, {Folder().id(), sensor}, {{"format", "csv"}, {"limit", "0"}}).status);
}

TEST(CsvExport, AnUnknownFormatNamesTheAcceptedOnes) {
  Fixture f;
  const std::string sensor = Folder().bundle.crusher.sensors.at(0).id;
  rest::Response r = f.Get(kReadings, {Folder().id(), sensor}, {{"format", "xml"}});
  LONGS_EQUAL(400, r.status);
  STRCMP_EQUAL("format='xml': use one of json, csv", r.json["error"].get<std::string>().c_str());
  r = f.Get("/api/v1/crushers/{crusher}/forecast", {Folder().id()}, {{"format", "CSV"}});
  LONGS_EQUAL(400, r.status);
  STRCMP_EQUAL("format='CSV': use one of json, csv", r.json["error"].get<std::string>().c_str());
  r = f.Get(kReadings, {Folder().id(), sensor}, {{"format", "json"}});
  LONGS_EQUAL(200, r.status);
  STRCMP_EQUAL("application/json", r.raw->content_type.c_str());
  CHECK(r.json.contains("readings"));
}

TEST(CsvExport, ForecastHasOneRecordPerRowThenPerSensorWithTheJsonsValues) {
  Fixture f;
  const json forecast = f.Get("/api/v1/crushers/{crusher}/forecast", {Folder().id()}, {}).json;
  const rest::Response csv = f.Get("/api/v1/crushers/{crusher}/forecast", {Folder().id()}, {{"format", "csv"}});
  LONGS_EQUAL(200, csv.status);
  STRCMP_EQUAL("text/csv; charset=utf-8", csv.raw->content_type.c_str());
  const auto records = ParseCsv(csv.raw->content);
  CHECK((std::vector<std::string>{"kind", "id", "thickness_mm", "thickness_lo_mm", "thickness_hi_mm", "rate_mm_per_day",
                                  "reach_date", "reach_earliest", "reach_latest", "last_time", "last_reading_mm", "note"}) ==
        records.at(0));
  const size_t rows = forecast["rows"].size(), sensors = forecast["sensors"].size();
  CHECK(rows > 0 && sensors > 0);
  LONGS_EQUAL(1 + rows + sensors, records.size());
  for (size_t i = 0; i < rows; ++i) {
    const json& r = forecast["rows"][i];
    const auto& rec = records[1 + i];
    STRCMP_EQUAL("row", rec[0].c_str());
    STRCMP_EQUAL(r["row"].get<std::string>().c_str(), rec[1].c_str());
    DOUBLES_EQUAL(r["min_thickness_mm"].get<double>(), std::stod(rec[2]), 0);
    DOUBLES_EQUAL(r["min_thickness_band_mm"][0].get<double>(), std::stod(rec[3]), 0);
    DOUBLES_EQUAL(r["min_thickness_band_mm"][1].get<double>(), std::stod(rec[4]), 0);
    STRCMP_EQUAL(r["reach_date"].is_null() ? "" : r["reach_date"].get<std::string>().c_str(), rec[6].c_str());
  }
  for (size_t i = 0; i < sensors; ++i) {
    const json& s = forecast["sensors"][i];
    const auto& rec = records[1 + rows + i];
    STRCMP_EQUAL("sensor", rec[0].c_str());
    STRCMP_EQUAL(s["id"].get<std::string>().c_str(), rec[1].c_str());
    if (s["ok"].get<bool>()) STRCMP_EQUAL(s["last_time"].get<std::string>().c_str(), rec[9].c_str());
  }
}

// Text with commas, quotes and line breaks (a note) survives a CSV parser whole.
TEST(CsvExport, FieldsThatNeedItAreQuoted) {
  const ordered_json forecast = {{"rows",
                                  {{{"row", "upper, outer"},
                                    {"min_thickness_mm", 31.5},
                                    {"min_thickness_band_mm", {30.1, 33}},
                                    {"note", "said \"x\"\nthen y"}}}},
                                 {"sensors", {{{"id", "1001"}, {"ok", false}, {"note", "no fit"}}}}};
  const auto records = ParseCsv(ForecastCsv(forecast));
  LONGS_EQUAL(3, records.size());
  STRCMP_EQUAL("upper, outer", records[1][1].c_str());
  STRCMP_EQUAL("said \"x\"\nthen y", records[1][11].c_str());
  STRCMP_EQUAL("", records[1][6].c_str());  // no reach date: an empty field
  STRCMP_EQUAL("no fit", records[2][11].c_str());
}
