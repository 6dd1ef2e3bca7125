// CSV records as RFC 4180 writes them (core/csv.hpp).
#include "core/csv.hpp"

#include <CppUTest/TestHarness.h>  // last

using namespace lw::core;

TEST_GROUP(Csv){};

TEST(Csv, FieldsAreQuotedOnlyWhenTheyMustBe) {
  STRCMP_EQUAL("plain", CsvField("plain").c_str());
  STRCMP_EQUAL("", CsvField("").c_str());
  STRCMP_EQUAL("2026-03-01T00:00:00Z", CsvField("2026-03-01T00:00:00Z").c_str());
  STRCMP_EQUAL("\"a,b\"", CsvField("a,b").c_str());
  STRCMP_EQUAL("\"say \"\"hi\"\"\"", CsvField("say \"hi\"").c_str());
  STRCMP_EQUAL("\"two\nlines\"", CsvField("two\nlines").c_str());
  STRCMP_EQUAL("\"cr\rhere\"", CsvField("cr\rhere").c_str());
  STRCMP_EQUAL("\" padded \"", CsvField(" padded ").c_str());
}

TEST(Csv, RecordsEndInCrLf) {
  std::string out;
  AppendCsvRecord(&out, {"time", "note"});
  AppendCsvRecord(&out, {"2026-03-01T00:00:00Z", "rate, from \"two\" readings"});
  AppendCsvRecord(&out, {"", ""});
  STRCMP_EQUAL("time,note\r\n2026-03-01T00:00:00Z,\"rate, from \"\"two\"\" readings\"\r\n,\r\n", out.c_str());
}
