// Spool: durability across reopen, duplicates, per-sensor order, confirm, full-spool policy,
// device registry.
#include <map>
#include "gateway/spool.hpp"
#include "unit/gateway/gateway_test_support.hpp"

// CppUTest last: its new/delete macros break standard headers included after it.
#include <CppUTest/TestHarness.h>

using lw::gateway::DeviceEntry;
using lw::gateway::InsertOutcome;
using lw::gateway::Spool;
using lw::gateway::SpoolError;
using lw::gateway::SpoolRecord;

namespace {
SpoolRecord Rec(const std::string& sensor, uint32_t seq, bool heartbeat = false) {
  SpoolRecord r;
  r.sensor = sensor;
  r.seq = seq;
  r.received_ms = 1000 + seq;
  r.heartbeat = heartbeat;
  r.payload = "{\"sensor\":\"" + sensor + "\",\"seq\":" + std::to_string(seq) + "}";
  return r;
}
std::vector<uint32_t> Seqs(const std::vector<SpoolRecord>& records, const std::string& sensor) {
  std::vector<uint32_t> out;
  for (const SpoolRecord& r : records) {
    if (r.sensor == sensor) out.push_back(r.seq);
  }
  return out;
}
}  // namespace

TEST_GROUP(Spool) {
  lw::test::TempDirectory dir;
  std::string path() {
    return dir.File("spool.db");
  }
};

TEST(Spool, StoredRecordsSurviveReopen) {
  {
    Spool spool(path(), 100);
    const auto out = spool.Insert({Rec("1001", 1), Rec("1001", 2)});
    CHECK(out == (std::vector<InsertOutcome>{InsertOutcome::kStored, InsertOutcome::kStored}));
    LONGS_EQUAL(2, spool.depth());
  }
  Spool reopened(path(), 100);
  LONGS_EQUAL(2, reopened.depth());
  const auto heads = reopened.Heads(10);
  LONGS_EQUAL(2, heads.size());
  STRCMP_EQUAL("{\"sensor\":\"1001\",\"seq\":2}", heads[1].payload.c_str());
  LONGS_EQUAL(1002, heads[1].received_ms);
}

TEST(Spool, DuplicateIsReportedAndNotStoredTwice) {
  Spool spool(path(), 100);
  spool.Insert({Rec("1001", 7)});
  const auto out = spool.Insert({Rec("1001", 7), Rec("1002", 7)});
  CHECK(out == (std::vector<InsertOutcome>{InsertOutcome::kDuplicate, InsertOutcome::kStored}));
  LONGS_EQUAL(2, spool.depth());
}

TEST(Spool, HeadsAreInSeqOrderPerSensorAndLimited) {
  Spool spool(path(), 100);
  spool.Insert({Rec("2", 5), Rec("1", 9), Rec("2", 3), Rec("1", 8), Rec("2", 4)});
  const auto one = spool.Heads(1);
  LONGS_EQUAL(2, one.size());
  CHECK(Seqs(one, "2") == std::vector<uint32_t>{3});
  CHECK(Seqs(one, "1") == std::vector<uint32_t>{8});
  const auto all = spool.Heads(10);
  CHECK(Seqs(all, "2") == (std::vector<uint32_t>{3, 4, 5}));
  CHECK(Seqs(all, "1") == (std::vector<uint32_t>{8, 9}));
}

TEST(Spool, ConfirmDeletesOnlyNamedRecordsAndReturnsTheirReceiveTimes) {
  Spool spool(path(), 100);
  spool.Insert({Rec("1", 1), Rec("1", 2), Rec("2", 1)});
  const auto received = spool.Confirm("1", {1, 2, 99});
  LONGS_EQUAL(2, received.size());
  LONGS_EQUAL(1001, received[0]);
  LONGS_EQUAL(1, spool.depth());
  CHECK(Seqs(spool.Heads(10), "2") == std::vector<uint32_t>{1});
  LONGS_EQUAL(0, spool.Confirm("1", {1}).size());  // a repeated commit ack is harmless
  LONGS_EQUAL(1, spool.depth());
}

// Commit acks of batches name runs of seqs: each run is deleted in one statement, and only the
// seqs named (unsorted, repeated, with gaps, beyond what is spooled) go.
TEST(Spool, ConfirmOfRunsWithGapsDeletesExactlyTheNamedSeqs) {
  Spool spool(path(), 100);
  std::vector<SpoolRecord> records;
  for (uint32_t seq = 1; seq <= 12; ++seq) records.push_back(Rec("1", seq));
  records.push_back(Rec("2", 4));
  spool.Insert(records);
  const auto received = spool.Confirm("1", {8, 2, 3, 1, 5, 3, 7, 10, 11, 12, 13, 14});
  LONGS_EQUAL(9, received.size());  // 1 2 3 5 7 8 10 11 12 (13, 14 are not spooled; 3 is named twice)
  LONGS_EQUAL(4, spool.depth());
  CHECK(Seqs(spool.Heads(20), "1") == (std::vector<uint32_t>{4, 6, 9}));
  CHECK(Seqs(spool.Heads(20), "2") == std::vector<uint32_t>{4});
}

// A sender's first registry entry is recorded in the transaction of its records.
TEST(Spool, InsertRecordsDevicesInTheSameTransaction) {
  DeviceEntry d;
  d.address = "0013A20040A1B2C3";
  d.sensor = "1001";
  d.first_seen_ms = 5;
  {
    Spool spool(path(), 10);
    std::vector<bool> changed;
    spool.Insert({Rec("1001", 1)}, {}, {d}, &changed);
    CHECK(changed == std::vector<bool>{true});
    spool.Insert({Rec("1001", 2)}, {}, {d}, &changed);
    CHECK(changed == std::vector<bool>{false});  // known: no news
  }
  Spool reopened(path(), 10);
  const auto devices = reopened.Devices();
  LONGS_EQUAL(1, devices.size());
  STRCMP_EQUAL("1001", devices[0].sensor.c_str());
  LONGS_EQUAL(2, reopened.depth());
}

// Several sensors' commit acks in one transaction; the heads of named sensors only.
TEST(Spool, ConfirmOfSeveralSensorsAndHeadsOfSomeSensors) {
  Spool spool(path(), 100);
  spool.Insert({Rec("1", 1), Rec("1", 2), Rec("2", 1), Rec("2", 2), Rec("3", 1)});
  const auto received = spool.Confirm(std::map<std::string, std::vector<uint32_t>>{{"1", {1}}, {"2", {1, 2, 9}}});
  LONGS_EQUAL(3, received.size());
  LONGS_EQUAL(2, spool.depth());
  const auto heads = spool.Heads(10, {"1", "4"});
  LONGS_EQUAL(1, heads.size());
  STRCMP_EQUAL("1", heads[0].sensor.c_str());
  LONGS_EQUAL(2, heads[0].seq);
  CHECK(Seqs(spool.Heads(10), "3") == std::vector<uint32_t>{1});
}

TEST(Spool, FullSpoolGivesUpOldestHeartbeatFirst) {
  Spool spool(path(), 3);
  spool.Insert({Rec("1", 1, false), Rec("1", 2, true), Rec("1", 3, true)});
  const auto out = spool.Insert({Rec("1", 4, false)});
  CHECK(out[0] == InsertOutcome::kStored);
  LONGS_EQUAL(3, spool.depth());
  LONGS_EQUAL(1, spool.evicted());
  CHECK(Seqs(spool.Heads(10), "1") == (std::vector<uint32_t>{1, 3, 4}));
}

TEST(Spool, FullSpoolWithoutHeartbeatsRejectsNewRecords) {
  Spool spool(path(), 2);
  spool.Insert({Rec("1", 1), Rec("1", 2)});
  const auto out = spool.Insert({Rec("1", 3), Rec("1", 2)});
  CHECK(out == (std::vector<InsertOutcome>{InsertOutcome::kRejectedFull, InsertOutcome::kDuplicate}));
  LONGS_EQUAL(2, spool.depth());
  CHECK(Seqs(spool.Heads(10), "1") == (std::vector<uint32_t>{1, 2}));
  spool.Confirm("1", {1});
  CHECK(spool.Insert({Rec("1", 3)})[0] == InsertOutcome::kStored);
}

TEST(Spool, DeviceRegistryRecordsNewsOnly) {
  {
    Spool spool(path(), 10);
    DeviceEntry d;
    d.address = "0013A20040A1B2C3";
    d.sensor = "1001";
    d.first_seen_ms = 5;
    CHECK_TRUE(spool.RecordDevice(d));
    CHECK_FALSE(spool.RecordDevice(d));
    DeviceEntry node;
    node.address = "0013A20040A1B2C3";
    node.node_identifier = "ROW2-A";
    node.device_type = 2;
    CHECK_TRUE(spool.RecordDevice(node));
    node.node_identifier = "ROW2-B";
    CHECK_TRUE(spool.RecordDevice(node));  // renamed: news
  }
  Spool reopened(path(), 10);
  const auto devices = reopened.Devices();
  LONGS_EQUAL(2, devices.size());
  bool found_node = false;
  for (const auto& d : devices) found_node |= d.node_identifier == "ROW2-B";
  CHECK_TRUE(found_node);
}

TEST(Spool, UnopenablePathThrowsNamingTheFile) {
  try {
    Spool spool(dir.File("missing-dir/spool.db"), 10);
    FAIL("expected SpoolError");
  } catch (const SpoolError& e) {
    CHECK(std::string(e.what()).find("missing-dir/spool.db") != std::string::npos);
  }
}

// Issue 16: records released by commit acks are deleted in the transaction that stores the next
// batch, before it, so that a full spool sees the room they make.
TEST(Spool, InsertDeletesTheReleasedRecordsFirstInTheSameTransaction) {
  Spool spool(path(), 2);
  spool.Insert({Rec("1001", 1), Rec("1002", 1)});
  const auto out = spool.Insert({Rec("1001", 2), Rec("1002", 2)}, {{"1001", {1}}, {"1002", {1, 99}}});
  CHECK(out == (std::vector<InsertOutcome>{InsertOutcome::kStored, InsertOutcome::kStored}));
  LONGS_EQUAL(2, spool.depth());
  LONGS_EQUAL(0, spool.evicted());
  Spool reopened(path(), 2);
  const auto heads = reopened.Heads(10);
  CHECK(Seqs(heads, "1001") == std::vector<uint32_t>{2});
  CHECK(Seqs(heads, "1002") == std::vector<uint32_t>{2});
}

TEST(Spool, HeadsLeaveOutSkippedSeqsWhichCountTowardsTheLimit) {
  Spool spool(path(), 100);
  spool.Insert({Rec("1001", 1), Rec("1001", 2), Rec("1001", 3), Rec("1001", 4), Rec("1002", 1)});
  const auto heads = spool.Heads({{"1001", 3}, {"1002", 1}}, {{"1001", {2}}});
  CHECK(Seqs(heads, "1001") == (std::vector<uint32_t>{1, 3}));
  CHECK(Seqs(heads, "1002") == std::vector<uint32_t>{1});
}
