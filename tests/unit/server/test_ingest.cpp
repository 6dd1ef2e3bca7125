#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>

#include "core/scan_correction.hpp"
#include "mqtt/messages.hpp"
#include "server/ingest.hpp"
#include "server/wear_service.hpp"
#include "unit/server/server_fixture.hpp"

#include <CppUTest/TestHarness.h>  // last: its leak-detection macros clash with std headers

using namespace lw::server;

namespace {
lw::test::CrusherFolder& Folder() {
  static lw::test::CrusherFolder f(20);
  return f;
}
int64_t Now() {
  return lw::test::LatestReadingS(Folder().bundle) + 3600;
}
Incoming With(const std::string& payload, const std::string& sensor = "1001") {
  return {"site1", Folder().id(), sensor, "linerwatch/v1/site1/" + Folder().id() + "/sensors/" + sensor + "/reading", payload};
}
std::string Reading(const std::string& fields) {
  return R"({"sensor":"1001","seq":5,"time":"2026-01-10T00:00:00Z","thickness_mm":100,"loops_intact":100,"flags":0,"battery_mv":3500)" +
         fields + "}";
}
}  // namespace

TEST_GROUP(Ingest) {
  std::unique_ptr<Registry> registry;
  void setup() override {
    std::vector<std::string> errors;
    registry = Registry::Load(Folder().crushers, &errors);
    CHECK(errors.empty());
  }
  std::string Reject(const Incoming& in) {
    const Validation v = ValidateReading(in, *registry, Now());
    CHECK_FALSE(v.reading.has_value());
    return v.error;
  }
};

TEST(Ingest, AcceptsAWellFormedReading) {
  const Validation v = ValidateReading(With(Reading("")), *registry, Now());
  CHECK_TRUE(v.error.empty());
  CHECK(v.reading.has_value());
  LONGS_EQUAL(5, v.reading->seq);
  DOUBLES_EQUAL(100, v.reading->thickness_mm, 0);
}

TEST(Ingest, RejectsBadInputNamingTheRule) {
  CHECK(Reject(With("{not json")).find("malformed JSON") != std::string::npos);
  CHECK(Reject(With("[1,2]")).find("not a JSON object") != std::string::npos);
  CHECK(Reject(With(R"({"sensor":"9999","seq":1})", "9999")).find("unknown sensor '9999'") != std::string::npos);
  CHECK(Reject(With(Reading(""), "1002")).find("differs from the topic") != std::string::npos);
  CHECK(Reject(With(R"({"sensor":"1001","seq":-1})")).find("\"seq\"") != std::string::npos);
  const std::string base = R"({"sensor":"1001","seq":5,"loops_intact":1,"flags":0,"battery_mv":1,)";
  CHECK(Reject(With(base + R"("time":"2026-01-10T00:00:00Z","thickness_mm":500})")).find("\"thickness_mm\" 500") !=
        std::string::npos);
  CHECK(Reject(With(base + R"("time":"2026-01-10T00:00:00Z","thickness_mm":"ten"})")).find("thickness_mm") != std::string::npos);
  CHECK(Reject(With(base + R"("time":"2019-01-01T00:00:00Z","thickness_mm":100})")).find("before the liner was installed") !=
        std::string::npos);
  CHECK(Reject(With(base + R"("time":"2099-01-01T00:00:00Z","thickness_mm":100})")).find("future") != std::string::npos);
  CHECK(Reject(With(base + R"("time":"yesterday","thickness_mm":100})")).find("ISO-8601") != std::string::npos);
  CHECK(
      Reject(
          With(
              R"({"sensor":"1001","seq":5,"time":"2026-01-10T00:00:00Z","thickness_mm":100,"loops_intact":100,"flags":70000,"battery_mv":3500})"))
          .find("\"flags\" 70000") != std::string::npos);
  CHECK(Reject(With(R"({"sensor":"1001","seq":5,"time":"2026-01-10T00:00:00Z","thickness_mm":100,"loops_intact":100,"flags":0})"))
            .find("missing \"battery_mv\"") != std::string::npos);
  CHECK(Reject(With("{\"a\":" + std::string(20, '[') + std::string(20, ']') + "}")).find("nested deeper") != std::string::npos);
  CHECK(Reject(With(std::string(70 * 1024, ' ') + Reading(""))).find("bytes (at most") != std::string::npos);
  Incoming unknown = With(Reading(""));
  unknown.crusher = "nope";
  CHECK(Reject(unknown).find("unknown crusher 'nope'") != std::string::npos);
}

TEST(Ingest, StoresOnceAcksEveryCommittedOrQuarantinedMessageAndCounts) {
  lw::test::TempDirectory dir{"lw-ingest"};
  Store store(dir.File("db.sqlite"));
  Ingestor ingestor(store, *registry, [] { return Now(); });
  const auto msgs = lw::test::Messages(Folder().bundle);
  const std::vector<Incoming> first(msgs.begin(), msgs.begin() + 50);
  IngestResult r = ingestor.Ingest(first);
  LONGS_EQUAL(50, r.stored);
  LONGS_EQUAL(50, r.new_readings.size());
  size_t acked = 0;
  for (const Ack& a : r.acks) {
    STRCMP_EQUAL("site1", a.site.c_str());
    CHECK(std::is_sorted(a.seqs.begin(), a.seqs.end()));
    acked += a.seqs.size();
  }
  LONGS_EQUAL(50, acked);

  // Redelivery of ten plus one bad message: nothing new stored, all eleven acked.
  std::vector<Incoming> again(msgs.begin() + 40, msgs.begin() + 50);
  again.push_back(With(R"({"sensor":"1001","seq":999,"time":"garbage"})"));
  r = ingestor.Ingest(again);
  LONGS_EQUAL(0, r.stored);
  LONGS_EQUAL(10, r.duplicates);
  LONGS_EQUAL(1, r.rejected);
  acked = 0;
  bool bad_acked = false;
  for (const Ack& a : r.acks) {
    acked += a.seqs.size();
    for (auto s : a.seqs) bad_acked |= (a.sensor == "1001" && s == 999);
  }
  LONGS_EQUAL(11, acked);
  CHECK_TRUE(bad_acked);
  LONGS_EQUAL(50, store.CountReadings(Folder().id()));
  LONGS_EQUAL(1, store.CountRejected());
  const IngestCounters c = ingestor.Counters();
  LONGS_EQUAL(50, c.stored);
  LONGS_EQUAL(10, c.duplicates);
  LONGS_EQUAL(1, c.rejected);
}

// docs/mqtt.md, *Batches*: each record of a batch is validated, stored (or a duplicate, or
// quarantined) and acked on its own, as if it had come alone; a malformed batch is quarantined
// whole and names no seq to ack.
TEST(Ingest, EachRecordOfABatchIsValidatedStoredAndAckedOnItsOwn) {
  lw::test::TempDirectory dir{"lw-ingest"};
  Store store(dir.File("db.sqlite"));
  Ingestor ingestor(store, *registry, [] { return Now(); });
  const auto record = [](int seq, const char* time) {
    return R"({"seq":)" + std::to_string(seq) + R"(,"time":")" + time +
           R"(","thickness_mm":100,"loops_intact":100,"flags":0,"battery_mv":3500})";
  };
  LONGS_EQUAL(1, ingestor.Ingest({With(Reading(""))}).stored);  // seq 5
  const std::string batch = R"({"sensor":"1001","records":[)" + record(5, "2026-01-10T00:00:00Z") + "," +
                            record(6, "2026-01-10T00:10:00Z") + "," + record(7, "yesterday") + R"(,{"sensor":"1002","seq":8}]})";
  const IngestResult r = ingestor.Ingest({With(batch), With(R"({"sensor":"1001","records":[]})")});
  LONGS_EQUAL(1, r.stored);
  LONGS_EQUAL(1, r.duplicates);
  LONGS_EQUAL(3, r.rejected);  // seq 7 (its time), the record of sensor 1002, the empty batch
  LONGS_EQUAL(1, r.acks.size());
  STRCMP_EQUAL("1001", r.acks[0].sensor.c_str());
  CHECK(r.acks[0].seqs == (std::vector<int64_t>{5, 6, 7}));  // not 8: another sensor than the topic's
  LONGS_EQUAL(2, store.CountReadings(Folder().id()));
  LONGS_EQUAL(3, store.CountRejected());
  bool named_time = false, named_topic = false, named_batch = false;
  for (const std::string& line : r.log) {
    named_time |= line.find("ISO-8601") != std::string::npos;
    named_topic |= line.find("payload sensor '1002' differs from the topic's '1001'") != std::string::npos;
    named_batch |= line.find("batch: \"records\" must be an array of 1 to 64 records, not 0 records") != std::string::npos;
  }
  CHECK_TRUE(named_time);
  CHECK_TRUE(named_topic);
  CHECK_TRUE(named_batch);
}

// The server decodes a batch once (mqtt::SplitAndDecodeReadingMessage): what it stores, rejects,
// logs and acks is what the same records sent alone (SplitReadingMessage's texts) give.
TEST(Ingest, ABatchGivesWhatItsRecordsSentAloneGive) {
  const auto record = [](const std::string& seq, const std::string& time, const std::string& more = "") {
    return R"({"seq":)" + seq + R"(, "time":")" + time + R"(", "thickness_mm":99.5, "loops_intact":99, "flags":0,)" +
           R"( "battery_mv":3500)" + more + "}";
  };
  const std::string batch = R"({"sensor":"1001","records":[)" + record("5", "2026-01-10T00:00:00Z") + "," +
                            record("6.0", "2026-01-10T00:10:00Z", R"(, "gateway":"gw\u00e9", "x":1E2)") + "," +
                            record("6", "2026-01-10T00:10:00Z") + "," +                    // a duplicate within the batch
                            record("7", "2026-01-10T00:20:00Z", R"(, "flags":1)") + "," +  // a duplicate key: the last counts
                            record("8", "yesterday") + "," + record("9", "2026-01-10T00:30:00Z", R"(, "sensor":"1002")") +
                            R"(, 5, {"seq": 10}, )" + record("11", "2026-01-10T00:40:00Z", R"(, "battery_mv": 20000)") + "]}";
  std::vector<std::string> texts;
  std::string error;
  CHECK_TEXT(lw::mqtt::SplitReadingMessage(batch, &texts, &error), error.c_str());
  LONGS_EQUAL(9, texts.size());
  lw::test::TempDirectory dir{"lw-ingest"};
  Store batched(dir.File("batched.sqlite")), alone(dir.File("alone.sqlite"));
  Ingestor by_batch(batched, *registry, [] { return Now(); }), one_by_one(alone, *registry, [] { return Now(); });
  const IngestResult a = by_batch.Ingest({With(batch)});
  std::vector<Incoming> singles;
  for (const std::string& t : texts) singles.push_back(With(t));
  const IngestResult b = one_by_one.Ingest(singles);
  LONGS_EQUAL(3, a.stored);  // seqs 5, 6, 7; 6 again is a duplicate
  LONGS_EQUAL(b.stored, a.stored);
  LONGS_EQUAL(1, a.duplicates);
  LONGS_EQUAL(b.duplicates, a.duplicates);
  LONGS_EQUAL(b.conflicts, a.conflicts);
  LONGS_EQUAL(5, a.rejected);
  LONGS_EQUAL(b.rejected, a.rejected);
  CHECK(a.log == b.log);
  LONGS_EQUAL(1, a.acks.size());
  LONGS_EQUAL(b.acks.size(), a.acks.size());
  CHECK(a.acks[0].seqs == b.acks[0].seqs);
  CHECK(a.acks[0].seqs == (std::vector<int64_t>{5, 6, 7, 8, 10, 11}));  // not 9: another sensor's
  LONGS_EQUAL(b.new_readings.size(), a.new_readings.size());
  for (size_t i = 0; i < a.new_readings.size(); ++i) {
    const StoredReading &x = a.new_readings[i], &y = b.new_readings[i];
    CHECK(x.sensor == y.sensor && x.seq == y.seq && x.time_s == y.time_s && x.thickness_mm == y.thickness_mm &&
          x.loops_intact == y.loops_intact && x.flags == y.flags && x.battery_mv == y.battery_mv);
    STRCMP_EQUAL(y.payload.c_str(), x.payload.c_str());
    STRCMP_EQUAL(texts[i == 0 ? 0 : i == 1 ? 1 : 3].c_str(), x.payload.c_str());  // the record's text, as split
  }
  const std::vector<Rejected> ra = batched.RejectedMessages(100), rb = alone.RejectedMessages(100);
  LONGS_EQUAL(rb.size(), ra.size());
  for (size_t i = 0; i < ra.size(); ++i) {
    STRCMP_EQUAL(rb[i].payload.c_str(), ra[i].payload.c_str());
    STRCMP_EQUAL(rb[i].reason.c_str(), ra[i].reason.c_str());
    STRCMP_EQUAL(rb[i].topic.c_str(), ra[i].topic.c_str());
  }
}

TEST(Ingest, RestReadingsAreNotAckedOverMqtt) {
  lw::test::TempDirectory dir{"lw-ingest"};
  Store store(dir.File("db.sqlite"));
  Ingestor ingestor(store, *registry, [] { return Now(); });
  Incoming in = With(Reading(""));
  in.site.clear();
  in.sensor.clear();
  in.topic.clear();
  const IngestResult r = ingestor.Ingest({in});
  LONGS_EQUAL(1, r.stored);
  LONGS_EQUAL(0, r.acks.size());
}

TEST(Ingest, WearFromStoredReadingsEqualsTheOfflineReconstruction) {
  lw::test::TempDirectory dir{"lw-ingest"};
  Store store(dir.File("db.sqlite"));
  Ingestor ingestor(store, *registry, [] { return Now(); });
  ingestor.Ingest(lw::test::Messages(Folder().bundle));
  // The same crusher folder without its scan: the map alone.
  const std::filesystem::path plain = dir.File("plain");
  std::filesystem::create_directories(plain);
  for (const char* f : {"crusher.json", "wear_map.vtk"}) std::filesystem::copy_file(Folder().folder + "/" + f, plain / f);
  const auto crusher = Registry::LoadCrusher(plain);
  const Crusher& c = *crusher;
  CHECK_TRUE(c.scans.empty());
  const CrusherState st = ComputeCrusherState(c, store.All(Folder().id()));
  CHECK_TRUE(st.has_wear);
  const auto& b = Folder().bundle;
  const auto last =
      std::max_element(b.readings.begin(), b.readings.end(), [](const auto& x, const auto& y) { return x.time < y.time; })->time;
  const auto offline = lw::core::Reconstruct(b.crusher, b.map, lw::core::SensorWearAt(b.crusher, b.readings, last));
  DOUBLES_EQUAL(offline.min_thickness_mm, st.reconstruction.min_thickness_mm, 1e-9);
  LONGS_EQUAL(offline.remaining_mm.size(), st.reconstruction.remaining_mm.size());
  DOUBLES_EQUAL(0, (offline.remaining_mm - st.reconstruction.remaining_mm).cwiseAbs().maxCoeff(), 1e-9);
  CHECK(st.scan == nullptr);
  const auto j = WearJson(st, false);
  CHECK_TRUE(j["scan"].is_null());
  STRCMP_EQUAL(c.map.sha256.c_str(), j["map_sha256"].get<std::string>().c_str());
  LONGS_EQUAL(b.crusher.sensors.size(), j["readings_used"].size());
  CHECK_FALSE(j.contains("remaining_mm"));
}

// The crusher folder's laser scan (scans/) corrects live wear between the sensors, as
// `linerwatch reconstruct` does: the same plan, the same numbers; the wear JSON names the scan.
TEST(Ingest, LiveWearAppliesTheLatestScanAsReconstructDoes) {
  lw::test::TempDirectory dir{"lw-ingest"};
  Store store(dir.File("db.sqlite"));
  Ingestor ingestor(store, *registry, [] { return Now(); });
  ingestor.Ingest(lw::test::Messages(Folder().bundle));
  const Crusher& c = *registry->Find(Folder().id());
  const auto& b = Folder().bundle;
  CHECK_FALSE(b.scans.empty());
  LONGS_EQUAL(b.scans.size(), c.scans.size());
  const CrusherState st = ComputeCrusherState(c, store.All(Folder().id()));
  CHECK(st.scan != nullptr);
  CHECK_TRUE(st.scan->correction.detail.empty());
  CHECK(st.scan->correction.faces_corrected > 0);
  const auto last =
      std::max_element(b.readings.begin(), b.readings.end(), [](const auto& x, const auto& y) { return x.time < y.time; })->time;
  const lw::core::Scan* scan = lw::core::LatestScanAt(b.scans, lw::core::TimePoint::max());
  CHECK(scan != nullptr);
  const lw::core::Reconstruction unscanned = lw::core::Reconstruct(lw::core::PrepareReconstruction(b.crusher, b.map),
                                                                   lw::core::SensorWearAt(b.crusher, b.readings, last));
  const lw::core::Reconstruction scanned = lw::test::OfflineLiveWear(b, last);
  DOUBLES_EQUAL(scanned.min_thickness_mm, st.reconstruction.min_thickness_mm, 1e-9);
  DOUBLES_EQUAL(0, (scanned.remaining_mm - st.reconstruction.remaining_mm).cwiseAbs().maxCoeff(), 1e-9);
  // The scan moved the live map (else this test could not tell the two apart).
  CHECK((unscanned.remaining_mm - st.reconstruction.remaining_mm).cwiseAbs().maxCoeff() > 0.5);
  const auto j = WearJson(st, false);
  STRCMP_EQUAL(scan->file.c_str(), j["scan"]["file"].get<std::string>().c_str());
  CHECK_TRUE(j["scan"]["applied"].get<bool>());
  // Cached: the same readings give the same corrected plan, not a new one.
  CHECK(ComputeCrusherState(c, store.All(Folder().id())).scan == st.scan);
}

TEST(Ingest, FaultReadingsAreStoredButNotUsedForWear) {
  lw::test::TempDirectory dir{"lw-ingest"};
  Store store(dir.File("db.sqlite"));
  Ingestor ingestor(store, *registry, [] { return Now(); });
  ingestor.Ingest(lw::test::Messages(Folder().bundle));
  const Crusher& c = *registry->Find(Folder().id());
  const double before = ComputeCrusherState(c, store.All(Folder().id())).reconstruction.min_thickness_mm;
  // An all-open reading (flag bit 3) of 0 mm after everything else while the board still holds
  // loops intact: a cut cable, not wear (with no loop intact it would be a consumed sensor: wear).
  const std::string t = lw::core::FormatIsoTime(lw::core::TimePoint(std::chrono::seconds(Now() - 60)));
  const IngestResult r = ingestor.Ingest({With(R"({"sensor":"1001","seq":100000,"time":")" + t +
                                               R"(","thickness_mm":0,"loops_intact":42,"flags":8,"battery_mv":3500})")});
  LONGS_EQUAL(1, r.stored);
  const double after = ComputeCrusherState(c, store.All(Folder().id())).reconstruction.min_thickness_mm;
  DOUBLES_EQUAL(before, after, 1e-12);
}

TEST(Ingest, AConsumedSensorIsWearACutCableIsNot) {
  // every loop open with none intact: the ladder is worn through (firmware: "consumed")
  CHECK_FALSE(IsFaultReading(1 << 3, 0));
  // every loop open while the board still holds loops intact: a cut cable
  CHECK_TRUE(IsFaultReading(1 << 3, 42));
  CHECK_TRUE(IsFaultReading(1 << 4, 42));   // SPI stuck
  CHECK_FALSE(IsFaultReading(1 << 0, 42));  // heartbeat
}

// Finding: a number that overflows a double threw out of the JSON parser and failed the whole
// batch (nothing stored, nothing acked). Now that message alone is quarantined and acked.
TEST(Ingest, AnOverflowingNumberQuarantinesThatMessageOnly) {
  lw::test::TempDirectory dir{"lw-ingest"};
  Store store(dir.File("db.sqlite"));
  Ingestor ingestor(store, *registry, [] { return Now(); });
  const auto msgs = lw::test::Messages(Folder().bundle);
  std::vector<Incoming> batch(msgs.begin(), msgs.begin() + 20);
  batch.insert(
      batch.begin() + 10,
      With(
          R"({"sensor":"1001","seq":777,"time":"2026-01-10T00:00:00Z","thickness_mm":100,"loops_intact":100,"flags":1e999,"battery_mv":3500})"));
  IngestResult r;
  try {
    r = ingestor.Ingest(batch);
  } catch (const std::exception& e) {
    FAIL(e.what());
  }
  LONGS_EQUAL(20, r.stored);
  LONGS_EQUAL(1, r.rejected);
  bool acked = false;
  for (const Ack& a : r.acks) acked |= a.sensor == "1001" && std::count(a.seqs.begin(), a.seqs.end(), 777) == 1;
  CHECK_TRUE(acked);
  // An overflowing seq identifies nothing: quarantined, but no seq (0 or other) is acknowledged.
  r = ingestor.Ingest({With(
      R"({"sensor":"1001","seq":1e999,"time":"2026-01-10T00:00:00Z","thickness_mm":100,"loops_intact":100,"flags":0,"battery_mv":3500})")});
  LONGS_EQUAL(1, r.rejected);
  LONGS_EQUAL(0, r.acks.size());
  const std::string reason = Reject(batch[10]);
  CHECK_TEXT(reason.find("\"flags\"") != std::string::npos, reason.c_str());
  CHECK(reason.find("1e999") != std::string::npos);
  LONGS_EQUAL(2, store.CountRejected());
}

// Finding: readings were keyed (crusher, sensor, seq) and the topic's site ignored, so a reading
// forged under another site with a future seq was kept and the genuine one acked as a conflict
// (and dropped from the gateway's spool). A crusher now belongs to one site.
TEST(Ingest, AReadingUnderAnotherSiteIsQuarantinedNotAckedAndTheGenuineOneIsStored) {
  lw::test::TempDirectory dir{"lw-ingest"};
  const auto msgs = lw::test::Messages(Folder().bundle);
  {
    Store store(dir.File("db.sqlite"));
    Ingestor ingestor(store, *registry, [] { return Now(); });
    IngestResult r = ingestor.Ingest({msgs[0]});  // binds the crusher to site1, the first site heard
    LONGS_EQUAL(1, r.stored);
    CHECK(ingestor.SiteOf(Folder().id()) == std::optional<std::string>("site1"));
  }
  // After a restart (new Store and Ingestor on the same file) the binding holds.
  Store store(dir.File("db.sqlite"));
  Ingestor ingestor(store, *registry, [] { return Now(); });
  CHECK(ingestor.SiteOf(Folder().id()) == std::optional<std::string>("site1"));
  const Incoming genuine = msgs[1];
  Incoming forged = lw::test::Messages(Folder().bundle, "evil")[1];
  forged.payload.replace(forged.payload.find("\"thickness_mm\":"), 15, "\"thickness_mm\":1,\"x\":");
  IngestResult r = ingestor.Ingest({forged});
  LONGS_EQUAL(0, r.stored);
  LONGS_EQUAL(1, r.rejected);
  LONGS_EQUAL(0, r.acks.size());  // the forger's gateway is not told anything was committed
  CHECK(r.log.at(0).find("is not crusher") != std::string::npos);
  r = ingestor.Ingest({genuine});
  LONGS_EQUAL(1, r.stored);
  LONGS_EQUAL(0, r.conflicts);
  LONGS_EQUAL(1, r.acks.size());
  STRCMP_EQUAL("site1", r.acks[0].site.c_str());
}

TEST(Ingest, CrusherJsonSiteBindsBeforeAnyReading) {
  lw::test::CrusherFolder folder(5, 3);
  std::string json(std::filesystem::file_size(folder.folder + "/crusher.json"), '\0');
  FILE* f = std::fopen((folder.folder + "/crusher.json").c_str(), "rb");
  CHECK(f != nullptr && std::fread(json.data(), 1, json.size(), f) == json.size());
  std::fclose(f);
  json.insert(json.find('{') + 1, "\"site\": \"plant\", ");
  f = std::fopen((folder.folder + "/crusher.json").c_str(), "wb");
  std::fwrite(json.data(), 1, json.size(), f);
  std::fclose(f);
  std::vector<std::string> errors;
  const auto reg = Registry::Load(folder.crushers, &errors);
  CHECK_TEXT(errors.empty(), errors.empty() ? "" : errors[0].c_str());
  lw::test::TempDirectory dir{"lw-ingest"};
  Store store(dir.File("db.sqlite"));
  Ingestor ingestor(store, *reg, [&] { return lw::test::LatestReadingS(folder.bundle); });
  IngestResult r = ingestor.Ingest({lw::test::Messages(folder.bundle, "site1")[0]});
  LONGS_EQUAL(0, r.stored);
  LONGS_EQUAL(0, r.acks.size());
  r = ingestor.Ingest({lw::test::Messages(folder.bundle, "plant")[0]});
  LONGS_EQUAL(1, r.stored);
  STRCMP_EQUAL("plant", r.acks.at(0).site.c_str());
}

// docs/mqtt.md, *Batches*: a batch that does not parse as JSON as a whole (here a number in one
// record overflows a double) is judged as one message: quarantined, nothing stored, nothing acked
// (no seq), so the gateway republishes its records one per message, and then each is judged alone:
// the good ones stored, the overflowing one quarantined and acked. Nothing is lost either way.
TEST(Ingest, ABatchWithAnOverflowingNumberIsQuarantinedWholeAndItsRecordsAloneAreJudgedAlone) {
  lw::test::TempDirectory dir{"lw-ingest"};
  Store store(dir.File("db.sqlite"));
  Ingestor ingestor(store, *registry, [] { return Now(); });
  const auto record = [](int seq, const char* flags) {
    return R"({"sensor":"1001","seq":)" + std::to_string(seq) +
           R"(,"time":"2026-01-10T00:00:00Z","thickness_mm":100,"loops_intact":100,"flags":)" + flags + R"(,"battery_mv":3500})";
  };
  const std::string batch =
      R"({"records":[)" + record(5, "0") + "," + record(6, "1e999") + "," + record(7, "0") + R"(],"sensor":"1001"})";
  IngestResult r = ingestor.Ingest({With(batch)});
  LONGS_EQUAL(0, r.stored);
  LONGS_EQUAL(1, r.rejected);
  LONGS_EQUAL(0, r.acks.size());
  CHECK(r.log.back().find("1e999") != std::string::npos);
  // The gateway's republication, one record per message.
  r = ingestor.Ingest({With(record(5, "0")), With(record(6, "1e999")), With(record(7, "0"))});
  LONGS_EQUAL(2, r.stored);
  LONGS_EQUAL(1, r.rejected);
  LONGS_EQUAL(1, r.acks.size());
  CHECK(r.acks[0].seqs == (std::vector<int64_t>{5, 6, 7}));
  LONGS_EQUAL(2, store.CountReadings(Folder().id()));
}

// Hostile batches: a seq twice in one batch (the same record, then another thickness), elements
// that are no records at all (a number, a string, an array, a batch inside the batch), a record of
// another sensor. Each element is judged alone: one stored, its repetitions a duplicate and a
// conflict (acked, the first kept), the rest quarantined; only the topic sensor's seqs are acked.
TEST(Ingest, HostileElementsOfABatchAreEachJudgedAloneAndNothingElseIsAcked) {
  lw::test::TempDirectory dir{"lw-ingest"};
  Store store(dir.File("db.sqlite"));
  Ingestor ingestor(store, *registry, [] { return Now(); });
  const auto record = [](int seq, int thickness) {
    return R"({"seq":)" + std::to_string(seq) + R"(,"time":"2026-01-10T00:00:00Z","thickness_mm":)" + std::to_string(thickness) +
           R"(,"loops_intact":100,"flags":0,"battery_mv":3500})";
  };
  const std::string inner = R"({"records":[)" + record(9, 100) + R"(],"sensor":"1001"})";
  const std::string batch = R"({"records":[)" + record(5, 100) + "," + record(5, 100) + "," + record(5, 90) +
                            R"(,7,"text",[1,2],)" + inner +
                            R"(,{"sensor":"1002","seq":6,"time":"2026-01-10T00:00:00Z","thickness_mm":100}],"sensor":"1001"})";
  const IngestResult r = ingestor.Ingest({With(batch)});
  LONGS_EQUAL(1, r.stored);
  LONGS_EQUAL(1, r.duplicates);
  LONGS_EQUAL(1, r.conflicts);
  LONGS_EQUAL(5, r.rejected);
  LONGS_EQUAL(1, r.acks.size());
  STRCMP_EQUAL("1001", r.acks[0].sensor.c_str());
  CHECK(r.acks[0].seqs == (std::vector<int64_t>{5}));  // not 6 (sensor 1002), not 9 (a batch in a batch)
  LONGS_EQUAL(1, store.CountReadings(Folder().id()));
  const Page page = store.Range(Folder().id(), "1001", 0, std::numeric_limits<int64_t>::max(), 10, "");
  LONGS_EQUAL(1, page.readings.size());
  DOUBLES_EQUAL(100, page.readings[0].thickness_mm, 0);  // the first of seq 5 is kept
  // The conflicting one is quarantined with the refused elements, not lost.
  LONGS_EQUAL(6, store.CountRejected());
  int conflicts = 0;
  for (const Rejected& q : store.RejectedMessages(10))
    if (q.reason.find("conflict") != std::string::npos && q.payload.find("\"thickness_mm\":90") != std::string::npos) ++conflicts;
  LONGS_EQUAL(1, conflicts);
  ingestor.Ingest({With(batch)});  // redelivered: quarantined once
  LONGS_EQUAL(6, store.CountRejected());
}

namespace {
std::string At(int64_t t_s, int seq, double mm) {
  return R"({"sensor":"1001","seq":)" + std::to_string(seq) + R"(,"time":")" +
         lw::core::FormatIsoTime(lw::core::TimePoint(std::chrono::seconds(t_s))) + R"(","thickness_mm":)" + std::to_string(mm) +
         R"(,"loops_intact":100,"flags":0,"battery_mv":3500})";
}
bool Acked(const IngestResult& r, int64_t seq) {
  for (const Ack& a : r.acks)
    if (std::find(a.seqs.begin(), a.seqs.end(), seq) != a.seqs.end()) return true;
  return false;
}
}  // namespace

// Finding: a reading stamped up to a day ahead was stored and became its sensor's latest, hiding
// the later genuine ones (a 5 mm reading at now + 23.9 h hid the genuine 100 mm). Now a reading
// more than 5 min ahead of the server's clock is held: not stored, not quarantined, not acked, so
// its gateway keeps it and publishes it again; once the clock reaches it, it is stored and acked.
TEST(Ingest, AReadingAheadOfTheServersClockIsHeldUntilTheClockReachesIt) {
  lw::test::TempDirectory dir{"lw-ingest"};
  Store store(dir.File("db.sqlite"));
  int64_t now = Now();
  Ingestor ingestor(store, *registry, [&] { return now; });
  const int64_t ahead = now + 86040;  // 23.9 h
  IngestResult r = ingestor.Ingest({With(At(ahead, 901, 5))});
  LONGS_EQUAL(0, r.stored);
  LONGS_EQUAL(0, r.rejected);
  CHECK_FALSE(Acked(r, 901));
  LONGS_EQUAL(0, store.CountRejected());
  CHECK(r.log.at(0).rfind("held ", 0) == 0);
  CHECK(r.log.at(0).find("after the server's clock") != std::string::npos);
  // Within the slack (a gateway's clock a little ahead) is stored as before.
  r = ingestor.Ingest({With(At(now + kFutureSlackS, 899, 100)), With(At(now + kFutureSlackS + 1, 900, 100))});
  LONGS_EQUAL(1, r.stored);
  CHECK(Acked(r, 899));
  CHECK_FALSE(Acked(r, 900));
  // The genuine reading is the sensor's latest, not the one from the future.
  for (const auto& s : store.LatestPerSensor(Folder().id()))
    if (s.latest.sensor == "1001") DOUBLES_EQUAL(100, s.latest.thickness_mm, 0);
  LONGS_EQUAL(2, ingestor.Counters().held);
  LONGS_EQUAL(2, ingestor.Counters().held_by_reason.at("future"));
  // The gateway's republication once the server's clock has caught up: stored and acked.
  now = ahead - kFutureSlackS;
  r = ingestor.Ingest({With(At(ahead, 901, 5))});
  LONGS_EQUAL(1, r.stored);
  CHECK(Acked(r, 901));
  // More than a day ahead is still refused (quarantined and acked): that clock is broken.
  r = ingestor.Ingest({With(At(now + 2 * 86400, 902, 90))});
  LONGS_EQUAL(1, r.rejected);
  CHECK(Acked(r, 902));
}

// Finding: a reading for an unknown crusher (a --crusher typo, a folder that failed to load) was
// quarantined and acked, so its gateway deleted it. Now it is held, and stored once a folder of
// that id loads (the gateway still has it). Per-crusher counters do not grow for made-up ids.
TEST(Ingest, AReadingForAnUnknownCrusherIsHeldAndStoredOnceItsFolderLoads) {
  lw::test::TempDirectory dir{"lw-ingest"};
  Store store(dir.File("db.sqlite"));
  Incoming late = With(Reading(""));
  late.crusher = "late";
  late.topic = "linerwatch/v1/site1/late/sensors/1001/reading";
  {
    Ingestor ingestor(store, *registry, [] { return Now(); });
    const IngestResult r = ingestor.Ingest({late});
    LONGS_EQUAL(0, r.stored);
    LONGS_EQUAL(0, r.rejected);
    LONGS_EQUAL(1, r.held);
    LONGS_EQUAL(0, r.acks.size());
    LONGS_EQUAL(0, store.CountRejected());
    CHECK(r.log.at(0).find("unknown crusher 'late'") != std::string::npos);
    LONGS_EQUAL(0, ingestor.CrusherCounters("late").held);
  }
  // The folder is fixed (here: a copy of the fixture's under the id "late") and the server restarts.
  lw::test::TempDirectory crushers{"lw-ingest-crushers"};
  std::filesystem::copy(Folder().folder, crushers.File("late"), std::filesystem::copy_options::recursive);
  const std::string json_path = crushers.File("late") + "/crusher.json";
  nlohmann::json j = nlohmann::json::parse(std::ifstream(json_path));
  j["crusher_id"] = "late";
  std::ofstream(json_path) << j.dump(2);
  std::vector<std::string> errors;
  const auto fixed = Registry::Load(crushers.path(), &errors);
  CHECK_TEXT(errors.empty(), errors.empty() ? "" : errors[0].c_str());
  Ingestor ingestor(store, *fixed, [] { return Now(); });
  const IngestResult r = ingestor.Ingest({late});
  LONGS_EQUAL(1, r.stored);
  CHECK(Acked(r, 5));
}

namespace {
/// Folder()'s crusher plus a copy of it as crusher `named` with "site": `site` in its crusher.json.
std::unique_ptr<Registry> WithANamedSite(lw::test::TempDirectory& dir, const std::string& named, const std::string& site) {
  std::filesystem::copy(Folder().folder, dir.File("demo"), std::filesystem::copy_options::recursive);
  std::filesystem::copy(Folder().folder, dir.File(named), std::filesystem::copy_options::recursive);
  const std::string json_path = dir.File(named) + "/crusher.json";
  nlohmann::json j = nlohmann::json::parse(std::ifstream(json_path));
  j["crusher_id"] = named;
  j["site"] = site;
  std::ofstream(json_path) << j.dump(2);
  std::vector<std::string> errors;
  auto registry = Registry::Load(dir.path(), &errors);
  CHECK_TEXT(errors.empty(), errors.empty() ? "" : errors[0].c_str());
  return registry;
}
}  // namespace

// Finding: a crusher without "site" was bound for good to whichever site spoke first, so another
// site's gateway account could take it and the genuine site's readings were never acked. On a
// server whose other crushers name their site, such a crusher now binds to none: its readings are
// held (not stored, not acked), the server says what to add, and a binding learnt before is dropped.
TEST(Ingest, OnAServerWithNamedSitesACrusherWithoutSiteBindsToNoSite) {
  lw::test::TempDirectory crushers{"lw-ingest-crushers"};
  const auto reg = WithANamedSite(crushers, "plant-crusher", "plant");
  lw::test::TempDirectory dir{"lw-ingest"};
  Store store(dir.File("db.sqlite"));
  store.Commit({}, {}, {{Folder().id(), "evil"}});  // a binding learnt from a first reading before
  Ingestor ingestor(store, *reg, [] { return Now(); });
  CHECK_FALSE(ingestor.SiteOf(Folder().id()).has_value());
  LONGS_EQUAL(1, ingestor.Warnings().size());
  CHECK(ingestor.Warnings()[0].find("crusher " + Folder().id() + " has no \"site\"") == 0);
  CHECK(ingestor.Warnings()[0].find("first heard from 'evil'") != std::string::npos);
  for (const std::string site : {"evil", "site1"}) {
    const IngestResult r = ingestor.Ingest({lw::test::Messages(Folder().bundle, site)[0]});
    LONGS_EQUAL(0, r.stored);
    LONGS_EQUAL(1, r.held);
    LONGS_EQUAL(0, r.acks.size());
    CHECK(r.log.at(0).find("add \"site\": \"" + site + "\"") != std::string::npos);
  }
  CHECK_FALSE(ingestor.SiteOf(Folder().id()).has_value());  // nothing bound it
  LONGS_EQUAL(0, store.CountReadings(Folder().id()));
  LONGS_EQUAL(2, ingestor.Counters().held_by_reason.at("no_site"));
  // The named crusher works as before; REST (no site) stores for either.
  Incoming named = lw::test::Messages(Folder().bundle, "plant")[0];
  named.crusher = "plant-crusher";
  LONGS_EQUAL(1, ingestor.Ingest({named}).stored);
  Incoming rest = lw::test::Messages(Folder().bundle)[1];
  rest.site = "";
  LONGS_EQUAL(1, ingestor.Ingest({rest}).stored);
}

// The single-site case (data/dem's crusher.json files have no "site"): no crusher names a site,
// so the first site heard binds, as before, with no warning.
TEST(Ingest, WithoutNamedSitesTheFirstSiteHeardStillBinds) {
  lw::test::TempDirectory dir{"lw-ingest"};
  Store store(dir.File("db.sqlite"));
  Ingestor ingestor(store, *registry, [] { return Now(); });
  CHECK(ingestor.Warnings().empty());
  LONGS_EQUAL(1, ingestor.Ingest({lw::test::Messages(Folder().bundle, "site1")[0]}).stored);
  CHECK(ingestor.SiteOf(Folder().id()) == std::optional<std::string>("site1"));
}
