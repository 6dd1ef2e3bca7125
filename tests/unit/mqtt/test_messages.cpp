// Messages of docs/mqtt.md: every codec round-trips, encodes the bytes the gateway and the server
// have always sent, and refuses malformed messages with a reason.
#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "mqtt/messages.hpp"

// CppUTest last: its new/delete macros break standard headers included after it.
#include <CppUTest/TestHarness.h>

using nlohmann::json;
namespace mq = lw::mqtt;

namespace {

mq::ReadingMessage FullReading() {
  mq::ReadingMessage r;
  r.sensor = "1001";
  r.seq = 42;
  r.time = "2026-03-01T12:00:00Z";
  r.thickness_mm = 87.3;
  r.loops_intact = 87;
  r.flags = 0x41;
  r.battery_mv = 3550;
  r.temperature_c = -5;
  r.ladder_loops = 12;
  r.loop_bitmap = "ab0f";
  r.dropped_total = 3;
  r.address = "0013A20040A1B2C3";
  r.gateway = "gw-1";
  r.received = "2026-03-01T12:00:07Z";
  return r;
}

}  // namespace

TEST_GROUP(Messages){};

TEST(Messages, IsoUtcFormatsUnixMilliseconds) {
  STRCMP_EQUAL("1970-01-01T00:00:00Z", mq::IsoUtc(0).c_str());
  STRCMP_EQUAL("2026-03-01T12:00:07Z", mq::IsoUtc(1772366407123).c_str());
  STRCMP_EQUAL("1969-12-31T23:59:59Z", mq::IsoUtc(-1).c_str());
}

TEST(Messages, AddressIsSixteenUpperCaseHexDigits) {
  STRCMP_EQUAL("0013A20040A1B2C3", mq::AddressHex(0x0013A20040A1B2C3ull).c_str());
}

TEST(Messages, FlagNamesLowestBitFirst) {
  CHECK(mq::FlagNames(0x41) == (std::vector<std::string>{"heartbeat", "low_battery"}));
  CHECK(mq::FlagNames(0x8200) == (std::vector<std::string>{"dropped", "bit15"}));
  CHECK(mq::FlagNames(0).empty());
}

// ---- reading ----

TEST(Messages, ReadingEncodesTheBytesTheGatewayAlwaysSent) {
  // The gateway's ReadingJson before lw::mqtt existed, for the same record.
  STRCMP_EQUAL(R"({"address":"0013A20040A1B2C3","battery_mv":3550,"dropped_total":3,"flag_names":["heartbeat","low_battery"],)"
               R"("flags":65,"gateway":"gw-1","ladder_loops":12,"loop_bitmap":"ab0f","loops_intact":87,)"
               R"("received":"2026-03-01T12:00:07Z","sensor":"1001","seq":42,"temperature_c":-5,"thickness_mm":87.3,)"
               R"("time":"2026-03-01T12:00:00Z"})",
               mq::EncodeReading(FullReading()).c_str());
}

TEST(Messages, ReadingRoundTrips) {
  std::string error;
  const auto full = mq::DecodeReading(mq::EncodeReading(FullReading()), &error);
  CHECK_TEXT(full.has_value(), error.c_str());
  CHECK(*full == FullReading());
  // Only the required fields: the optional ones stay absent.
  mq::ReadingMessage bare;
  bare.sensor = "7";
  bare.seq = 4294967295u;
  bare.time = "2026-01-01T00:00:00Z";
  bare.thickness_mm = 0.5;
  bare.flags = 0xFFFF;
  const auto back = mq::DecodeReading(mq::EncodeReading(bare), &error);
  CHECK_TEXT(back.has_value(), error.c_str());
  CHECK(*back == bare);
  CHECK_FALSE(json::parse(mq::EncodeReading(bare)).contains("address"));
}

TEST(Messages, ReadingDecoderIgnoresUnknownFieldsAndNamesWhatIsWrong) {
  std::string error;
  CHECK(mq::DecodeReading(
            R"({"sensor":1001,"seq":1,"time":"t","thickness_mm":9,"loops_intact":9,"flags":0,"battery_mv":1,"new":[1]})", &error)
            ->sensor == "1001");
  CHECK_FALSE(
      mq::DecodeReading(R"({"sensor":"1","time":"t","thickness_mm":9,"loops_intact":9,"flags":0,"battery_mv":1})", &error));
  STRCMP_EQUAL("missing \"seq\"", error.c_str());
  CHECK_FALSE(mq::DecodeReading(
      R"({"sensor":"1","seq":-1,"time":"t","thickness_mm":9,"loops_intact":9,"flags":0,"battery_mv":1})", &error));
  STRCMP_EQUAL("\"seq\" -1 is outside [0, 4294967295]", error.c_str());
  CHECK_FALSE(mq::DecodeReading(
      R"({"sensor":"1","seq":1.5,"time":"t","thickness_mm":9,"loops_intact":9,"flags":0,"battery_mv":1})", &error));
  STRCMP_EQUAL("\"seq\" must be a whole number", error.c_str());
  CHECK_FALSE(mq::DecodeReading(
      R"({"sensor":"1","seq":18446744073709551615,"time":"t","thickness_mm":9,"loops_intact":9,"flags":0,"battery_mv":1})",
      &error));
  STRCMP_EQUAL("\"seq\" 18446744073709551615 is outside [0, 4294967295]", error.c_str());
  CHECK_FALSE(mq::DecodeReading(
      R"({"sensor":"1","seq":1,"time":"t","thickness_mm":"9","loops_intact":9,"flags":0,"battery_mv":1})", &error));
  STRCMP_EQUAL("missing or non-numeric \"thickness_mm\"", error.c_str());
  CHECK_FALSE(
      mq::DecodeReading(R"({"sensor":"1","seq":1,"time":5,"thickness_mm":9,"loops_intact":9,"flags":0,"battery_mv":1})", &error));
  STRCMP_EQUAL("missing or non-string \"time\"", error.c_str());
  CHECK_FALSE(mq::DecodeReading(
      R"({"sensor":"1","seq":1,"time":"t","thickness_mm":9,"loops_intact":9,"flags":65536,"battery_mv":1})", &error));
  STRCMP_EQUAL("\"flags\" 65536 is outside [0, 65535]", error.c_str());
  CHECK_FALSE(mq::DecodeReading(
      R"({"sensor":"1","seq":1,"time":"t","thickness_mm":9,"loops_intact":4097,"flags":0,"battery_mv":1})", &error));
  STRCMP_EQUAL("\"loops_intact\" 4097 is outside [0, 4096]", error.c_str());
  CHECK_FALSE(mq::DecodeReading(
      R"({"sensor":"1","seq":1,"time":"t","thickness_mm":9,"loops_intact":9,"flags":0,"battery_mv":10001})", &error));
  STRCMP_EQUAL("\"battery_mv\" 10001 is outside [0, 10000]", error.c_str());
  CHECK_FALSE(mq::DecodeReading(R"({"seq":1,"time":"t","thickness_mm":9,"loops_intact":9,"flags":0,"battery_mv":1})", &error));
  STRCMP_EQUAL("missing or invalid \"sensor\"", error.c_str());
  CHECK_FALSE(mq::DecodeReading("[1]", &error));
  STRCMP_EQUAL("not a JSON object", error.c_str());
  CHECK_FALSE(mq::DecodeReading("{not json", &error));
  STRCMP_EQUAL("malformed JSON", error.c_str());
  CHECK_FALSE(mq::DecodeReading("{\"sensor\":\"1\",\"note\":\"\xff\xfe\"}", &error));
  STRCMP_EQUAL("malformed JSON: text that is not UTF-8 at byte 23", error.c_str());
  CHECK_FALSE(mq::DecodeReading(std::string(70000, ' '), &error));
  STRCMP_EQUAL("message of 70000 bytes (at most 65536)", error.c_str());
  CHECK_FALSE(mq::DecodeReading("{\"a\":" + std::string(20, '[') + std::string(20, ']') + "}", &error));
  STRCMP_EQUAL("JSON nested deeper than 8 levels", error.c_str());
}

TEST(Messages, ReadingDecoderAcceptsWholeFloatsAndLeavesMistypedOptionalFieldsAbsent) {
  std::string error;
  const auto r =
      mq::DecodeReading(R"({"sensor":"1","seq":5.0,"time":"t","thickness_mm":9,"loops_intact":9.0,"flags":0,"battery_mv":1,)"
                        R"("temperature_c":"warm","gateway":7,"address":"0013A20040A1B2C3","ladder_loops":12.0})",
                        &error);
  CHECK_TEXT(r.has_value(), error.c_str());
  LONGS_EQUAL(5, r->seq);
  LONGS_EQUAL(9, r->loops_intact);
  CHECK_FALSE(r->temperature_c.has_value());
  CHECK_FALSE(r->gateway.has_value());
  STRCMP_EQUAL("0013A20040A1B2C3", r->address.value_or("").c_str());
  LONGS_EQUAL(12, r->ladder_loops.value_or(0));
}

TEST(Messages, ReadingDecoderIdentifiesARefusedMessageSoItCanBeAcknowledged) {
  std::string error;
  mq::ReadingIdentity id;
  CHECK_FALSE(mq::DecodeReading(R"({"sensor":"1001","seq":77,"time":"garbage"})", &error, &id));
  STRCMP_EQUAL("missing or non-numeric \"thickness_mm\"", error.c_str());
  CHECK_TRUE(id.object);
  STRCMP_EQUAL("1001", id.sensor.c_str());
  LONGS_EQUAL(77, id.seq.value_or(0));
  // A number overflowing a double is named by its field; the identity is still read.
  CHECK_FALSE(mq::DecodeReading(R"({"sensor":"1001","seq":78,"flags":1e999})", &error, &id));
  STRCMP_EQUAL("\"flags\" '1e999' does not fit a double (number overflow)", error.c_str());
  CHECK_FALSE(id.object);
  STRCMP_EQUAL("1001", id.sensor.c_str());
  LONGS_EQUAL(78, id.seq.value_or(0));
  // An overflowing seq identifies nothing (never 0 or another invented seq).
  CHECK_FALSE(mq::DecodeReading(R"({"sensor":"1001","seq":1e999})", &error, &id));
  CHECK_FALSE(id.seq.has_value());
  // Not JSON: no identity.
  CHECK_FALSE(mq::DecodeReading(R"({"sensor":"1001","seq":78,)", &error, &id));
  CHECK_TRUE(id.sensor.empty());
  CHECK_FALSE(id.seq.has_value());
}

// DecodeReading reads a message's text in one pass without building a tree; a batch's records are
// judged from the batch's tree. Both must find the same: the same message as a one-record batch.
TEST(Messages, DecodingATextFindsWhatDecodingItsParsedObjectFinds) {
  const std::string objects[] = {
      mq::EncodeReading(FullReading()),
      // A duplicate key: its last value counts (as in a tree), wherever the first was valid.
      R"({"sensor":"1001","seq":1,"seq":2,"time":"t","thickness_mm":9,"loops_intact":9,"flags":0,"battery_mv":1})",
      R"({"sensor":"1001","seq":1,"time":"t","thickness_mm":9,"loops_intact":9,"flags":0,"battery_mv":1,"seq":"x"})",
      R"({"sensor":"1001","seq":{"seq":1},"time":"t","thickness_mm":9,"loops_intact":9,"flags":0,"battery_mv":1})",
      // Known names inside nested values are not the reading's fields.
      R"({"sensor":"1001","x":{"seq":3,"time":"t"},"y":[{"thickness_mm":1}],"time":"t","thickness_mm":9})",
      R"({"sensor":"1001","seq":4,"time":["t"],"thickness_mm":9,"loops_intact":9,"flags":0,"battery_mv":1})",
      R"({"sensor":"1001","seq":4,"time":"t","thickness_mm":null,"loops_intact":9,"flags":0,"battery_mv":1})",
      R"({"sensor":"1001","seq":4,"time":"t","thickness_mm":true,"loops_intact":9,"flags":0,"battery_mv":1})",
      R"({"sensor":"1001","seq":4,"time":"t","thickness_mm":-1e-3,"loops_intact":-0,"flags":1.0,"battery_mv":1E3,)"
      R"("temperature_c":-40,"ladder_loops":{},"loop_bitmap":"ff","dropped_total":18446744073709551615,"address":[],)"
      R"("gateway":"g\u00e9","received":null,"sensor_extra":1})",
      R"({"sensor":"1001","seq":4.5})",
      R"({"sensor":"1001","seq":9007199254740993.0,"time":"t"})",
  };
  for (const std::string& object : objects) {
    mq::ReadingIdentity id;
    std::string error;
    const auto alone = mq::DecodeReading(object, &error, &id);
    std::vector<mq::BatchRecord> records;
    std::string batch_error;
    CHECK_TEXT(mq::SplitAndDecodeReadingMessage("{\"records\":[" + object + "],\"sensor\":\"1001\"}", &records, &batch_error),
               batch_error.c_str());
    LONGS_EQUAL(1, records.size());
    CHECK_TEXT(alone == records[0].reading, object.c_str());
    if (!alone) STRCMP_EQUAL(records[0].error.c_str(), error.c_str());
    CHECK_EQUAL(records[0].identity.object, id.object);
    STRCMP_EQUAL(records[0].identity.sensor.c_str(), id.sensor.c_str());
    CHECK_TEXT(records[0].identity.seq == id.seq, object.c_str());
  }
  // What the one-pass decoder finds in them (the tree's answer above must be the same).
  std::string error;
  LONGS_EQUAL(2, mq::DecodeReading(objects[1], &error)->seq);
  CHECK_FALSE(mq::DecodeReading(objects[2], &error));
  STRCMP_EQUAL("\"seq\" must be a whole number", error.c_str());
  CHECK_FALSE(mq::DecodeReading(objects[3], &error));
  STRCMP_EQUAL("\"seq\" must be a whole number", error.c_str());
  CHECK_FALSE(mq::DecodeReading(objects[4], &error));
  STRCMP_EQUAL("missing \"seq\"", error.c_str());
  CHECK_FALSE(mq::DecodeReading(objects[5], &error));
  STRCMP_EQUAL("missing or non-string \"time\"", error.c_str());
  CHECK_FALSE(mq::DecodeReading(objects[6], &error));
  STRCMP_EQUAL("missing or non-numeric \"thickness_mm\"", error.c_str());
  const auto odd = mq::DecodeReading(objects[8], &error);
  CHECK_TEXT(odd.has_value(), error.c_str());
  DOUBLES_EQUAL(-1e-3, odd->thickness_mm, 0);
  LONGS_EQUAL(1, odd->flags);
  LONGS_EQUAL(1000, odd->battery_mv);
  LONGS_EQUAL(-40, odd->temperature_c.value_or(0));
  CHECK_FALSE(odd->ladder_loops.has_value());
  CHECK_FALSE(odd->dropped_total.has_value());
  CHECK_FALSE(odd->address.has_value());
  STRCMP_EQUAL("g\xc3\xa9", odd->gateway.value_or("").c_str());
  CHECK_FALSE(odd->received.has_value());
  STRCMP_EQUAL("ff", odd->loop_bitmap.value_or("").c_str());
}

TEST(Messages, ReadingDecoderRefusesWhatIsNotOneJsonObject) {
  std::string error;
  mq::ReadingIdentity id;
  for (const char* text : {"5", "\"sensor\"", "null", "[{\"sensor\":\"1\",\"seq\":1}]", "[]"}) {
    CHECK_FALSE(mq::DecodeReading(text, &error, &id));
    STRCMP_EQUAL("not a JSON object", error.c_str());
    CHECK_FALSE(id.object);
  }
  // Malformed anywhere, even after every field: nothing is identified (the text is not JSON).
  for (const std::string& text : {std::string(R"({"sensor":"1","seq":1} {)"), std::string(R"({"sensor":"1","seq":1,})"),
                                  std::string(R"({"sensor":"1","seq":1,"time":"\x")") + "}", std::string("{\"sensor\":\"\xff\"}"),
                                  std::string(R"({"sensor":"1","seq":1 /* c */})"), std::string()}) {
    CHECK_FALSE(mq::DecodeReading(text, &error, &id));
    // Text that is not UTF-8 is named with the byte where it stops being UTF-8.
    const bool utf8 = text.find('\xff') == std::string::npos;
    STRCMP_EQUAL(utf8 ? "malformed JSON" : "malformed JSON: text that is not UTF-8 at byte 12", error.c_str());
    CHECK_FALSE(id.object);
    CHECK_TRUE(id.sensor.empty());
  }
  // A number overflowing a double in a nested value is named by the last key before it.
  CHECK_FALSE(mq::DecodeReading(R"({"sensor":"1","seq":1,"x":{"deep":[1e400]}})", &error, &id));
  STRCMP_EQUAL("\"deep\" '1e400' does not fit a double (number overflow)", error.c_str());
  STRCMP_EQUAL("1", id.sensor.c_str());
  LONGS_EQUAL(1, id.seq.value_or(0));
}

TEST(Messages, JsonNestingDepthCountsOutsideStringsOnly) {
  LONGS_EQUAL(3, mq::JsonNestingDepth(R"({"a":[{"b":"[[[[{{"}]})"));
  LONGS_EQUAL(0, mq::JsonNestingDepth(R"("\"[")"));
}

// ---- commit ack ----

TEST(Messages, CommitAckEncodesTheBytesTheServerAlwaysSent) {
  STRCMP_EQUAL(R"({"sensor":"1001","seqs":[41,42,43],"time":"2026-06-01T00:00:00Z"})",
               mq::EncodeCommitAck({"1001", {41, 42, 43}, "2026-06-01T00:00:00Z"}).c_str());
}

TEST(Messages, CommitAckRoundTrips) {
  const mq::CommitAck ack{"1001", {0, 41, 4294967295u}, "2026-06-01T00:00:00Z"};
  std::string error;
  const auto back = mq::DecodeCommitAck(mq::EncodeCommitAck(ack), "1001", &error);
  CHECK_TEXT(back.has_value(), error.c_str());
  CHECK(*back == ack);
}

TEST(Messages, CommitAckParses) {
  std::string error;
  const auto ack = mq::DecodeCommitAck(R"({"sensor": "1001", "seqs": [41, 42, 43], "time": "x"})", "1001", &error);
  CHECK_TRUE(ack.has_value());
  STRCMP_EQUAL("1001", ack->sensor.c_str());
  CHECK(ack->seqs == (std::vector<uint32_t>{41, 42, 43}));
  STRCMP_EQUAL("x", ack->time.c_str());
}

TEST(Messages, CommitAckWithoutSensorFieldUsesTheTopic) {
  std::string error;
  const auto ack = mq::DecodeCommitAck(R"({"seqs": [1]})", "77", &error);
  CHECK_TRUE(ack.has_value());
  STRCMP_EQUAL("77", ack->sensor.c_str());
  STRCMP_EQUAL("", ack->time.c_str());
}

TEST(Messages, MalformedCommitAcksAreRefusedWithAReason) {
  std::string error;
  CHECK_FALSE(mq::DecodeCommitAck("not json", "1", &error).has_value());
  STRCMP_EQUAL("not JSON", error.c_str());
  CHECK_FALSE(mq::DecodeCommitAck("[1, 2]", "1", &error).has_value());
  STRCMP_EQUAL("not a JSON object", error.c_str());
  CHECK_FALSE(mq::DecodeCommitAck(R"({"sensor": "1", "seqs": 5})", "1", &error).has_value());
  CHECK(error.find("seqs") != std::string::npos);
  CHECK_FALSE(mq::DecodeCommitAck(R"({"sensor": "1", "seqs": [-1]})", "1", &error).has_value());
  CHECK_FALSE(mq::DecodeCommitAck(R"({"sensor": "1", "seqs": [4294967296]})", "1", &error).has_value());
  CHECK_FALSE(mq::DecodeCommitAck(R"({"sensor": "2", "seqs": [1]})", "1", &error).has_value());
  CHECK(error.find("does not match") != std::string::npos);
}

// Finding 1 of issue 15: `seqs` nested 100 000 deep crashed the gateway (SIGSEGV in a recursive
// dump() of the offending element); sent retained it crash-looped the gateway on every restart.
TEST(Messages, DeeplyNestedCommitAckIsRefusedWithoutRecursing) {
  auto nested = [](size_t depth) {
    return R"({"sensor": "1", "seqs": [)" + std::string(depth, '[') + "1" + std::string(depth, ']') + "]}";
  };
  std::string error;
  CHECK_FALSE(mq::DecodeCommitAck(nested(100000), "1", &error).has_value());  // 200 kB: over the size limit
  CHECK(error.find("bytes (at most 65536)") != std::string::npos);
  CHECK_FALSE(mq::DecodeCommitAck(nested(30000), "1", &error).has_value());  // 60 kB: the depth limit
  STRCMP_EQUAL("JSON nested deeper than 8 levels", error.c_str());
  // Deep but within the byte limit, in a field the gateway does not use: refused all the same.
  const std::string nested_extra = R"({"seqs": [1], "x": )" + std::string(20, '[') + std::string(20, ']') + "}";
  CHECK_FALSE(mq::DecodeCommitAck(nested_extra, "1", &error).has_value());
}

TEST(Messages, CommitAckErrorsNeverEchoANestedValue) {
  std::string error;
  CHECK_FALSE(mq::DecodeCommitAck(R"({"seqs": [1, [2, [3]]]})", "1", &error).has_value());
  STRCMP_EQUAL("\"seqs\" holds an array, not a 32-bit unsigned sequence number", error.c_str());
  CHECK_FALSE(mq::DecodeCommitAck(R"({"seqs": [-7]})", "1", &error).has_value());
  STRCMP_EQUAL("\"seqs\" holds -7, not a 32-bit unsigned sequence number", error.c_str());
}

TEST(Messages, OversizedCommitAcksAreRefusedBeforeParsing) {
  std::string error;
  std::string big = R"({"seqs": [1], "pad": ")" + std::string(mq::kMaxCommitAckBytes, 'x') + "\"}";
  CHECK_FALSE(mq::DecodeCommitAck(big, "1", &error).has_value());
  CHECK(error.find("bytes (at most 65536)") != std::string::npos);
  json many = {{"seqs", json::array()}};
  for (uint32_t i = 0; i <= mq::kMaxCommitAckSeqs; ++i) many["seqs"].push_back(i);
  CHECK_FALSE(mq::DecodeCommitAck(many.dump(), "1", &error).has_value());
  CHECK(error.find("at most 10000") != std::string::npos);
  many["seqs"].erase(many["seqs"].size() - 1);
  CHECK_TRUE(mq::DecodeCommitAck(many.dump(), "1", &error).has_value());
}

// Found by fuzz/commit_ack: one commit ack per sensor and batch could exceed what the gateway
// accepts (64 KiB, 10,000 seqs): 10,000 ten-digit seqs are 110 KB, and a topic level of control
// characters is escaped six-fold. The gateway refused such an ack and kept republishing the records.
TEST(Messages, AcksAreSplitIntoMessagesTheGatewayAccepts) {
  mq::CommitAck ack{"1001", {}, "2026-06-01T00:00:00Z"};
  for (uint32_t s = 0; s < 25000; ++s) ack.seqs.push_back(4294967295u - s);
  const auto messages = mq::EncodeCommitAcks(ack);
  CHECK(messages.size() >= 3);
  std::vector<uint32_t> seqs;
  for (const std::string& m : messages) {
    CHECK(m.size() <= mq::kMaxCommitAckBytes);
    std::string error;
    const auto back = mq::DecodeCommitAck(m, "1001", &error);
    CHECK_TEXT(back.has_value(), error.c_str());
    seqs.insert(seqs.end(), back->seqs.begin(), back->seqs.end());
  }
  CHECK(seqs == ack.seqs);
  // The single message: the gateway refuses it.
  std::string error;
  CHECK_FALSE(mq::DecodeCommitAck(mq::EncodeCommitAck(ack), "1001", &error).has_value());
  // An empty ack and a small one stay one message, exactly EncodeCommitAck.
  const mq::CommitAck small{"1001", {41, 42}, "t"};
  CHECK(mq::EncodeCommitAcks(small) == std::vector<std::string>{mq::EncodeCommitAck(small)});
  const mq::CommitAck none{"1001", {}, "t"};
  CHECK(mq::EncodeCommitAcks(none) == std::vector<std::string>{mq::EncodeCommitAck(none)});
  // A sensor name no message can carry: nothing to send.
  CHECK(mq::EncodeCommitAcks({std::string(20000, '\x17'), {1}, "t"}).empty());
}

// ---- batches: several records of one sensor in one reading message ----

TEST(Messages, ReadingBatchCarriesTheSpooledTextsAndSplitsBackIntoTheSameRecords) {
  std::vector<mq::ReadingMessage> readings;
  std::vector<std::string> texts;
  for (uint32_t seq = 41; seq <= 43; ++seq) {
    readings.push_back(FullReading());
    readings.back().seq = seq;
    texts.push_back(mq::EncodeReading(readings.back()));
  }
  const std::string batch = mq::EncodeReadingBatch("1001", {texts[0], texts[1], texts[2]});
  STRCMP_EQUAL(("{\"records\":[" + texts[0] + "," + texts[1] + "," + texts[2] + "],\"sensor\":\"1001\"}").c_str(), batch.c_str());
  std::vector<std::string> records;
  std::string error;
  CHECK_TEXT(mq::SplitReadingMessage(batch, &records, &error), error.c_str());
  CHECK(records == texts);  // each record exactly as the gateway encoded it, in order
  for (size_t i = 0; i < records.size(); ++i) {
    const auto back = mq::DecodeReading(records[i], &error);
    CHECK_TEXT(back.has_value(), error.c_str());
    CHECK(*back == readings[i]);
  }
}

TEST(Messages, ABatchRecordWithoutASensorIsTheBatchsAndOneNamingAnotherKeepsIt) {
  std::vector<std::string> records;
  std::string error;
  CHECK(mq::SplitReadingMessage(
      R"({"sensor": 1001, "records": [{"seq": 7, "time": "t", "thickness_mm": 5, "loops_intact": 5, "flags": 0,
          "battery_mv": 3000}, {"sensor": "1002", "seq": 8}, 5]})",
      &records, &error));
  LONGS_EQUAL(3, records.size());
  const auto first = mq::DecodeReading(records[0], &error);
  CHECK_TEXT(first.has_value(), error.c_str());
  STRCMP_EQUAL("1001", first->sensor.c_str());
  LONGS_EQUAL(7, first->seq);
  mq::ReadingIdentity id;
  CHECK_FALSE(mq::DecodeReading(records[1], &error, &id).has_value());
  STRCMP_EQUAL("1002", id.sensor.c_str());  // the server's topic check refuses it, on its own
  CHECK_FALSE(mq::DecodeReading(records[2], &error, &id).has_value());
  STRCMP_EQUAL("not a JSON object", error.c_str());
}

TEST(Messages, OneRecordMessagesAreNotBatches) {
  const std::string payloads[] = {
      mq::EncodeReading(FullReading()),
      R"({"sensor": "1001", "seq": 1, "gateway": "\"records\""})",        // the word in a string
      R"({"records": [)",                                                 // not JSON: DecodeReading names it
      R"(["records"])",                                                   // not an object
      "{\"records\": [" + std::string(mq::kMaxReadingBytes, ' ') + "]}",  // too long: DecodeReading names it
  };
  for (const std::string& p : payloads) {
    std::vector<std::string> records{"left over"};
    std::string error;
    CHECK_TEXT(mq::SplitReadingMessage(p, &records, &error), p.substr(0, 60).c_str());
    CHECK_TEXT(records.empty(), p.substr(0, 60).c_str());
  }
}

TEST(Messages, MalformedBatchesAreRefusedWithAReason) {
  const std::string record = mq::EncodeReading(FullReading());
  std::string many = "{\"sensor\": \"1001\", \"records\": [" + record;
  for (size_t i = 1; i <= mq::kMaxReadingBatch; ++i) many += "," + record;
  many += "]}";
  const std::pair<std::string, std::string> cases[] = {
      {"{\"records\": [" + record + "]}", "batch: missing or invalid \"sensor\""},
      {"{\"sensor\": [1], \"records\": [" + record + "]}", "batch: missing or invalid \"sensor\""},
      {"{\"sensor\": \"1001\", \"seq\": 4, \"records\": [" + record + "]}",
       "batch: both \"records\" and \"seq\" (a batch carries its seqs in its records)"},
      {R"({"sensor": "1001", "records": {"seq": 1}})", "batch: \"records\" must be an array of 1 to 64 records, not an object"},
      {R"({"sensor": "1001", "records": []})", "batch: \"records\" must be an array of 1 to 64 records, not 0 records"},
      {many, "batch: \"records\" must be an array of 1 to 64 records, not 65 records"},
  };
  for (const auto& [payload, expected] : cases) {
    std::vector<std::string> records;
    std::string error;
    CHECK_FALSE_TEXT(mq::SplitReadingMessage(payload, &records, &error), expected.c_str());
    STRCMP_EQUAL(expected.c_str(), error.c_str());
  }
}

// The server decodes a batch's records from the batch's one parse: what it finds must be what
// DecodeReading finds in each record's text (docs/mqtt.md: each record as if it had come alone).
TEST(Messages, DecodingABatchFindsWhatDecodingEachOfItsRecordsFinds) {
  const std::string full = mq::EncodeReading(FullReading());
  std::string expanding = R"({"seq":9,"time":"t","thickness_mm":1,"loops_intact":1,"flags":0,"battery_mv":1,"x":[)";
  for (int i = 0; i < 9000; ++i) expanding += i ? ",1E5" : "1E5";  // each prints back as 100000.0
  expanding += "]}";
  const std::string payloads[] = {
      // The gateway's batch.
      "{\"records\":[" + full + "," + full + "],\"sensor\":\"1001\"}",
      // Records of every kind: whole-number floats, -0, a numeric sensor, another sensor, not an
      // object, a seq out of range or negative, a duplicate key, optional fields of another type,
      // a missing field, escapes, spaces.
      R"({"sensor": 1001, "records": [
          {"seq": 5.0, "time": "t", "thickness_mm": -0, "loops_intact": 9.0, "flags": 0, "battery_mv": 1},
          {"sensor": 1002, "seq": 8}, 5, "text", null, [1, 2],
          {"seq": -1, "time": "t"}, {"seq": 18446744073709551615}, {"seq": 4294967296},
          {"seq": 1, "seq": 2, "time": "t", "thickness_mm": 1e308, "loops_intact": 0, "flags": 65535, "battery_mv": 10000},
          {"seq": 3, "time": "t\u00e9\/\n", "thickness_mm": 1.5E-3, "loops_intact": 1, "flags": 0, "battery_mv": 0,
           "temperature_c": "hot", "ladder_loops": 1.5, "loop_bitmap": 7, "received": "r", "gateway": ["g"]},
          {"seq": 6, "time": "t", "thickness_mm": "1", "loops_intact": 1, "flags": 0, "battery_mv": 0},
          {"seq": 7, "time": "t", "thickness_mm": 1, "loops_intact": 5000, "flags": 0, "battery_mv": 0},
          {"seq": 8, "time": "t", "thickness_mm": 1, "loops_intact": 1, "battery_mv": 0},
          {"sensor": "", "seq": 9}, {"sensor": -3, "seq": 10}, {}]})",
      // A batch within the limit whose record's text is not (its numbers print back longer).
      "{\"records\":[" + expanding + "],\"sensor\":\"1001\"}",
  };
  for (const std::string& p : payloads) {
    CHECK(p.size() <= mq::kMaxReadingBytes);
    std::vector<std::string> texts;
    std::vector<mq::BatchRecord> records;
    std::string split_error, error;
    CHECK_TEXT(mq::SplitReadingMessage(p, &texts, &split_error), split_error.c_str());
    CHECK_TEXT(mq::SplitAndDecodeReadingMessage(p, &records, &error), error.c_str());
    CHECK(!texts.empty());
    LONGS_EQUAL(texts.size(), records.size());
    for (size_t i = 0; i < texts.size(); ++i) {
      mq::ReadingIdentity id;
      std::string alone_error;
      const auto alone = mq::DecodeReading(texts[i], &alone_error, &id);
      STRCMP_EQUAL(texts[i].substr(0, 80).c_str(), records[i].text.substr(0, 80).c_str());
      CHECK_TEXT(texts[i] == records[i].text, texts[i].substr(0, 80).c_str());
      CHECK_TEXT(alone == records[i].reading, texts[i].substr(0, 80).c_str());
      if (!alone) STRCMP_EQUAL(alone_error.c_str(), records[i].error.c_str());
      CHECK_EQUAL(id.object, records[i].identity.object);
      STRCMP_EQUAL(id.sensor.c_str(), records[i].identity.sensor.c_str());
      CHECK(id.seq == records[i].identity.seq);
    }
  }
  // The last record is too long on its own: refused as DecodeReading refuses it.
  std::vector<mq::BatchRecord> records;
  std::string error;
  CHECK(mq::SplitAndDecodeReadingMessage(payloads[2], &records, &error));
  CHECK(records.at(0).text.size() > mq::kMaxReadingBytes);
  CHECK(records[0].error.find("bytes (at most 65536)") != std::string::npos);
  // One-record messages and malformed batches: as SplitReadingMessage says.
  CHECK(mq::SplitAndDecodeReadingMessage(full, &records, &error));
  CHECK(records.empty());
  CHECK_FALSE(mq::SplitAndDecodeReadingMessage(R"({"sensor": "1001", "records": []})", &records, &error));
  STRCMP_EQUAL("batch: \"records\" must be an array of 1 to 64 records, not 0 records", error.c_str());
}

TEST(Messages, CommitAckAnnouncesBatchesOnlyWhenAsked) {
  const mq::CommitAck ack{"1001", {41, 42}, "2026-06-01T00:00:00Z", 64};
  STRCMP_EQUAL(R"({"batch":64,"sensor":"1001","seqs":[41,42],"time":"2026-06-01T00:00:00Z"})", mq::EncodeCommitAck(ack).c_str());
  std::string error;
  const auto back = mq::DecodeCommitAck(mq::EncodeCommitAck(ack), "1001", &error);
  CHECK_TEXT(back.has_value(), error.c_str());
  CHECK(*back == ack);
  // Split acks each carry the announcement.
  mq::CommitAck big{"1001", {}, "t", 64};
  for (uint32_t s = 0; s < 25000; ++s) big.seqs.push_back(s);
  for (const std::string& m : mq::EncodeCommitAcks(big)) {
    const auto part = mq::DecodeCommitAck(m, "1001", &error);
    CHECK_TEXT(part.has_value(), error.c_str());
    LONGS_EQUAL(64, part->batch);
  }
  // An announcement that cannot be read is none; the ack itself still counts.
  for (const char* bad : {R"({"seqs": [1], "batch": "64"})", R"({"seqs": [1], "batch": -1})", R"({"seqs": [1], "batch": 6.5})",
                          R"({"seqs": [1], "batch": 4294967296})"}) {
    const auto a = mq::DecodeCommitAck(bad, "1001", &error);
    CHECK_TEXT(a.has_value(), bad);
    LONGS_EQUAL(0, a->batch);
    CHECK(a->seqs == std::vector<uint32_t>{1});
  }
}

// ---- gateway status ----

TEST(Messages, StatusEncodesTheBytesTheGatewayAlwaysSent) {
  STRCMP_EQUAL(R"({"gateway":"gw-7","state":"offline","time":"1970-01-01T00:00:00Z"})",
               mq::EncodeStatus({false, "gw-7", mq::IsoUtc(0)}).c_str());
  STRCMP_EQUAL(R"({"gateway":"gw-1","state":"online","time":"2026-03-01T12:00:07Z"})",
               mq::EncodeStatus({true, "gw-1", "2026-03-01T12:00:07Z"}).c_str());
}

TEST(Messages, StatusRoundTripsAndRefusesAnUnknownState) {
  std::string error;
  for (const bool online : {true, false}) {
    const mq::StatusMessage s{online, "gw-1", "2026-03-01T12:00:07Z"};
    const auto back = mq::DecodeStatus(mq::EncodeStatus(s), &error);
    CHECK_TEXT(back.has_value(), error.c_str());
    CHECK(*back == s);
  }
  CHECK_FALSE(mq::DecodeStatus(R"({"state":"asleep","gateway":"g","time":"t"})", &error));
  STRCMP_EQUAL("\"state\" must be \"online\" or \"offline\"", error.c_str());
  CHECK_FALSE(mq::DecodeStatus(R"({"state":"online","time":"t"})", &error));
  STRCMP_EQUAL("missing \"gateway\"", error.c_str());
}

TEST(Messages, TextThatIsNotUtf8IsReplacedNeverThrown) {
  const json j = json::parse(mq::EncodeStatus({true, "gw\xFF", "t"}));
  STRCMP_EQUAL("gw\xEF\xBF\xBD", j["gateway"].get<std::string>().c_str());
}

// ---- gateway stats ----

TEST(Messages, StatsRoundTrip) {
  mq::StatsMessage s;
  s.gateway = "gw-1";
  s.time = "2026-03-01T12:00:07Z";
  s.counters = {{"frames_ok", 12}, {"spool_depth", 0}, {"bytes_discarded", 18446744073709551615ull}};
  s.latency_last_ms = 4;
  s.latency_max_ms = 90;
  s.latency_mean_ms = 11;
  const std::string text = mq::EncodeStats(s);
  STRCMP_EQUAL(R"({"bytes_discarded":18446744073709551615,"frames_ok":12,"gateway":"gw-1",)"
               R"("publish_latency_ms":{"last":4,"max":90,"mean":11},"spool_depth":0,"time":"2026-03-01T12:00:07Z"})",
               text.c_str());
  std::string error;
  const auto back = mq::DecodeStats(text, &error);
  CHECK_TEXT(back.has_value(), error.c_str());
  CHECK(*back == s);
  CHECK_FALSE(mq::DecodeStats(R"({"gateway":"g","time":"t"})", &error));
  STRCMP_EQUAL("\"publish_latency_ms\" must be an object", error.c_str());
}

// ---- device registry ----

TEST(Messages, DeviceRoundTrips) {
  mq::DeviceMessage d;
  d.gateway = "gw-1";
  d.time = "2026-03-01T12:00:07Z";
  d.address = "0013A20040A1B2C3";
  d.first_seen = "2026-03-01T12:00:00Z";
  d.sensors = {"1001", "1002"};
  std::string error;
  auto back = mq::DecodeDevice(mq::EncodeDevice(d), &error);  // no identifier, no type: left out
  CHECK_TEXT(back.has_value(), error.c_str());
  CHECK(*back == d);
  d.node_identifier = "ROW1";
  d.device_type = 2;
  STRCMP_EQUAL(R"({"address":"0013A20040A1B2C3","device_type":2,"first_seen":"2026-03-01T12:00:00Z","gateway":"gw-1",)"
               R"("node_identifier":"ROW1","sensors":["1001","1002"],"time":"2026-03-01T12:00:07Z"})",
               mq::EncodeDevice(d).c_str());
  back = mq::DecodeDevice(mq::EncodeDevice(d), &error);
  CHECK_TEXT(back.has_value(), error.c_str());
  CHECK(*back == d);
  CHECK_FALSE(mq::DecodeDevice(R"({"gateway":"g","time":"t","address":"a","first_seen":"t","sensors":[1]})", &error));
  STRCMP_EQUAL("\"sensors\" must be an array of sensor ids", error.c_str());
}

// ---- wear ----

TEST(Messages, WearRoundTripsWithEveryFieldKept) {
  nlohmann::ordered_json summary;
  summary["crusher_id"] = "cr7";
  summary["time"] = "2026-03-01T12:00:00Z";
  summary["map_sha256"] = "ab12";
  summary["status"] = "ok";
  summary["min_thickness_mm"] = 61.25;
  summary["rows"] = {{{"row", "R1"}, {"min_thickness_mm", 61.25}, {"scale_sd", 0.1}},
                     {{"row", "R2"}, {"min_thickness_mm", nullptr}}};
  summary["readings_used"] = {{{"sensor", "1001"}, {"seq", 42}, {"time", "2026-03-01T12:00:00Z"}, {"thickness_mm", 61.0}}};
  summary["note"] = "kept as it is";
  const std::string text = mq::EncodeWear(summary);
  // Insertion order, as the server has always sent it.
  CHECK(text.rfind(R"({"crusher_id":"cr7","time":)", 0) == 0);
  std::string error;
  const auto w = mq::DecodeWear(text, &error);
  CHECK_TEXT(w.has_value(), error.c_str());
  CHECK(w->summary == summary);
  STRCMP_EQUAL(text.c_str(), mq::EncodeWear(w->summary).c_str());
  STRCMP_EQUAL("cr7", w->crusher_id.c_str());
  STRCMP_EQUAL("2026-03-01T12:00:00Z", w->time.c_str());
  STRCMP_EQUAL("ab12", w->map_sha256.c_str());
  DOUBLES_EQUAL(61.25, *w->min_thickness_mm, 0);
  CHECK(w->rows == (std::vector<mq::WearMessage::Row>{{"R1", 61.25}, {"R2", std::nullopt}}));
  CHECK(w->readings_used == (std::vector<mq::WearMessage::Used>{{"1001", 42, "2026-03-01T12:00:00Z", 61.0}}));
}

TEST(Messages, WearWithoutSupportAndMalformedWear) {
  std::string error;
  const auto w = mq::DecodeWear(
      R"({"crusher_id":"c","time":"t","map_sha256":"h","min_thickness_mm":null,"rows":[],"readings_used":[]})", &error);
  CHECK_TEXT(w.has_value(), error.c_str());
  CHECK_FALSE(w->min_thickness_mm.has_value());
  CHECK_FALSE(mq::DecodeWear(R"({"crusher_id":"c","time":"t","min_thickness_mm":1,"rows":[],"readings_used":[]})", &error));
  STRCMP_EQUAL("missing \"map_sha256\"", error.c_str());
  CHECK_FALSE(mq::DecodeWear(
      R"({"crusher_id":"c","time":"t","map_sha256":"h","min_thickness_mm":1,"rows":[{"min_thickness_mm":1}],"readings_used":[]})",
      &error));
  STRCMP_EQUAL("missing \"row\"", error.c_str());
  CHECK_FALSE(mq::DecodeWear("not json", &error));
  STRCMP_EQUAL("not JSON", error.c_str());
}
