#include "mqtt/messages.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>

namespace lw::mqtt {

using nlohmann::json;

namespace {

/// Text from the radio (NI strings) or the host is not always UTF-8: invalid bytes become U+FFFD
/// instead of an exception that would lose the message.
std::string Dump(const json& j) {
  return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

/// Every decoder's bounds (the server's on readings, the gateway's on commit acks): checked before
/// a tree is built. Wear messages name every row and sensor: they get more room.
constexpr size_t kMaxMessageBytes = 64 * 1024;
constexpr size_t kMaxMessageDepth = 8;
constexpr size_t kMaxWearBytes = 1024 * 1024;

// SAX pass that only measures nesting and stops at the first level beyond the limit, so that a
// hostile message (`[[[[...` 100 000 deep) is refused without building a tree or recursing.
class DepthLimit {
 public:
  explicit DepthLimit(size_t max_depth) : max_depth_(max_depth) {}
  bool too_deep() const { return too_deep_; }
  bool null() { return true; }
  bool boolean(bool) { return true; }
  bool number_integer(json::number_integer_t) { return true; }
  bool number_unsigned(json::number_unsigned_t) { return true; }
  bool number_float(json::number_float_t, const json::string_t&) { return true; }
  bool string(json::string_t&) { return true; }
  bool binary(json::binary_t&) { return true; }
  bool key(json::string_t&) { return true; }
  bool start_object(std::size_t) { return Enter(); }
  bool start_array(std::size_t) { return Enter(); }
  bool end_object() { return Leave(); }
  bool end_array() { return Leave(); }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) { return false; }

 private:
  bool Enter() {
    if (++depth_ > max_depth_) too_deep_ = true;
    return !too_deep_;
  }
  bool Leave() {
    --depth_;
    return true;
  }
  size_t max_depth_;
  size_t depth_ = 0;
  bool too_deep_ = false;
};

// Describes a JSON value for an error message without serialising it (a nested value may be
// arbitrarily large): numbers and short strings as they are, anything else by its type.
std::string Describe(const json& v) {
  if (v.is_number() || v.is_boolean() || v.is_null()) return v.dump();
  if (v.is_string() && v.get_ref<const std::string&>().size() <= 32) return v.dump();
  const std::string type = v.type_name();
  return (v.is_object() || v.is_array() ? "an " : "a ") + type;
}

// Size and nesting checked before a tree is built.
std::optional<json> ParseBoundedJson(std::string_view text, size_t max_bytes, size_t max_depth, std::string* error) {
  if (text.size() > max_bytes) {
    *error = "message of " + std::to_string(text.size()) + " bytes (at most " + std::to_string(max_bytes) + ")";
    return std::nullopt;
  }
  DepthLimit limit(max_depth);
  if (!json::sax_parse(text, &limit, json::input_format_t::json, /*strict=*/true, /*ignore_comments=*/false)) {
    *error = limit.too_deep() ? "JSON nested deeper than " + std::to_string(max_depth) + " levels" : "not JSON";
    return std::nullopt;
  }
  json j = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) {
    *error = "not JSON";
    return std::nullopt;
  }
  return j;
}

/// A bounded JSON object, or nullopt with `*error` set.
std::optional<json> ParseObject(std::string_view text, std::string* error, size_t max_bytes = kMaxMessageBytes) {
  auto parsed = ParseBoundedJson(text, max_bytes, kMaxMessageDepth, error);
  if (parsed && !parsed->is_object()) {
    *error = "not a JSON object";
    return std::nullopt;
  }
  return parsed;
}

/// Typed field readers for the decoders: each sets `*error` naming the field when it is missing
/// (required ones) or of another type, and returns false.
class Fields {
 public:
  Fields(const json& object, std::string* error) : j_(object), error_(error) {}

  bool String(const char* name, std::string* out, bool required = true) {
    const auto it = j_.find(name);
    if (it == j_.end()) return Missing(name, required);
    if (!it->is_string()) return Wrong(name, "a string");
    *out = it->get<std::string>();
    return true;
  }
  bool String(const char* name, std::optional<std::string>* out) {
    std::string v;
    if (j_.find(name) == j_.end()) return true;
    if (!String(name, &v)) return false;
    *out = std::move(v);
    return true;
  }
  bool Integer(const char* name, int64_t lo, int64_t hi, int64_t* out, bool required = true) {
    const auto it = j_.find(name);
    if (it == j_.end()) return Missing(name, required);
    if (!it->is_number_integer() || (it->is_number_unsigned() && it->get<uint64_t>() > static_cast<uint64_t>(hi)) ||
        it->get<int64_t>() < lo || it->get<int64_t>() > hi) {
      return Wrong(name, "a whole number in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    }
    *out = it->get<int64_t>();
    return true;
  }
  bool Integer(const char* name, std::optional<int64_t>* out) {
    int64_t v = 0;
    if (j_.find(name) == j_.end()) return true;
    if (!Integer(name, INT64_MIN, INT64_MAX, &v)) return false;
    *out = v;
    return true;
  }
  bool Number(const char* name, double* out) {
    const auto it = j_.find(name);
    if (it == j_.end()) return Missing(name, true);
    if (!it->is_number()) return Wrong(name, "a number");
    *out = it->get<double>();
    return true;
  }
  /// A number or null.
  bool NumberOrNull(const json& where, const char* name, std::optional<double>* out) {
    const auto it = where.find(name);
    if (it == where.end()) return Missing(name, true);
    if (it->is_null()) return true;
    if (!it->is_number()) return Wrong(name, "a number or null");
    *out = it->get<double>();
    return true;
  }
  bool Array(const char* name, const json** out) {
    const auto it = j_.find(name);
    if (it == j_.end()) return Missing(name, true);
    if (!it->is_array()) return Wrong(name, "an array");
    *out = &*it;
    return true;
  }
  bool Wrong(const std::string& name, const std::string& what) {
    *error_ = "\"" + name + "\" must be " + what;
    return false;
  }

 private:
  bool Missing(const char* name, bool required) {
    if (!required) return true;
    *error_ = std::string("missing \"") + name + "\"";
    return false;
  }
  const json& j_;
  std::string* error_;
};

}  // namespace

std::string IsoUtc(int64_t unix_ms) {
  int64_t secs = unix_ms / 1000;
  if (unix_ms < 0 && unix_ms % 1000 != 0) --secs;
  const time_t t = static_cast<time_t>(secs);
  struct tm tm_utc {};
  gmtime_r(&t, &tm_utc);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm_utc);
  return buf;
}

std::string AddressHex(uint64_t address) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llX", static_cast<unsigned long long>(address));
  return buf;
}

std::vector<std::string> FlagNames(uint16_t flags) {
  static constexpr const char* kNames[] = {"heartbeat", "loop_healed", "non_contiguous", "all_open",       "spi_stuck",
                                           "flicker",   "low_battery", "boot",           "watchdog_reset", "dropped"};
  std::vector<std::string> out;
  for (unsigned bit = 0; bit < 16; ++bit) {
    if (!(flags & (1u << bit))) continue;
    out.push_back(bit < std::size(kNames) ? kNames[bit] : "bit" + std::to_string(bit));
  }
  return out;
}

// ---- reading ----

std::string EncodeReading(const ReadingMessage& r) {
  json j = {
      {"sensor", r.sensor},
      {"seq", r.seq},
      {"time", r.time},
      {"thickness_mm", r.thickness_mm},
      {"loops_intact", r.loops_intact},
      {"flags", r.flags},
      {"flag_names", FlagNames(r.flags)},
      {"battery_mv", r.battery_mv},
  };
  if (r.temperature_c) j["temperature_c"] = *r.temperature_c;
  if (r.ladder_loops) j["ladder_loops"] = *r.ladder_loops;
  if (r.loop_bitmap) j["loop_bitmap"] = *r.loop_bitmap;
  if (r.dropped_total) j["dropped_total"] = *r.dropped_total;
  if (r.address) j["address"] = *r.address;
  if (r.gateway) j["gateway"] = *r.gateway;
  if (r.received) j["received"] = *r.received;
  return Dump(j);
}

namespace {

/// A top-level field of a reading object as the reading decoder sees it: its JSON type and value,
/// read from the text by one SAX pass (ReadingSax) or from a parsed tree (FieldsOf, batches).
struct Field {
  enum class Kind : uint8_t { kAbsent, kString, kUnsigned, kInteger, kFloat, kOther };  ///< kOther: bool, null, object, array
  Kind kind = Kind::kAbsent;
  std::string text;  ///< kString
  uint64_t u = 0;    ///< kUnsigned
  int64_t i = 0;     ///< kInteger; kUnsigned up to INT64_MAX too
  double d = 0;      ///< every number as a double (what nlohmann's get<double> gives)
  bool absent() const { return kind == Kind::kAbsent; }
  bool is_string() const { return kind == Kind::kString; }
  bool is_number() const { return kind == Kind::kUnsigned || kind == Kind::kInteger || kind == Kind::kFloat; }
  void SetString(const std::string& v) {
    kind = Kind::kString;
    text = v;
  }
  void SetUnsigned(uint64_t v) {
    kind = Kind::kUnsigned;
    u = v;
    i = static_cast<int64_t>(v);
    d = static_cast<double>(v);
  }
  void SetInteger(int64_t v) {
    kind = Kind::kInteger;
    i = v;
    d = static_cast<double>(v);
  }
  void SetFloat(double v) {
    kind = Kind::kFloat;
    d = v;
  }
};

/// The fields the reading decoder reads; any other key is ignored.
enum FieldId : uint8_t {
  kSensor,
  kSeq,
  kTime,
  kThickness,
  kLoops,
  kFlags,
  kBattery,
  kTemperature,
  kLadder,
  kBitmap,
  kDropped,
  kAddress,
  kGateway,
  kReceived,
  kFieldCount
};
constexpr std::string_view kFieldNames[kFieldCount] = {
    "sensor",        "seq",          "time",        "thickness_mm",  "loops_intact", "flags",   "battery_mv",
    "temperature_c", "ladder_loops", "loop_bitmap", "dropped_total", "address",      "gateway", "received"};
using ReadingFields = std::array<Field, kFieldCount>;

int FieldIndex(std::string_view key) {
  for (int k = 0; k < kFieldCount; ++k) {
    if (kFieldNames[k] == key) return k;
  }
  return -1;
}

/// The fields of a parsed object (a record of a batch, or a whole message parsed as a tree).
ReadingFields FieldsOf(const json& object) {
  ReadingFields f;
  for (int k = 0; k < kFieldCount; ++k) {
    const auto it = object.find(kFieldNames[k]);
    if (it == object.end()) continue;
    if (it->is_string())
      f[k].SetString(it->get_ref<const std::string&>());
    else if (it->is_number_unsigned())
      f[k].SetUnsigned(it->get<uint64_t>());
    else if (it->is_number_integer())
      f[k].SetInteger(it->get<int64_t>());
    else if (it->is_number_float())
      f[k].SetFloat(it->get<double>());
    else
      f[k].kind = Field::Kind::kOther;
  }
  return f;
}

/// "malformed JSON", naming text that is not UTF-8 and where (a payload's bytes can be anything;
/// the offending bytes themselves are not quoted: the reason is logged and served as JSON).
std::string MalformedJson(const json::exception& e) {
  const auto* parse = dynamic_cast<const json::parse_error*>(&e);
  if (parse && std::string_view(e.what()).find("ill-formed UTF-8") != std::string_view::npos) {
    return "malformed JSON: text that is not UTF-8 at byte " + std::to_string(parse->byte);
  }
  return "malformed JSON";
}

/// The overflow error of a number that does not fit a double, named by the last key seen before
/// it (`what`: nlohmann's "[json.exception.out_of_range.406] number overflow parsing '1e999'").
std::string OverflowError(const std::string& key, const std::string& what) {
  const size_t q = what.find('\'');
  const std::string number = q == std::string::npos ? std::string() : what.substr(q);
  return (key.empty() ? std::string("a number") : "\"" + key + "\"") + (number.empty() ? "" : " " + number) +
         " does not fit a double (number overflow)";
}

/// One SAX pass over a reading message's text: the top level's known fields into a ReadingFields,
/// without building a tree (a tree cost a heap node per key and value). Nested values are only
/// walked (a known field holding one is kOther). A duplicate key's last value counts, as in a tree.
/// The parse is nlohmann's own (strict, no comments): the same JSON is accepted and refused.
class ReadingSax {
 public:
  explicit ReadingSax(ReadingFields* fields) : f_(*fields) {}
  bool object() const { return object_; }
  bool overflow() const { return overflow_; }
  const std::string& error() const { return error_; }

  bool null() { return Other(); }
  bool boolean(bool) { return Other(); }
  bool number_integer(json::number_integer_t v) {
    if (Field* f = Target()) f->SetInteger(v);
    return true;
  }
  bool number_unsigned(json::number_unsigned_t v) {
    if (Field* f = Target()) f->SetUnsigned(v);
    return true;
  }
  bool number_float(json::number_float_t v, const json::string_t&) {
    if (Field* f = Target()) f->SetFloat(v);
    return true;
  }
  bool string(json::string_t& v) {
    if (Field* f = Target()) f->SetString(v);
    return true;
  }
  bool binary(json::binary_t&) { return Other(); }
  bool key(json::string_t& k) {
    key_ = k;  // names a number overflow, at any depth (as ParseJsonNamingField does)
    if (depth_ == 1) pending_ = FieldIndex(k);
    return true;
  }
  bool start_object(std::size_t) {
    if (depth_ == 0) object_ = true;
    Other();
    ++depth_;
    return true;
  }
  bool start_array(std::size_t) {
    Other();
    ++depth_;
    return true;
  }
  bool end_object() {
    --depth_;
    return true;
  }
  bool end_array() {
    --depth_;
    return true;
  }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception& e) {
    overflow_ = dynamic_cast<const json::out_of_range*>(&e) != nullptr;
    error_ = overflow_ ? OverflowError(key_, e.what()) : MalformedJson(e);
    return false;
  }

 private:
  /// The field the value now starting at the top level belongs to, or null.
  Field* Target() {
    if (depth_ != 1 || pending_ < 0) return nullptr;
    Field* f = &f_[static_cast<size_t>(pending_)];
    pending_ = -1;
    return f;
  }
  bool Other() {
    if (Field* f = Target()) f->kind = Field::Kind::kOther;
    return true;
  }
  ReadingFields& f_;
  std::string key_;
  std::string error_;
  size_t depth_ = 0;
  int pending_ = -1;
  bool object_ = false;
  bool overflow_ = false;
};

/// A whole-number field in [lo, hi] (a float without a fraction counts); sets *error naming the
/// field otherwise (the server's texts: `missing "seq"`, `"seq" must be a whole number`,
/// `"flags" 70000 is outside [0, 65535]`).
std::optional<int64_t> WholeField(const Field& f, const char* name, int64_t lo, int64_t hi, std::string* error) {
  if (f.absent()) {
    *error = std::string("missing \"") + name + "\"";
    return std::nullopt;
  }
  const auto outside = [&](const std::string& value) {
    *error = std::string("\"") + name + "\" " + value + " is outside [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
    return std::nullopt;
  };
  int64_t v = 0;
  if (f.kind == Field::Kind::kUnsigned && f.u > static_cast<uint64_t>(INT64_MAX)) {
    return outside(std::to_string(f.u));  // beyond every range a field has
  } else if (f.kind == Field::Kind::kUnsigned || f.kind == Field::Kind::kInteger) {
    v = f.i;
  } else if (f.kind == Field::Kind::kFloat && std::floor(f.d) == f.d && std::fabs(f.d) < 9e15) {
    v = static_cast<int64_t>(f.d);
  } else {
    *error = std::string("\"") + name + "\" must be a whole number";
    return std::nullopt;
  }
  if (v < lo || v > hi) return outside(std::to_string(v));
  return v;
}

/// The identity of a reading object: its sensor (a string or a whole number) and a valid seq.
void Identify(const ReadingFields& f, ReadingIdentity* id) {
  const Field& s = f[kSensor];
  if (s.kind == Field::Kind::kString)
    id->sensor = s.text;
  else if (s.kind == Field::Kind::kUnsigned)
    id->sensor = std::to_string(s.u);
  else if (s.kind == Field::Kind::kInteger)
    id->sensor = std::to_string(s.i);
  std::string ignored;
  if (const auto seq = WholeField(f[kSeq], "seq", 0, 0xFFFFFFFFLL, &ignored)) id->seq = static_cast<uint32_t>(*seq);
}

/// The quoted token of a number overflow message ("... parsing '1e999'"), or empty.
std::string OverflowToken(const std::string& what) {
  const size_t a = what.find('\'');
  const size_t b = a == std::string::npos ? a : what.find('\'', a + 1);
  return b == std::string::npos ? std::string() : what.substr(a + 1, b - a - 1);
}

/// A message whose numbers overflow a double still names its sensor and seq: read them from a copy
/// with each overflowing number replaced by 0 (at most 16), so the rejection can be acknowledged.
void IdentifyDespiteOverflow(std::string_view payload, ReadingIdentity* id) {
  std::string text(payload);
  for (int tries = 0; tries < 16; ++tries) {
    try {
      const json j = json::parse(text);
      if (j.is_object()) Identify(FieldsOf(j), id);
      return;
    } catch (const json::out_of_range& e) {
      const std::string token = OverflowToken(e.what());
      if (token.empty()) return;
      bool replaced = false;
      for (size_t at = text.find(token); at != std::string::npos; at = text.find(token, at + 1)) {
        // Only a whole number token (after ':' ',' or '[' and optional spaces), not text in a string.
        size_t before = at;
        while (before > 0 && std::isspace(static_cast<unsigned char>(text[before - 1]))) --before;
        const char prev = before > 0 ? text[before - 1] : '\0';
        const size_t after = at + token.size();
        const bool ends = after >= text.size() || std::strchr(",]} \t\r\n", text[after]) != nullptr;
        if ((prev == ':' || prev == ',' || prev == '[') && ends) {
          // Never invent the identity itself: an overflowing "seq" or "sensor" identifies nothing.
          if (prev == ':') {
            const size_t quote = text.rfind('"', before - 1);
            const size_t open = quote == std::string::npos || quote == 0 ? std::string::npos : text.rfind('"', quote - 1);
            const std::string key = open == std::string::npos ? std::string() : text.substr(open + 1, quote - open - 1);
            if (key == "seq" || key == "sensor") return;
          }
          text.replace(at, token.size(), "0");
          replaced = true;
          break;
        }
      }
      if (!replaced) return;
    } catch (const json::exception&) {
      return;
    }
  }
}

/// Optional fields: set when present with docs/mqtt.md's type, left absent otherwise.
void OptionalString(const Field& f, std::optional<std::string>* out) {
  if (f.is_string()) *out = f.text;
}
void OptionalWhole(const Field& f, const char* name, std::optional<int64_t>* out) {
  std::string ignored;
  if (!f.absent()) *out = WholeField(f, name, INT64_MIN, INT64_MAX, &ignored);
}

}  // namespace

bool ParseJsonNamingField(std::string_view text, nlohmann::json* out, std::string* error) {
  try {
    *out = json::parse(text);  // the common case: no callback per token
    return true;
  } catch (const json::out_of_range&) {
    // Parse again to learn which field holds the overflowing number (below).
  } catch (const json::exception& e) {
    *error = MalformedJson(e);
    return false;
  }
  std::string key;  // the last object key seen: names the field a number overflow sits in
  try {
    *out = json::parse(text, [&key](int, json::parse_event_t event, json& parsed) {
      if (event == json::parse_event_t::key && parsed.is_string()) key = parsed.get<std::string>();
      return true;
    });
    return true;
  } catch (const json::out_of_range& e) {
    *error = OverflowError(key, e.what());
  } catch (const json::exception& e) {
    *error = MalformedJson(e);
  }
  return false;
}

size_t JsonNestingDepth(std::string_view text) {
  size_t depth = 0, deepest = 0;
  bool in_string = false, escaped = false;
  for (const char ch : text) {
    if (in_string) {
      if (escaped)
        escaped = false;
      else if (ch == '\\')
        escaped = true;
      else if (ch == '"')
        in_string = false;
    } else if (ch == '"') {
      in_string = true;
    } else if (ch == '[' || ch == '{') {
      deepest = std::max(deepest, ++depth);
    } else if ((ch == ']' || ch == '}') && depth > 0) {
      --depth;
    }
  }
  return deepest;
}

namespace {

/// DecodeReading's checks on the fields of a JSON object (`id.object` set), from "sensor" on:
/// the one place a reading's fields are judged, whether read from its text or from a batch's tree.
std::optional<ReadingMessage> DecodeFields(const ReadingFields& f, std::string* error, ReadingIdentity& id) {
  // Identify first, so that even a rejected message can be acknowledged once quarantined.
  Identify(f, &id);
  if (id.sensor.empty()) {
    *error = "missing or invalid \"sensor\"";
    return std::nullopt;
  }
  ReadingMessage r;
  r.sensor = id.sensor;
  if (!WholeField(f[kSeq], "seq", 0, 0xFFFFFFFFLL, error)) return std::nullopt;
  r.seq = *id.seq;
  if (!f[kTime].is_string()) {
    *error = "missing or non-string \"time\"";
    return std::nullopt;
  }
  r.time = f[kTime].text;
  if (!f[kThickness].is_number()) {
    *error = "missing or non-numeric \"thickness_mm\"";
    return std::nullopt;
  }
  r.thickness_mm = f[kThickness].d;
  const auto loops = WholeField(f[kLoops], "loops_intact", 0, 4096, error);
  const auto flags = loops ? WholeField(f[kFlags], "flags", 0, 0xFFFF, error) : std::nullopt;
  const auto battery = flags ? WholeField(f[kBattery], "battery_mv", 0, 10000, error) : std::nullopt;
  if (!battery) return std::nullopt;
  r.loops_intact = *loops;
  r.flags = static_cast<uint16_t>(*flags);
  r.battery_mv = *battery;
  OptionalWhole(f[kTemperature], "temperature_c", &r.temperature_c);
  OptionalWhole(f[kLadder], "ladder_loops", &r.ladder_loops);
  OptionalString(f[kBitmap], &r.loop_bitmap);
  OptionalWhole(f[kDropped], "dropped_total", &r.dropped_total);
  OptionalString(f[kAddress], &r.address);
  OptionalString(f[kGateway], &r.gateway);
  OptionalString(f[kReceived], &r.received);
  return r;
}

/// DecodeReading's checks on a parsed JSON value (a record of a batch), from "an object" on.
std::optional<ReadingMessage> DecodeReadingValue(const json& j, std::string* error, ReadingIdentity& id) {
  if (!j.is_object()) {
    *error = "not a JSON object";
    return std::nullopt;
  }
  id.object = true;
  return DecodeFields(FieldsOf(j), error, id);
}

/// Size and nesting of a reading message, checked before it is parsed.
bool ReadingWithinLimits(std::string_view payload, std::string* error) {
  if (payload.size() > kMaxReadingBytes) {
    *error = "message of " + std::to_string(payload.size()) + " bytes (at most " + std::to_string(kMaxReadingBytes) + ")";
    return false;
  }
  if (JsonNestingDepth(payload) > kMaxReadingDepth) {
    *error = "JSON nested deeper than " + std::to_string(kMaxReadingDepth) + " levels";
    return false;
  }
  return true;
}

}  // namespace

std::optional<ReadingMessage> DecodeReading(std::string_view payload, std::string* error, ReadingIdentity* identity) {
  ReadingIdentity local;
  ReadingIdentity& id = identity ? *identity : local;
  id = {};
  if (!ReadingWithinLimits(payload, error)) return std::nullopt;
  // One SAX pass, no tree (docs/performance.md, *Ingest*: the tree was ~9 % of the server's CPU).
  ReadingFields fields;
  ReadingSax sax(&fields);
  if (!json::sax_parse(payload, &sax, json::input_format_t::json, /*strict=*/true, /*ignore_comments=*/false)) {
    *error = sax.error();
    if (sax.overflow()) IdentifyDespiteOverflow(payload, &id);  // so that the quarantined message can be acknowledged
    return std::nullopt;
  }
  if (!sax.object()) {
    *error = "not a JSON object";
    return std::nullopt;
  }
  id.object = true;
  return DecodeFields(fields, error, id);
}

// ---- batches of readings ----

std::string EncodeReadingBatch(const std::string& sensor, const std::vector<std::string_view>& records) {
  // The records are spooled texts, copied as they are: no parse, no re-encoding. Keys in sorted
  // order as every encoder here: "records" before "sensor".
  std::string out = "{\"records\":[";
  size_t bytes = out.size() + sensor.size() + 16;
  for (const std::string_view r : records) bytes += r.size() + 1;
  out.reserve(bytes);
  for (size_t i = 0; i < records.size(); ++i) {
    if (i) out += ',';
    out.append(records[i]);
  }
  out += "],\"sensor\":";
  out += Dump(json(sensor));
  out += '}';
  return out;
}

namespace {

/// The batch form's checks: calls `each(record)` for every element of "records", with the batch's
/// "sensor" added to an object naming none, in order. Returns as SplitReadingMessage does (false
/// with *error for a malformed batch; true without calling `each` for a one-record message).
template <typename Each>
bool ForEachBatchRecord(std::string_view payload, std::string* error, Each each) {
  // The one-record form (every message of a gateway that has not seen the server's announcement)
  // is not parsed here: DecodeReading does that once.
  if (payload.find("\"records\"") == std::string_view::npos) return true;
  if (payload.size() > kMaxReadingBytes || JsonNestingDepth(payload) > kMaxReadingDepth) return true;
  json j = json::parse(payload, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object()) return true;
  const auto list = j.find("records");
  if (list == j.end()) return true;  // "records" was text inside a string
  ReadingIdentity id;
  Identify(FieldsOf(j), &id);
  if (id.sensor.empty()) {
    *error = "batch: missing or invalid \"sensor\"";
    return false;
  }
  if (j.contains("seq")) {
    *error = "batch: both \"records\" and \"seq\" (a batch carries its seqs in its records)";
    return false;
  }
  if (!list->is_array() || list->empty() || list->size() > kMaxReadingBatch) {
    *error = "batch: \"records\" must be an array of 1 to " + std::to_string(kMaxReadingBatch) + " records, not " +
             (list->is_array() ? std::to_string(list->size()) + " records" : Describe(*list));
    return false;
  }
  for (json& r : *list) {
    if (r.is_object() && !r.contains("sensor")) r["sensor"] = id.sensor;
    each(r);
  }
  return true;
}

}  // namespace

bool SplitReadingMessage(std::string_view payload, std::vector<std::string>* records, std::string* error) {
  records->clear();
  return ForEachBatchRecord(payload, error, [&](const json& r) { records->push_back(Dump(r)); });
}

bool SplitAndDecodeReadingMessage(std::string_view payload, std::vector<BatchRecord>* records, std::string* error) {
  records->clear();
  return ForEachBatchRecord(payload, error, [&](const json& r) {
    BatchRecord& out = records->emplace_back();
    out.text = Dump(r);
    // What DecodeReading(out.text) finds, from the tree the text was made from: the text of a
    // record within a batch is never nested too deep and always parses back to this tree (a
    // parsed number prints back to the same number); only its size can exceed the limit (the
    // batch's "sensor" added to a one-record batch of nearly 64 KiB).
    if (ReadingWithinLimits(out.text, &out.error)) out.reading = DecodeReadingValue(r, &out.error, out.identity);
  });
}

// ---- commit ack ----

std::string EncodeCommitAck(const CommitAck& ack) {
  json j = {{"sensor", ack.sensor}, {"seqs", ack.seqs}, {"time", ack.time}};
  if (ack.batch != 0) j["batch"] = ack.batch;
  return Dump(j);
}

std::vector<std::string> EncodeCommitAcks(const CommitAck& ack) {
  std::vector<std::string> out;
  CommitAck part{ack.sensor, {}, ack.time, ack.batch};
  const size_t empty = EncodeCommitAck(part).size();
  if (empty + 10 > kMaxCommitAckBytes) return out;  // not even one seq fits
  size_t bytes = empty;
  for (const uint32_t seq : ack.seqs) {
    const size_t add = std::to_string(seq).size() + (part.seqs.empty() ? 0 : 1);  // digits and a comma
    if (part.seqs.size() == kMaxCommitAckSeqs || bytes + add > kMaxCommitAckBytes) {
      out.push_back(EncodeCommitAck(part));
      part.seqs.clear();
      bytes = empty;
    }
    bytes += std::to_string(seq).size() + (part.seqs.empty() ? 0 : 1);
    part.seqs.push_back(seq);
  }
  if (!part.seqs.empty() || out.empty()) out.push_back(EncodeCommitAck(part));
  return out;
}

std::optional<CommitAck> DecodeCommitAck(std::string_view payload, const std::string& topic_sensor, std::string* error) {
  auto parsed = ParseBoundedJson(payload, kMaxCommitAckBytes, kMaxCommitAckDepth, error);
  if (!parsed) return std::nullopt;
  const json& j = *parsed;
  if (!j.is_object()) {
    *error = "not a JSON object";
    return std::nullopt;
  }
  CommitAck ack;
  ack.sensor = topic_sensor;
  if (const auto it = j.find("sensor"); it != j.end()) {
    if (!it->is_string() && !it->is_number_unsigned()) {
      *error = "\"sensor\" must be a string";
      return std::nullopt;
    }
    const std::string named = it->is_string() ? it->get<std::string>() : std::to_string(it->get<uint64_t>());
    if (!topic_sensor.empty() && named != topic_sensor) {
      *error = "\"sensor\" " + named + " does not match the topic's sensor " + topic_sensor;
      return std::nullopt;
    }
    ack.sensor = named;
  }
  if (ack.sensor.empty()) {
    *error = "no sensor";
    return std::nullopt;
  }
  const auto seqs = j.find("seqs");
  if (seqs == j.end() || !seqs->is_array()) {
    *error = "\"seqs\" must be an array of sequence numbers";
    return std::nullopt;
  }
  if (seqs->size() > kMaxCommitAckSeqs) {
    *error = "\"seqs\" holds " + std::to_string(seqs->size()) + " sequence numbers (at most " +
             std::to_string(kMaxCommitAckSeqs) + ")";
    return std::nullopt;
  }
  for (const json& s : *seqs) {
    if (!s.is_number_unsigned() || s.get<uint64_t>() > 0xFFFFFFFFull) {
      *error = "\"seqs\" holds " + Describe(s) + ", not a 32-bit unsigned sequence number";
      return std::nullopt;
    }
    ack.seqs.push_back(static_cast<uint32_t>(s.get<uint64_t>()));
  }
  // The time is informative: the gateway acts on the seqs whatever it says.
  if (const auto t = j.find("time"); t != j.end() && t->is_string()) ack.time = t->get<std::string>();
  // An announcement the gateway cannot read is no announcement: the one-record form stays.
  if (const auto b = j.find("batch"); b != j.end() && b->is_number_unsigned() && b->get<uint64_t>() <= 0xFFFFFFFFull) {
    ack.batch = static_cast<uint32_t>(b->get<uint64_t>());
  }
  return ack;
}

// ---- gateway status ----

std::string EncodeStatus(const StatusMessage& s) {
  return Dump({{"state", s.online ? "online" : "offline"}, {"gateway", s.gateway}, {"time", s.time}});
}

std::optional<StatusMessage> DecodeStatus(std::string_view payload, std::string* error) {
  const auto j = ParseObject(payload, error);
  if (!j) return std::nullopt;
  Fields f(*j, error);
  StatusMessage s;
  std::string state;
  if (!f.String("state", &state) || !f.String("gateway", &s.gateway) || !f.String("time", &s.time)) return std::nullopt;
  if (state != "online" && state != "offline") {
    f.Wrong("state", "\"online\" or \"offline\"");
    return std::nullopt;
  }
  s.online = state == "online";
  return s;
}

// ---- gateway stats ----

std::string EncodeStats(const StatsMessage& s) {
  json j(s.counters);
  j["gateway"] = s.gateway;
  j["time"] = s.time;
  j["publish_latency_ms"] = {{"last", s.latency_last_ms}, {"max", s.latency_max_ms}, {"mean", s.latency_mean_ms}};
  return Dump(j);
}

std::optional<StatsMessage> DecodeStats(std::string_view payload, std::string* error) {
  const auto j = ParseObject(payload, error);
  if (!j) return std::nullopt;
  Fields f(*j, error);
  StatsMessage s;
  if (!f.String("gateway", &s.gateway) || !f.String("time", &s.time)) return std::nullopt;
  const auto latency = j->find("publish_latency_ms");
  if (latency == j->end() || !latency->is_object()) {
    f.Wrong("publish_latency_ms", "an object");
    return std::nullopt;
  }
  Fields l(*latency, error);
  if (!l.Integer("last", -1, INT64_MAX, &s.latency_last_ms) || !l.Integer("max", -1, INT64_MAX, &s.latency_max_ms) ||
      !l.Integer("mean", -1, INT64_MAX, &s.latency_mean_ms)) {
    return std::nullopt;
  }
  for (const auto& [name, value] : j->items()) {
    if (value.is_number_unsigned()) s.counters[name] = value.get<uint64_t>();
  }
  return s;
}

// ---- device registry ----

std::string EncodeDevice(const DeviceMessage& d) {
  json j = {{"gateway", d.gateway}, {"time", d.time}, {"address", d.address}, {"first_seen", d.first_seen}};
  if (d.node_identifier) j["node_identifier"] = *d.node_identifier;
  if (d.device_type) j["device_type"] = *d.device_type;
  j["sensors"] = d.sensors;
  return Dump(j);
}

std::optional<DeviceMessage> DecodeDevice(std::string_view payload, std::string* error) {
  const auto j = ParseObject(payload, error);
  if (!j) return std::nullopt;
  Fields f(*j, error);
  DeviceMessage d;
  const json* sensors = nullptr;
  if (!f.String("gateway", &d.gateway) || !f.String("time", &d.time) || !f.String("address", &d.address) ||
      !f.String("first_seen", &d.first_seen) || !f.Array("sensors", &sensors) ||
      !f.String("node_identifier", &d.node_identifier) || !f.Integer("device_type", &d.device_type)) {
    return std::nullopt;
  }
  for (const json& s : *sensors) {
    if (!s.is_string()) {
      f.Wrong("sensors", "an array of sensor ids");
      return std::nullopt;
    }
    d.sensors.push_back(s.get<std::string>());
  }
  return d;
}

// ---- wear ----

std::string EncodeWear(const nlohmann::ordered_json& summary) {
  return summary.dump();
}

std::optional<WearMessage> DecodeWear(std::string_view payload, std::string* error) {
  if (!ParseObject(payload, error, kMaxWearBytes)) return std::nullopt;
  WearMessage w;
  w.summary = nlohmann::ordered_json::parse(payload);
  // Fields reads a json; the ordered copy is kept for the caller.
  const json j = json::parse(payload);
  Fields f(j, error);
  const json* rows = nullptr;
  const json* used = nullptr;
  if (!f.String("crusher_id", &w.crusher_id) || !f.String("time", &w.time) || !f.String("map_sha256", &w.map_sha256) ||
      !f.NumberOrNull(j, "min_thickness_mm", &w.min_thickness_mm) || !f.Array("rows", &rows) ||
      !f.Array("readings_used", &used)) {
    return std::nullopt;
  }
  for (const json& r : *rows) {
    WearMessage::Row row;
    if (!r.is_object()) {
      f.Wrong("rows", "an array of objects");
      return std::nullopt;
    }
    Fields rf(r, error);
    if (!rf.String("row", &row.row) || !rf.NumberOrNull(r, "min_thickness_mm", &row.min_thickness_mm)) return std::nullopt;
    w.rows.push_back(std::move(row));
  }
  for (const json& u : *used) {
    WearMessage::Used one;
    if (!u.is_object()) {
      f.Wrong("readings_used", "an array of objects");
      return std::nullopt;
    }
    Fields uf(u, error);
    if (!uf.String("sensor", &one.sensor) || !uf.Integer("seq", 0, 0xFFFFFFFFLL, &one.seq) || !uf.String("time", &one.time) ||
        !uf.Number("thickness_mm", &one.thickness_mm)) {
      return std::nullopt;
    }
    w.readings_used.push_back(std::move(one));
  }
  return w;
}

}  // namespace lw::mqtt
