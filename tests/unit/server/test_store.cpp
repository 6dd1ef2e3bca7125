#include <sqlite3.h>
#include <sys/stat.h>

#include <atomic>
#include <chrono>
#include <thread>

#include "server/store.hpp"
#include "support/mosquitto_fixture.hpp"

#include <CppUTest/TestHarness.h>  // last: its leak-detection macros clash with std headers

using lw::server::InsertOutcome;
using lw::server::Store;
using lw::server::StoredReading;

namespace {
StoredReading R(const std::string& sensor, int64_t seq, int64_t t, double mm) {
  StoredReading r;
  r.crusher = "c1";
  r.sensor = sensor;
  r.seq = seq;
  r.time_s = t;
  r.thickness_mm = mm;
  r.loops_intact = static_cast<int64_t>(mm);
  r.received_s = 5;
  r.payload = "{}";
  return r;
}
}  // namespace

TEST_GROUP(Store) {
  lw::test::TempDirectory dir{"lw-store"};
  std::string db() {
    return dir.File("db.sqlite");
  }
};

TEST(Store, RedeliveryIsStoredOnceAndReportedAsDuplicate) {
  Store s(db());
  auto out = s.Commit({R("a", 1, 100, 90), R("a", 2, 200, 89)}, {});
  CHECK(out == std::vector<InsertOutcome>({InsertOutcome::kStored, InsertOutcome::kStored}));
  out = s.Commit({R("a", 2, 200, 89), R("a", 3, 300, 88)}, {});
  CHECK(out == std::vector<InsertOutcome>({InsertOutcome::kDuplicate, InsertOutcome::kStored}));
  LONGS_EQUAL(3, s.CountReadings("c1"));
}

TEST(Store, SameKeyOtherContentIsAConflictAndTheFirstIsKept) {
  Store s(db());
  s.Commit({R("a", 1, 100, 90)}, {});
  const auto out = s.Commit({R("a", 1, 100, 70)}, {});
  CHECK(out[0] == InsertOutcome::kConflict);
  DOUBLES_EQUAL(90, s.All("c1").at(0).thickness_mm, 0);
}

TEST(Store, SurvivesReopenAndKeepsRejectedMessages) {
  {
    Store s(db());
    s.Commit({R("a", 1, 100, 90)}, {{7, "t/x", "garbage", "malformed JSON", "malformed"}});
  }
  Store s(db());
  LONGS_EQUAL(1, s.CountReadings("c1"));
  LONGS_EQUAL(1, s.CountRejected());
  const auto rej = s.RejectedMessages(10);
  STRCMP_EQUAL("garbage", rej.at(0).payload.c_str());
  STRCMP_EQUAL("malformed JSON", rej.at(0).reason.c_str());
}

// A server started on a full disk serves what it has from a read-only Store (docs/server.md, "Disk
// full"): it reads the stored rows, writes nothing (no -wal/-shm file appears), every write throws.
TEST(Store, ReadOnlyOpenReadsWhatIsStoredAndWritesNothing) {
  {
    Store s(db());
    s.Commit({R("a", 1, 100, 90), R("a", 2, 200, 89)}, {{7, "t/x", "garbage", "malformed JSON", "malformed"}});
  }
  std::error_code ec;
  CHECK(!std::filesystem::exists(db() + "-wal", ec) && !std::filesystem::exists(db() + "-shm", ec));
  const auto size = std::filesystem::file_size(db());
  const auto s = Store::OpenReadOnly(db());
  LONGS_EQUAL(2, s->CountReadings("c1"));
  LONGS_EQUAL(1, s->CountRejected());
  LONGS_EQUAL(2, s->Range("c1", "a", 0, 1000, 10, "").readings.size());
  CHECK_THROWS(std::runtime_error, s->Commit({R("a", 3, 300, 88)}, {}));
  LONGS_EQUAL(2, s->CountReadings("c1"));
  CHECK(!std::filesystem::exists(db() + "-wal", ec) && !std::filesystem::exists(db() + "-shm", ec));
  CHECK(std::filesystem::file_size(db()) == size);
  // A file that is not there is not created.
  CHECK_THROWS(std::runtime_error, Store::OpenReadOnly(dir.File("none.sqlite")));
  CHECK(!std::filesystem::exists(dir.File("none.sqlite"), ec));
}

TEST(Store, PagesThroughARangeWithCursorsWithoutGapsOrRepeats) {
  Store s(db());
  std::vector<StoredReading> rs;
  for (int i = 1; i <= 25; ++i) rs.push_back(R("a", i, 1000 + (i / 2) * 10, 120 - i));  // equal times in pairs
  rs.push_back(R("b", 1, 1000, 50));
  s.Commit(rs, {});
  std::vector<int64_t> seen;
  std::string cursor;
  int pages = 0;
  while (true) {
    const auto page = s.Range("c1", "a", 1010, 1100, 4, cursor);
    for (const auto& r : page.readings) seen.push_back(r.seq);
    ++pages;
    if (!page.next_cursor) break;
    cursor = *page.next_cursor;
  }
  // times 1010..1100 are seqs 2..21
  LONGS_EQUAL(20, seen.size());
  for (size_t i = 0; i < seen.size(); ++i) LONGS_EQUAL(static_cast<long>(i + 2), seen[i]);
  LONGS_EQUAL(5, pages);
}

// Store::Range against the definition, computed here from what was committed: the readings of one
// sensor with time in [from, to], ordered by (time, seq), strictly after the cursor's (time, seq),
// at most `limit`, next_cursor naming the last one when more follow; every field as committed
// but the payload, which Range leaves empty (the readings JSON never shows it). Windows starting
// before, inside and after the cursor, pages of 1..7, equal times, other sensors around it.
TEST(Store, RangeIsTheReadingsAfterTheCursorInTheWindowWithEveryFieldButThePayload) {
  Store s(db());
  std::vector<StoredReading> all;
  for (int i = 1; i <= 40; ++i) {
    StoredReading r = R("b", i, 1000 + (i / 3) * 10, 150 - i);  // times in threes
    r.flags = i % 4;
    r.battery_mv = 3000 + i;
    r.received_s = 7000 + i;
    all.push_back(r);
  }
  all.push_back(R("a", 1, 1100, 50));
  all.push_back(R("c", 1, 1100, 50));
  s.Commit(all, {});
  all.resize(40);
  const auto expected = [&](int64_t from, int64_t to, int64_t after_t, int64_t after_seq) {
    std::vector<StoredReading> out;
    for (const StoredReading& r : all) {
      if (r.time_s >= from && r.time_s <= to && (r.time_s > after_t || (r.time_s == after_t && r.seq > after_seq)))
        out.push_back(r);
    }
    return out;  // already in (time, seq) order
  };
  int pages_checked = 0;
  for (const auto& [from, to] : {std::pair<int64_t, int64_t>{0, 5000}, {1030, 1100}, {1035, 1035}, {1040, 1040}, {2000, 3000}}) {
    for (const int limit : {1, 2, 3, 7}) {
      std::string cursor;
      int64_t after_t = INT64_MIN, after_seq = INT64_MIN;
      for (int page_no = 0; page_no < 100; ++page_no) {
        const auto page = s.Range("c1", "b", from, to, limit, cursor);
        const std::vector<StoredReading> left = expected(from, to, after_t, after_seq);
        const size_t n = std::min(left.size(), static_cast<size_t>(limit));
        LONGS_EQUAL(n, page.readings.size());
        for (size_t k = 0; k < n; ++k) {
          const StoredReading &got = page.readings[k], &want = left[k];
          STRCMP_EQUAL("c1", got.crusher.c_str());
          STRCMP_EQUAL("b", got.sensor.c_str());
          LONGS_EQUAL(want.seq, got.seq);
          LONGS_EQUAL(want.time_s, got.time_s);
          DOUBLES_EQUAL(want.thickness_mm, got.thickness_mm, 0);
          LONGS_EQUAL(want.loops_intact, got.loops_intact);
          LONGS_EQUAL(want.flags, got.flags);
          LONGS_EQUAL(want.battery_mv, got.battery_mv);
          LONGS_EQUAL(want.received_s, got.received_s);
          CHECK(got.payload.empty());
        }
        ++pages_checked;
        if (left.size() <= static_cast<size_t>(limit)) {
          CHECK(!page.next_cursor);
          break;
        }
        CHECK(page.next_cursor.has_value());
        STRCMP_EQUAL(lw::server::MakeCursor(left[n - 1].time_s, left[n - 1].seq).c_str(), page.next_cursor->c_str());
        cursor = *page.next_cursor;
        after_t = left[n - 1].time_s;
        after_seq = left[n - 1].seq;
      }
    }
  }
  CHECK(pages_checked > 100);
  // A cursor from before the window (or after it) still reads the window's readings (or none).
  LONGS_EQUAL(expected(1050, 1100, 1000, 1).size(), s.Range("c1", "b", 1050, 1100, 100, "t1000s1").readings.size());
  LONGS_EQUAL(0, s.Range("c1", "b", 1050, 1100, 100, "t1200s1").readings.size());
}

TEST(Store, MalformedCursorIsRefused) {
  Store s(db());
  CHECK_THROWS(std::invalid_argument, s.Range("c1", "a", 0, 10, 5, "t12x"));
  // Finding: std::stoll skips leading blanks and takes a sign, so "t 1s 1" passed as a cursor.
  for (const char* c : {"t 1s 1", "t1s 1", "t+1s1", "t1s+1", "t-s1", "t1s-", "t\t1s1"}) {
    bool refused = false;
    try {
      s.Range("c1", "a", 0, 10, 5, c);
    } catch (const std::invalid_argument&) {
      refused = true;
    }
    CHECK_TEXT(refused, c);
  }
  s.Range("c1", "a", 0, 10, 5, "t-5s3");  // what MakeCursor writes, negative times too
}

TEST(Store, LatestPerSensorIsByTimeWithCounts) {
  Store s(db());
  s.Commit({R("a", 1, 100, 90), R("a", 3, 50, 95), R("b", 1, 10, 60)}, {});
  const auto latest = s.LatestPerSensor("c1");
  LONGS_EQUAL(2, latest.size());
  LONGS_EQUAL(1, latest[0].latest.seq);  // seq 3 is older in time
  LONGS_EQUAL(2, latest[0].count);
  STRCMP_EQUAL("b", latest[1].latest.sensor.c_str());
}

TEST(Store, RefusesADatabaseFromANewerServer) {
  {
    sqlite3* h = nullptr;
    sqlite3_open(db().c_str(), &h);
    sqlite3_exec(h, "PRAGMA user_version=99", nullptr, nullptr, nullptr);
    sqlite3_close(h);
  }
  try {
    Store s(db());
    FAIL("expected a refusal");
  } catch (const std::runtime_error& e) {
    CHECK(std::string(e.what()).find("newer") != std::string::npos);
  }
}

TEST(Store, RefusesAFileThatIsNotADatabase) {
  {
    FILE* f = fopen(db().c_str(), "w");
    fputs("this is not sqlite, but it is long enough to look like a header of something...........", f);
    fclose(f);
  }
  CHECK_THROWS(std::runtime_error, Store(db()));
}

TEST(Store, AReaderConnectionSeesCommitsMadeAfterItsEarlierQueries) {
  Store writer(db());
  Store reader(db());
  writer.Commit({R("a", 1, 100, 90)}, {});
  LONGS_EQUAL(1, reader.CountReadings("c1"));
  LONGS_EQUAL(0, reader.CountRejected());
  LONGS_EQUAL(1, reader.LatestPerSensor("c1").size());
  writer.Commit({R("a", 2, 200, 89), R("b", 1, 200, 70)}, {{1, "t", "p", "r", "malformed"}});
  LONGS_EQUAL(3, reader.CountReadings("c1"));
  LONGS_EQUAL(1, reader.CountRejected());
  LONGS_EQUAL(2, reader.LatestPerSensor("c1").size());
  LONGS_EQUAL(3, reader.All("c1").size());
}

TEST(Store, AResentBadMessageIsQuarantinedOnce) {
  Store s(db());
  s.Commit({}, {{1, "t/a", "garbage", "malformed JSON", "malformed"}});
  s.Commit({}, {{2, "t/a", "garbage", "malformed JSON", "malformed"}, {2, "t/a", "other", "malformed JSON", "malformed"}});
  LONGS_EQUAL(2, s.CountRejected());
}

// Finding: the rejected table had no cap, kept payloads beyond the 64 KiB message limit, and its
// duplicate check compared payloads row by row (10,000 rejected 6 kB readings took 212 s).
TEST(Store, RejectedRowsAreCappedTruncatedAndEvictedOldestFirst) {
  lw::server::RejectedLimits limits;
  limits.max_rows = 50;
  limits.max_bytes = 1 << 20;
  limits.max_payload_bytes = 100;
  Store s(db(), limits);
  std::vector<lw::server::Rejected> batch;
  for (int i = 0; i < 80; ++i)
    batch.push_back({i, "t", "payload " + std::to_string(i) + std::string(300, 'x'), "bad", "malformed"});
  s.Commit({}, batch);
  LONGS_EQUAL(50, s.CountRejected());
  LONGS_EQUAL(30, s.RejectedEvicted());
  const auto newest = s.RejectedMessages(50);
  CHECK(newest.front().payload.rfind("payload 79", 0) == 0);
  CHECK(newest.back().payload.rfind("payload 30", 0) == 0);  // 0..29 went first
  CHECK(newest.front().payload.size() < 160);
  CHECK(newest.front().payload.find("[truncated: 310 bytes]") != std::string::npos);
  // The byte cap holds too, and the eviction count survives a reopen.
  limits.max_rows = 1000;
  limits.max_bytes = 2000;
  {
    Store again(db(), limits);
    again.Commit({}, {{100, "t", std::string(150, 'y'), "bad", "malformed"}});
    CHECK(again.CountRejected() <= 2000 / 100);
    CHECK(again.RejectedEvicted() > 30);
  }
  // A resend of a truncated payload is still recognised (the digest covers the whole payload).
  Store third(db(), limits);
  const int64_t before = third.CountRejected();
  third.Commit({}, {{101, "t", std::string(150, 'y'), "bad", "malformed"}});
  LONGS_EQUAL(before, third.CountRejected());
}

// Finding: the table evicted its oldest rows whatever their kind, so a radio flood of made-up
// sensor ids (20,000 in ~7 s) pushed every earlier quarantined reading out. Now the class holding
// the largest share gives up its oldest row: the flood evicts only itself.
TEST(Store, AFloodOfOneRejectionClassEvictsOnlyItself) {
  lw::server::RejectedLimits limits;
  limits.max_rows = 20;
  limits.max_bytes = 1 << 20;
  Store s(db(), limits);
  std::vector<lw::server::Rejected> genuine;
  for (int i = 0; i < 4; ++i) genuine.push_back({i, "t", "thick " + std::to_string(i), "\"thickness_mm\" 500", "thickness"});
  genuine.push_back({4, "t", "conflicting", "conflict: ...", "conflict"});
  s.Commit({}, genuine);
  std::vector<lw::server::Rejected> flood;
  for (int i = 0; i < 1000; ++i) flood.push_back({10 + i, "t", "fake " + std::to_string(i), "unknown sensor", "unknown_sensor"});
  s.Commit({}, flood);
  LONGS_EQUAL(20, s.CountRejected());
  int kept = 0, fake = 0;
  for (const auto& r : s.RejectedMessages(20)) {
    kept += r.payload.rfind("thick ", 0) == 0 || r.payload == "conflicting";
    fake += r.payload.rfind("fake ", 0) == 0;
  }
  LONGS_EQUAL(5, kept);   // all the earlier rows of other classes
  LONGS_EQUAL(15, fake);  // the flood's newest
  CHECK(s.RejectedMessages(1).front().payload == "fake 999");
  // A class below its share takes room from the largest, after a reopen too (sizes recounted).
  Store again(db(), limits);
  again.Commit({}, {{2000, "t", "late thickness", "\"thickness_mm\" 600", "thickness"}});
  kept = 0;
  for (const auto& r : again.RejectedMessages(20)) kept += r.payload.rfind("thick ", 0) == 0 || r.payload == "late thickness";
  LONGS_EQUAL(5, kept);
  LONGS_EQUAL(20, again.CountRejected());
}

// Finding: a read-only file system gave "unable to open database file" and nothing more. The
// system's reason is now added (here: a folder that does not exist; on a read-only mount it reads
// "Read-only file system").
TEST(Store, AnOpenThatFailsSaysWhy) {
  const std::string path = dir.File("no-such-folder/db.sqlite");
  try {
    Store s(path);
    FAIL("a database in a folder that does not exist was opened");
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    CHECK_TEXT(what.find(path) != std::string::npos, what.c_str());
    CHECK_TEXT(what.find("(No such file or directory)") != std::string::npos, what.c_str());
  }
}

// Finding: a database truncated to 0 bytes was taken as a new one, all history gone, no word said.
TEST(Store, AnEmptyDatabaseFileIsRefusedNotTakenAsNew) {
  FILE* f = fopen(db().c_str(), "w");
  fclose(f);
  try {
    Store s(db());
    FAIL("an empty database file was opened as a new database");
  } catch (const std::runtime_error& e) {
    CHECK(std::string(e.what()).find("empty file (0 bytes)") != std::string::npos);
    CHECK(std::string(e.what()).find(db()) != std::string::npos);
  }
  // A database the server creates itself is still fine.
  std::remove(db().c_str());
  Store created(db());
  LONGS_EQUAL(0, created.CountRejected());
}

// Its cost (once 212 s for one commit) is measured by bench/server/lw_bench_store_rejected, not here.
TEST(Store, TenThousandRejectedReadingsAreStoredOnceWhenCommittedTwice) {
  Store s(db());
  std::vector<lw::server::Rejected> batch;
  for (int i = 0; i < 10000; ++i)
    batch.push_back({i, "", "{\"n\":" + std::to_string(i) + ",\"pad\":\"" + std::string(6000, 'z') + "\"}", "bad", "malformed"});
  s.Commit({}, batch);
  LONGS_EQUAL(10000, s.CountRejected());
  s.Commit({}, batch);  // all duplicates: found through the digest index
  LONGS_EQUAL(10000, s.CountRejected());
}

TEST(Store, ANewDatabaseIsPrivateToItsOwner) {
  Store s(db());
  s.Commit({R("a", 1, 100, 90)}, {});
  for (const std::string suffix : {"", "-wal", "-shm"}) {
    struct stat st {};
    CHECK_EQUAL(0, ::stat((db() + suffix).c_str(), &st));
    LONGS_EQUAL(0, st.st_mode & 077);
  }
}

// A LockedStore hands its store to one caller at a time, and what a call returns is the result.
TEST(Store, ALockedStoreIsUsedByOneThreadAtATime) {
  lw::server::LockedStore shared(std::make_unique<Store>(db()));
  shared.With([](Store& s) { s.Commit({R("a", 1, 100, 90)}, {}); });
  LONGS_EQUAL(1, shared.With([](Store& s) { return s.CountReadings("c1"); }));
  std::atomic<int> inside{0};
  std::atomic<int> overlaps{0};
  std::atomic<int64_t> seq{1};
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&] {
      for (int i = 0; i < 25; ++i) {
        shared.With([&](Store& s) {
          if (inside.fetch_add(1) != 0) ++overlaps;
          s.Commit({R("a", ++seq, 100 + seq, 90)}, {});
          std::this_thread::sleep_for(std::chrono::microseconds(200));
          inside.fetch_sub(1);
        });
      }
    });
  }
  for (auto& t : threads) t.join();
  LONGS_EQUAL(0, overlaps.load());
  LONGS_EQUAL(101, shared.With([](Store& s) { return s.CountReadings("c1"); }));
}

// A version 6 database (campaigns keyed by (crusher, start), no voiding) is upgraded in place to
// version 7: its campaigns are kept as they were, a reline can be voided and a campaign started
// again at the voided one's time.
TEST(Store, AVersion6DatabaseKeepsItsCampaignsAndGainsVoidedRelines) {
  { Store fresh(db()); }
  {
    // The version 7 file turned back into version 6: the tables of both are the same but campaigns'.
    sqlite3* h = nullptr;
    sqlite3_open(db().c_str(), &h);
    const int rc =
        sqlite3_exec(h,
                     "DROP TABLE campaigns;"
                     "CREATE TABLE campaigns (crusher TEXT NOT NULL, start INTEGER NOT NULL, end INTEGER,"
                     " thickness_new_mm REAL NOT NULL, sensors TEXT NOT NULL, final_scan TEXT, final_readings TEXT NOT NULL,"
                     " created INTEGER NOT NULL, PRIMARY KEY (crusher, start));"
                     "INSERT INTO campaigns VALUES('c1', 100, 200, 120, '[]', '0 0 1', '[{\"sensor\":\"a\"}]', 5),"
                     " ('c1', 200, NULL, 125, '[]', NULL, '[]', 6);"
                     "PRAGMA user_version=6;",
                     nullptr, nullptr, nullptr);
    sqlite3_close(h);
    LONGS_EQUAL(SQLITE_OK, rc);
  }
  Store s(db());
  std::vector<lw::server::CampaignRecord> c = s.Campaigns("c1");
  LONGS_EQUAL(2, c.size());
  LONGS_EQUAL(200, c[0].end_s.value_or(0));
  STRCMP_EQUAL("0 0 1", c[0].final_scan.c_str());
  STRCMP_EQUAL("[{\"sensor\":\"a\"}]", c[0].final_readings_json.c_str());
  CHECK_FALSE(c[1].end_s.has_value());
  CHECK(c[0].id > 0 && c[1].id > 0 && c[0].id != c[1].id);
  CHECK_FALSE(c[0].voided_s.has_value() || c[1].voided_s.has_value());
  lw::server::CampaignRecord voided = c[1];
  voided.voided_s = 300;
  voided.voided_by = "ops";
  voided.reline_scan = c[0].final_scan;
  s.VoidReline(voided, c[0].id);
  lw::server::CampaignRecord closed = s.Campaigns("c1")[0], next;
  CHECK_FALSE(closed.end_s.has_value());  // reopened
  CHECK(closed.final_scan.empty());
  closed.end_s = 200;
  next.start_s = 200;
  next.thickness_new_mm = 130;
  next.sensors_json = "[]";
  next.final_readings_json = "[]";
  s.Reline("c1", closed, next);
  c = s.Campaigns("c1");
  LONGS_EQUAL(3, c.size());
  LONGS_EQUAL(300, c[1].voided_s.value_or(0));
  STRCMP_EQUAL("ops", c[1].voided_by.c_str());
  STRCMP_EQUAL("0 0 1", c[1].reline_scan.c_str());
  DOUBLES_EQUAL(125, c[1].thickness_new_mm, 1e-9);
  LONGS_EQUAL(200, c[2].start_s);
  DOUBLES_EQUAL(130, c[2].thickness_new_mm, 1e-9);
  CHECK_FALSE(c[2].end_s.has_value());
  LONGS_EQUAL(200, c[0].end_s.value_or(0));
}

// Version 8 kept a check's opening, NULL where the ring was not supported: on opening it as
// version 9 every check is kept, a stored opening counts as supported and a NULL one as not known.
TEST(Store, AVersion8DatabaseKeepsItsSettingChecksAndMarksTheirSupport) {
  { Store fresh(db()); }
  {
    sqlite3* h = nullptr;
    sqlite3_open(db().c_str(), &h);
    const int rc = sqlite3_exec(h,
                                "DROP TABLE setting_checks;"
                                "CREATE TABLE setting_checks (crusher TEXT NOT NULL, time INTEGER NOT NULL, css_mm REAL NOT NULL,"
                                " opening_mm REAL, by TEXT NOT NULL, note TEXT NOT NULL DEFAULT '', recorded INTEGER NOT NULL,"
                                " PRIMARY KEY (crusher, time));"
                                "INSERT INTO setting_checks VALUES('c1', 100, 131.5, 2.25, 'ops', 'raised', 101),"
                                " ('c1', 200, 128, NULL, 'ops', '', 201);"
                                "PRAGMA user_version=8;",
                                nullptr, nullptr, nullptr);
    sqlite3_close(h);
    LONGS_EQUAL(SQLITE_OK, rc);
  }
  for (int open = 0; open < 2; ++open) {  // and once more as version 9: nothing changes again
    Store s(db());
    const std::vector<lw::server::SettingCheckRecord> c = s.SettingChecks("c1");
    LONGS_EQUAL(2, c.size());
    DOUBLES_EQUAL(131.5, c[0].css_mm, 1e-9);
    DOUBLES_EQUAL(2.25, c[0].opening_mm.value_or(-1), 1e-9);
    CHECK_TRUE(c[0].opening_supported);
    STRCMP_EQUAL("raised", c[0].note.c_str());
    CHECK_FALSE(c[1].opening_mm.has_value());
    CHECK_FALSE(c[1].opening_supported);
    LONGS_EQUAL(201, c[1].recorded_s);
  }
}
