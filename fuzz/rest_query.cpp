// REST query parsing and paging (GET /api/v1/crushers/{id}/sensors/{sensor}/readings): a raw query
// string decoded the way the server's HTTP layer decodes it (cpp-httplib), server::ParseReadingsQuery,
// then Store::Range page by page over 60 stored readings of the fixture crusher, following
// next_cursor.
// Properties: parsing never throws; an accepted query has limit in [1, 5000] and a cursor that
// ParseCursor reads; Range does not throw on it; pages hold at most `limit` readings inside
// [from, to], strictly after the cursor, in (time, seq) order; paging ends; every cursor the server
// issues reads back to the last reading of its page.
#include "fuzz_fixture.hpp"
#include "server/ingest.hpp"
#include "server/query.hpp"
#include "server/store.hpp"

// After the project headers: cpp-httplib before Eigen's headers breaks them under clang 14.
#include <httplib.h>

#include <memory>
#include <string>

using namespace lw;
using lw::fuzz::Check;

namespace {

server::Store& FixtureStore() {
  static const std::unique_ptr<server::Store> store = [] {
    auto s = std::make_unique<server::Store>(":memory:");
    server::Ingestor ingestor(*s, fuzz::FixtureRegistry(), [] { return fuzz::kNowS; });
    std::vector<server::Incoming> batch;
    for (int i = 0; i < 60; ++i) {
      // Ten readings share each time stamp (1 s apart otherwise), so paging must order by seq too.
      const std::string time = "2026-02-01T00:00:0" + std::to_string(i / 10) + "Z";
      batch.push_back({"site1", "fz1", "1001", "t",
                       R"({"sensor":"1001","seq":)" + std::to_string(1000 - i) + R"(,"time":")" + time +
                           R"(","thickness_mm":100,"loops_intact":100,"flags":0,"battery_mv":3500})"});
    }
    const server::IngestResult r = ingestor.Ingest(batch);
    if (r.stored != 60) fuzz::Fail("fixture readings not stored");
    return s;
  }();
  return *store;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string query(reinterpret_cast<const char*>(data), size);
  httplib::Params params;
  httplib::detail::parse_query_text(query, params);
  std::string error;
  const auto q = server::ParseReadingsQuery(params, &error);
  if (!q) {
    Check(!error.empty(), "a refused query without a reason");
    return 0;
  }
  Check(q->limit >= 1 && q->limit <= 5000, "limit outside [1, 5000] accepted");
  int64_t after_t = INT64_MIN, after_seq = INT64_MIN;
  if (!q->cursor.empty()) server::ParseCursor(q->cursor, &after_t, &after_seq);  // accepted: must read

  server::Store& store = FixtureStore();
  std::string cursor = q->cursor;
  for (int page_no = 0;; ++page_no) {
    Check(page_no <= 61, "paging does not end");
    const server::Page page = store.Range("fz1", "1001", q->from_s, q->to_s, q->limit, cursor);
    Check(page.readings.size() <= static_cast<size_t>(q->limit), "a page holds more than limit readings");
    for (const server::StoredReading& r : page.readings) {
      Check(r.time_s >= q->from_s && r.time_s <= q->to_s, "a reading outside [from, to]");
      Check(r.time_s > after_t || (r.time_s == after_t && r.seq > after_seq), "a reading not after the cursor");
      after_t = r.time_s;
      after_seq = r.seq;
    }
    if (!page.next_cursor) break;
    Check(!page.readings.empty(), "a next_cursor after an empty page");
    int64_t t = 0, s = 0;
    server::ParseCursor(*page.next_cursor, &t, &s);
    Check(t == after_t && s == after_seq, "next_cursor does not name the page's last reading");
    cursor = *page.next_cursor;
  }
  return 0;
}
