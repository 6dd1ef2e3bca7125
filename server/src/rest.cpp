#include "server/rest.hpp"

#include <stdlib.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "core/clock.hpp"
#include "core/csv.hpp"
#include "core/time.hpp"
#include "core/wear_map.hpp"
#include "mqtt/messages.hpp"
#include "server/csv_export.hpp"
#include "estimate/plan.hpp"
#include "server/openapi.hpp"
#include "rest_schemas.hpp"

namespace lw::server::rest {
namespace {

using nlohmann::ordered_json;

Response Json(int status, ordered_json body) {
  Response r;
  r.status = status;
  r.json = std::move(body);
  return r;
}

/// The fields of a sensor's stored reading as JSON (without its sensor id), in order, given to `out`:
/// "previous_liner": true when it is a previous liner's (before installed_at, or worn in the day of
/// slack before it: core's OfThisLiner), which live wear leaves out (docs/server.md, Relining). One
/// list of fields for the two writers below.
template <typename Out>
void ReadingFields(const core::CrusherConfig& config, const StoredReading& r, Out& out) {
  out.Text("time", core::FormatIsoSeconds(r.time_s));
  out.Int("seq", r.seq);
  out.Real("thickness_mm", r.thickness_mm);
  out.Int("loops_intact", r.loops_intact);
  out.Int("flags", r.flags);
  out.Int("battery_mv", r.battery_mv);
  out.Text("received", core::FormatIsoSeconds(r.received_s));
  if (!config.OfThisLiner(r.sensor, core::FromUnixSeconds(r.time_s), r.thickness_mm)) out.True("previous_liner");
}

/// A reading's fields into a JSON tree (a sensor's latest reading; the CSV export).
struct ReadingTree {
  ordered_json o = ordered_json::object();
  void Text(const char* key, std::string value) { o[key] = std::move(value); }
  void Int(const char* key, int64_t value) { o[key] = value; }
  void Real(const char* key, double value) { o[key] = value; }
  void True(const char* key) { o[key] = true; }
};

/// A reading's fields written as compact JSON text, the bytes `ordered_json::dump()` gives for the
/// same tree: a readings page is written directly, because building and freeing a tree per reading
/// was about a fifth of the page's server CPU (docs/performance.md). The texts written are ISO times,
/// which hold no character JSON escapes.
class ReadingText {
 public:
  explicit ReadingText(std::string* out) : out_(out) {}
  void Text(const char* key, const std::string& value) {
    Key(key);
    *out_ += '"';
    *out_ += value;
    *out_ += '"';
  }
  void Int(const char* key, int64_t value) {
    Key(key);
    char buf[24];
    out_->append(buf, std::to_chars(buf, buf + sizeof buf, value).ptr);
  }
  void Real(const char* key, double value) {
    Key(key);
    if (!std::isfinite(value)) {
      *out_ += "null";  // as dump() writes it
      return;
    }
    char buf[64];  // nlohmann's own shortest round-trip form (what dump() calls), so "100.0" stays "100.0"
    out_->append(buf, nlohmann::detail::to_chars(buf, buf + sizeof buf, value));
  }
  void True(const char* key) {
    Key(key);
    *out_ += "true";
  }
  void Close() { *out_ += first_ ? "{}" : "}"; }

 private:
  void Key(const char* key) {
    *out_ += first_ ? "{\"" : ",\"";
    first_ = false;
    *out_ += key;
    *out_ += "\":";
  }
  std::string* out_;
  bool first_ = true;
};

ordered_json SensorReadingJson(const core::CrusherConfig& config, const StoredReading& r) {
  ReadingTree tree;
  ReadingFields(config, r, tree);
  return std::move(tree.o);
}

ordered_json RowsJson(const core::CrusherConfig& config) {
  ordered_json rows = ordered_json::array();
  for (const auto& r : config.rows) rows.push_back({{"name", r.name}, {"z_min_m", r.z_min_m}, {"z_max_m", r.z_max_m}});
  return rows;
}

}  // namespace

const char* MethodName(Method method) {
  return method == Method::kGet ? "GET" : "POST";
}

const char* ScopeName(Scope scope) {
  switch (scope) {
    case Scope::kNone:
      return "none";
    case Scope::kRead:
      return "read";
    case Scope::kWrite:
      return "write";
  }
  return "none";
}

bool Writes(std::string_view method) {
  return method != "GET" && method != "HEAD";
}

Scope RequiredScope(std::string_view method, std::string_view path) {
  if (path == "/metrics") return Scope::kRead;  // counts and names of crushers: not for anyone on the network
  if (path.rfind("/api/", 0) != 0) return Scope::kNone;
  return Writes(method) ? Scope::kWrite : Scope::kRead;
}

namespace {
/// Whether `path` matches `path_template` segment by segment, {name} matching one non-empty
/// segment: what PathPattern's regular expression matches, without building one per request.
/// `args` (when given) receives the segments the {name}s matched.
bool PathMatches(std::string_view path_template, std::string_view path, std::vector<std::string>* args = nullptr) {
  size_t t = 0, p = 0;
  while (t < path_template.size()) {
    if (path_template[t] == '{') {
      const size_t close = path_template.find('}', t);
      const size_t end = std::min(path.find('/', p), path.size());
      if (close == std::string_view::npos || end == p) return false;
      if (args) args->emplace_back(path.substr(p, end - p));
      t = close + 1;
      p = end;
      continue;
    }
    if (p >= path.size() || path[p] != path_template[t]) return false;
    ++t;
    ++p;
  }
  return p == path.size();
}
}  // namespace

RouteMatch MatchRoute(std::string_view method, std::string_view path) {
  RouteMatch m;
  const std::string_view as = method == "HEAD" ? std::string_view("GET") : method;
  for (const Route& r : Resources::Routes()) {
    if (!PathMatches(r.path, path)) continue;
    m.path_known = true;
    if (as == MethodName(r.method)) {
      m.route = &r;
      PathMatches(r.path, path, &m.args);
      break;
    }
  }
  return m;
}

Response Error(int status, const std::string& message) {
  return Json(status, {{"error", message}});
}

std::vector<std::string> PathParams(std::string_view path_template) {
  std::vector<std::string> names;
  for (size_t open = path_template.find('{'); open != std::string_view::npos; open = path_template.find('{', open + 1)) {
    const size_t close = path_template.find('}', open);
    if (close == std::string_view::npos)
      throw std::invalid_argument("path template '" + std::string(path_template) + "': unclosed {");
    names.emplace_back(path_template.substr(open + 1, close - open - 1));
  }
  return names;
}

std::string PathPattern(std::string_view path_template) {
  std::string out;
  for (size_t i = 0; i < path_template.size(); ++i) {
    if (path_template[i] != '{') {
      out += path_template[i];
      continue;
    }
    const size_t close = path_template.find('}', i);
    if (close == std::string_view::npos)
      throw std::invalid_argument("path template '" + std::string(path_template) + "': unclosed {");
    out += "([^/]+)";
    i = close;
  }
  return out;
}

std::optional<std::string> EventStream::Next(const std::function<bool()>& client_gone) {
  if (stopping_ || events_.closed()) return std::nullopt;
  if (first_) {
    first_ = false;
    return std::string("retry: 3000\n: connected\n\n");
  }
  // Wait up to 15 s for events (then a keepalive), but look every second whether the client
  // is still there: a closed stream frees its slot and its worker at once.
  std::vector<Event> events;
  for (int waited = 0; waited < 15 && events.empty(); ++waited) {
    if (Expired()) return std::nullopt;
    events = events_.WaitAfter(&after_, crusher_, std::chrono::milliseconds(1000));
    if (stopping_ || events_.closed()) return std::nullopt;
    if (events.empty() && client_gone && client_gone()) return std::nullopt;
  }
  std::string out;
  if (events.empty()) out = ": keepalive\n\n";
  for (const Event& e : events) out += "id: " + std::to_string(e.id) + "\nevent: " + e.name + "\ndata: " + e.data + "\n\n";
  return out;
}

/// OpenAPI schemas of the campaign routes (docs/campaigns.md).
constexpr const char* kSensorSchema =
    R"j({"type":"object","required":["id","row","z_m","theta_deg"],"properties":{"id":{"type":"string"},)j"
    R"j("row":{"type":"string"},"z_m":{"type":"number"},"theta_deg":{"type":"number"},"thickness_new_mm":{"type":"number"},)j"
    R"j("address":{"type":"string","description":"64-bit radio address, hex"}}})j";
const std::string kRelineRequestSchema =
    std::string(R"j({"type":"object","required":["time","thickness_new_mm"],"additionalProperties":false,"properties":{)j") +
    R"j("time":{"type":"string","format":"date-time","description":"the reline: the old liner's end, the new one's start"},)j" +
    R"j("thickness_new_mm":{"type":"number","description":"the new liner's thickness"},)j" +
    R"j("scan_xyz":{"type":"string","description":"the old liner's end-of-life scan: one 'x y z' line per point (metres)"},)j" +
    R"j("sensors":{"type":"array","minItems":1,"description":"the new sensor layout (default: the same, at the new thickness)","items":)j" +
    kSensorSchema + "}}}";
const std::string kCampaignSchema =
    std::string(R"j({"type":"object","required":["start","end","thickness_new_mm","has_scan"],"properties":{)j") +
    R"j("start":{"type":"string","format":"date-time"},"end":{"type":"string","format":"date-time","nullable":true},)j" +
    R"j("running":{"type":"boolean"},"thickness_new_mm":{"type":"number"},"has_scan":{"type":"boolean"},)j" +
    R"j("life_days":{"type":"number","nullable":true,"description":"start to end (the running one: to now; a voided one: null)"},"sensor_count":{"type":"integer"},)j" +
    R"j("sensors":{"type":"array","items":)j" + kSensorSchema +
    R"j(},"final_readings":{"type":"array","items":{"type":"object","properties":{"sensor":{"type":"string"},)j" +
    R"j("time":{"type":"string","format":"date-time"},"thickness_mm":{"type":"number"},"seq":{"type":"integer"}}}},)j" +
    R"j("voided":{"type":"boolean","description":"a reline posted by mistake, voided: kept, never counted"},)j" +
    R"j("voided_at":{"type":"string","format":"date-time"},"voided_by":{"type":"string","description":"the token's name"},)j" +
    R"j("void_reason":{"type":"string"}}})j";
const std::string kVoidRequestSchema =
    R"j({"type":"object","additionalProperties":false,"properties":{"reason":{"type":"string","maxLength":1000}}})j";
const std::string kCampaignListSchema =
    R"j({"type":"object","required":["campaigns"],"properties":{"campaigns":{"type":"array","items":)j" + kCampaignSchema + "}}}";
const std::string kSettingCheckRequestSchema =
    std::string(R"j({"type":"object","required":["time","css_mm"],"additionalProperties":false,"properties":{)j") +
    R"j("time":{"type":"string","format":"date-time","description":"when the setting was measured"},)j" +
    R"j("css_mm":{"type":"number","minimum":0,"exclusiveMinimum":true,"maximum":1000,"description":"the closed-side setting measured, mm"},)j" +
    R"j("note":{"type":"string","maxLength":1000}}})j";
const std::string kSettingCheckSchema =
    std::string(
        R"j({"type":"object","required":["time","css_mm","opening_mm","opening_supported","counts","by","note","recorded"],"properties":{)j") +
    R"j("time":{"type":"string","format":"date-time"},"css_mm":{"type":"number"},)j" +
    R"j("opening_mm":{"type":"number","nullable":true,"description":"the concave's opening since installation estimated at that time from the readings stored now (null: not known)"},)j" +
    R"j("opening_supported":{"type":"boolean","description":"false: opening_mm is the central estimate of a discharge ring not supported then"},)j" +
    R"j("counts":{"type":"boolean","description":"measured on the running liner (a check before its installation does not count)"},)j" +
    R"j("by":{"type":"string","description":"the token's name"},"note":{"type":"string"},)j" +
    R"j("recorded":{"type":"string","format":"date-time"}}})j";
const std::string kSettingCheckListSchema =
    R"j({"type":"object","required":["checks"],"properties":{"checks":{"type":"array","items":)j" + kSettingCheckSchema + "}}}";

// linerwatch plan's JSON (docs/plan.md); numbers may be null where a band is not defined.
const char* const kPlanSchema =
    R"j({"type":"object","required":["sensors","expected_band_mm","liner_band_mm","rows","candidates","objective"],)j"
    R"j("properties":{"sensors":{"type":"array","items":{"type":"object","required":["row","z_m","theta_deg"],)j"
    R"j("properties":{"row":{"type":"string"},"z_m":{"type":"number","nullable":true},)j"
    R"j("theta_deg":{"type":"number","nullable":true},"keeps":{"type":"string","nullable":true}}}},)j"
    R"j("expected_band_mm":{"type":"object","properties":{"current":{"type":"number","nullable":true},"proposed":{"type":"number","nullable":true}}},)j"
    R"j("liner_band_mm":{"type":"object","properties":{"current":{"type":"number","nullable":true},"proposed":{"type":"number","nullable":true}}},)j"
    R"j("rows":{"type":"array","items":{"type":"object","required":["row","sensors","band_mm"],"properties":{)j"
    R"j("row":{"type":"string"},"sensors":{"type":"object","properties":{"current":{"type":"integer"},)j"
    R"j("proposed":{"type":"integer"}}},"band_mm":{"type":"object","properties":{"current":{"type":"number","nullable":true},)j"
    R"j("proposed":{"type":"number","nullable":true}}}}}},)j"
    R"j("compared_on":{"type":"object","properties":{"shape":{"type":"string","enum":["row","square"]},)j"
    R"j("patch_m":{"type":"number","nullable":true}}},"candidates":{"type":"integer"},"objective":{"type":"string"},)j"
    R"j("scan_now":{"type":"object","nullable":true,"additionalProperties":true}}})j";

/// OpenAPI schemas of the alarm routes (docs/alarms.md).
const std::string kAlarmSchema =
    std::string(R"j({"type":"object","required":["id","rule","subject","severity","state","since","detail"],"properties":{)j") +
    R"j("id":{"type":"integer"},"rule":{"type":"string"},"subject":{"type":"string"},)j" +
    R"j("severity":{"type":"string","enum":["info","warning","critical"]},)j" +
    R"j("state":{"type":"string","enum":["active","acknowledged","cleared"]},"since":{"type":"string","format":"date-time"},)j" +
    R"j("detail":{"type":"string"},"value":{"type":"number","nullable":true},"threshold":{"type":"number","nullable":true},)j" +
    R"j("acknowledged_at":{"type":"string","format":"date-time","nullable":true},)j" +
    R"j("acknowledged_by":{"type":"string","nullable":true},"cleared_at":{"type":"string","format":"date-time","nullable":true},)j" +
    R"j("audit":{"type":"array","items":{"type":"object","properties":{"time":{"type":"string","format":"date-time"},)j" +
    R"j("action":{"type":"string"},"by":{"type":"string"},"detail":{"type":"string"}}}}}})j";
const std::string kAlarmListSchema =
    R"j({"type":"object","required":["alarms"],"properties":{"alarms":{"type":"array","items":)j" + kAlarmSchema + "}}}";

namespace {
// Statuses several handlers share.
constexpr StatusDoc kStarting = {"503",
                                 "the server is starting: the crusher is not loaded (or its wear not computed) yet; "
                                 "Retry-After: 2"};
constexpr StatusDoc kReadOnly = {"503", "not kept by this server (it serves read-only: its disk is full)"};
constexpr StatusDoc kBadQuery = {"400", "a query parameter is malformed or out of range (the message names it)"};
constexpr const char* kJson = "application/json";
}  // namespace

/// The routes of liveness, crushers, sensors, readings and the mesh (in the order of the document).
std::vector<Route> Resources::ReadingRoutes() {
  using namespace schemas;  // NOLINT: the schema constants, by their short names
  return {
      {Method::kGet,
       "/healthz",
       "Liveness: database and broker state",
       {},
       "200",
       &Resources::Health,
       {kJson},
       kSmallBodyBytes,
       nullptr,
       kHealth.c_str(),
       {{"503", "degraded: the database cannot be read or its disk is full (the same body as 200)", kHealth.c_str()}}},
      {Method::kGet,
       "/api/v1/crushers",
       "Crushers with their latest minimum thickness",
       {},
       "200",
       &Resources::Crushers,
       {kJson},
       kSmallBodyBytes,
       nullptr,
       kCrusherList.c_str()},
      {Method::kGet,
       "/api/v1/crushers/{crusher}",
       "Crusher geometry, sensors, map hash and counters",
       {},
       "200",
       &Resources::CrusherDetail,
       {kJson},
       kSmallBodyBytes,
       nullptr,
       kCrusherDetail.c_str(),
       {kStarting}},
      {Method::kGet,
       "/api/v1/crushers/{crusher}/sensors",
       "Latest reading of each sensor",
       {},
       "200",
       &Resources::Sensors,
       {kJson},
       kSmallBodyBytes,
       nullptr,
       kSensorList.c_str(),
       {kStarting}},
      {Method::kGet,
       "/api/v1/crushers/{crusher}/sensors/{sensor}/readings",
       "Readings of one sensor, oldest first, paged with cursors",
       {{"from", "string", "ISO-8601 UTC, inclusive"},
        {"to", "string", "ISO-8601 UTC, inclusive"},
        {"limit", "integer", "1..5000, default 500"},
        {"cursor", "string", "next_cursor of the previous page"},
        {"format",
         "string",
         "json (default) or csv (RFC 4180; the next page's cursor in the X-Next-Cursor header)",
         {"json", "csv"}}},
       "200",
       &Resources::Readings,
       {kJson, "text/csv"},
       kSmallBodyBytes,
       nullptr,
       kReadingsPage.c_str(),
       {kBadQuery, {"404", "unknown sensor of the crusher"}}},
      {Method::kPost,
       "/api/v1/crushers/{crusher}/readings",
       "Store readings {\"readings\": [{sensor, seq, time, thickness_mm, loops_intact, flags, battery_mv}]}",
       {},
       "200",
       &Resources::PostReadings,
       {kJson},
       kMaxReadingsBodyBytes,
       kPostReadingsRequest.c_str(),
       kPostReadingsResult.c_str(),
       {{"400", "the body is not {\"readings\": [...]} JSON, or is nested too deeply"},
        {"413", "more than 10000 readings"},
        {"422", "no reading was taken: each was rejected or held (what happened to each, and why)",
         kPostReadingsNoneTaken.c_str()},
        {"503", "not stored: the database refused the batch (or the server serves read-only)"}}},
      {Method::kGet,
       "/api/v1/crushers/{crusher}/mesh",
       "As-new liner mesh: points, faces, face z and theta",
       {},
       "200",
       &Resources::Mesh,
       {kJson},
       kSmallBodyBytes,
       nullptr,
       kMesh.c_str()},
  };
}

/// The routes of wear, forecast, diagnosis and liner campaigns.
std::vector<Route> Resources::WearRoutes() {
  using namespace schemas;  // NOLINT: the schema constants, by their short names
  return {
      {Method::kGet,
       "/api/v1/crushers/{crusher}/wear",
       "Global wear (seed Eq. 9): per-face remaining thickness, per-row summary, minimum and where",
       {{"format", "string", "json (default), vtk (legacy VTK for ParaView) or csv (per face)", {"json", "vtk", "csv"}},
        {"faces", "boolean", "false: leave out the per-face array"},
        {"at", "string",
         "ISO-8601 UTC: the wear at that past time, from the readings and scans up to it (400 before installed_at, in the "
         "future or malformed; docs/server.md, Wear at a past time)"}},
       "200",
       &Resources::Wear,
       {kJson, "application/octet-stream", "text/csv"},
       kSmallBodyBytes,
       nullptr,
       kWear.c_str(),
       {{"400", "format is not json, vtk or csv; at is malformed, before installed_at or in the future"},
        {"404", "no readings yet (or none at or before at=)"},
        {"500", "the VTK file cannot be made"},
        kStarting}},
      {Method::kGet,
       "/api/v1/crushers/{crusher}/forecast",
       "Per row and sensor: the date the minimum thickness is reached, with a band",
       {{"format", "string", "json (default) or csv (RFC 4180: one record per row, then per sensor)", {"json", "csv"}},
        {"at", "string",
         "ISO-8601 UTC: the forecast made from the readings and scans up to that past time (the same rules as .../wear?at=)"}},
       "200",
       &Resources::Forecast,
       {kJson, "text/csv"},
       kSmallBodyBytes,
       nullptr,
       kForecast.c_str(),
       {{"400", "format is not json or csv; at is malformed, before installed_at or in the future"},
        {"404", "no readings yet (or none at or before at=)"},
        kStarting}},
      {Method::kGet,
       "/api/v1/crushers/{crusher}/diagnosis",
       "Latest diagnosis (docs/diagnosis.md, section Output) and its status",
       {},
       "200",
       &Resources::Diagnosis,
       {kJson},
       kSmallBodyBytes,
       nullptr,
       kDiagnosis.c_str(),
       {kReadOnly}},
      {Method::kPost,
       "/api/v1/crushers/{crusher}/diagnosis",
       "Start a diagnosis on the stored readings",
       {},
       "202",
       &Resources::StartDiagnosis,
       {kJson},
       kSmallBodyBytes,
       nullptr,
       kDiagnosisStarted.c_str(),
       {{"409", "a diagnosis of the crusher is already running"}, kReadOnly}},
      {Method::kPost,
       "/api/v1/crushers/{crusher}/relines",
       "Reline: close the running liner campaign (its end-of-life scan and last readings kept) and start the next "
       "(201; the same time again returns the campaign it started, 200)",
       {},
       "201",
       &Resources::PostReline,
       {kJson},
       kMaxRelineBodyBytes,
       kRelineRequestSchema.c_str(),
       kCampaignSchema.c_str(),
       {{"200", "already stored: the campaign this time started", kCampaignSchema.c_str()},
        {"400", "the body is not the reline object (the message names the field)"},
        {"409", "a campaign already starts at this time with other values"},
        {"422",
         "a value that does not fit: a thickness not above the minimum, a time not after the running campaign's "
         "start or in the future, a scan or sensors the crusher cannot have"},
        {"500", "not stored: the database refused it"},
        kReadOnly}},
      {Method::kGet,
       "/api/v1/crushers/{crusher}/campaigns",
       "The crusher's liner campaigns, oldest first (end null for the running one)",
       {},
       "200",
       &Resources::CampaignList,
       {kJson},
       kSmallBodyBytes,
       nullptr,
       kCampaignListSchema.c_str(),
       {kReadOnly}},
      {Method::kPost,
       "/api/v1/crushers/{crusher}/relines/{time}/void",
       "Void the reline at {time} (posted by mistake): its campaign is kept, marked voided by the token's name, and "
       "the campaign it closed runs again (a void again: 200, unchanged)",
       {},
       "200",
       &Resources::VoidReline,
       {kJson},
       kSmallBodyBytes,
       kVoidRequestSchema.c_str(),
       kCampaignSchema.c_str(),
       {{"400", "{time} is not an ISO-8601 UTC time, or the body is not {\"reason\"}"},
        {"404", "no reline of the crusher at {time}"},
        {"409", "the campaign from {time} is not the running one (void the later relines first) or began with no reline"},
        {"500", "not stored: the database refused it"},
        kReadOnly}},
      {Method::kPost,
       "/api/v1/crushers/{crusher}/setting/checks",
       "Record the closed-side setting measured on the crusher (after raising the mantle, say): live wear counts the "
       "setting and the setting_open alarm from it (201; the same again, 200)",
       {},
       "201",
       &Resources::PostSettingCheck,
       {kJson},
       kSmallBodyBytes,
       kSettingCheckRequestSchema.c_str(),
       kSettingCheckSchema.c_str(),
       {{"200", "already stored: the same setting at this time", kSettingCheckSchema.c_str()},
        {"400", "the body is not the setting object (the message names the field)"},
        {"409", "another setting is recorded at this time"},
        {"422", "a time in the future or before the liner's installation, or a setting out of range"},
        {"500", "not stored: the database refused it"},
        kReadOnly}},
      {Method::kGet,
       "/api/v1/crushers/{crusher}/setting/checks",
       "The closed-side settings measured on the crusher, oldest first (every liner's)",
       {},
       "200",
       &Resources::SettingCheckList,
       {kJson},
       kSmallBodyBytes,
       nullptr,
       kSettingCheckListSchema.c_str(),
       {kReadOnly}},
  };
}

/// The routes of alarms, the sensor plan, events, the quarantine, the caller, this document and metrics.
std::vector<Route> Resources::AlarmAndServiceRoutes() {
  using namespace schemas;  // NOLINT: the schema constants, by their short names
  return {
      {Method::kGet,
       "/api/v1/crushers/{crusher}/alarms",
       "Alarms of the crusher, newest first: the open ones (active, acknowledged) and those cleared in the last 7 days, "
       "each with its audit trail (docs/alarms.md)",
       {{"state", "string", "active, acknowledged or cleared: only alarms in that state", {"active", "acknowledged", "cleared"}},
        {"limit", "integer", "1..1000, default 100"}},
       "200",
       &Resources::AlarmList,
       {kJson},
       kSmallBodyBytes,
       nullptr,
       kAlarmListSchema.c_str(),
       {{"400", "state is not active, acknowledged or cleared; limit is not 1..1000"}, kReadOnly}},
      {Method::kPost,
       "/api/v1/crushers/{crusher}/alarms/{id}/ack",
       "Acknowledge an alarm (the token's name and the time are kept; an acknowledged one again: 200, unchanged; "
       "a cleared one: 409; an unknown id: 404)",
       {},
       "200",
       &Resources::AckAlarm,
       {kJson},
       kSmallBodyBytes,
       nullptr,
       kAlarmSchema.c_str(),
       {{"404", "unknown alarm of the crusher"}, {"409", "the alarm is cleared: nothing to acknowledge"}, kReadOnly}},
      {Method::kGet,
       "/api/v1/crushers/{crusher}/alarms/rules",
       "The alarm rules in force: crusher.json's \"alarms\" with the changes made over REST (docs/alarms.md)",
       {},
       "200",
       &Resources::AlarmRules,
       {kJson},
       kSmallBodyBytes,
       nullptr,
       kAlarmRules.c_str(),
       {kReadOnly}},
      {Method::kPost,
       "/api/v1/crushers/{crusher}/alarms/rules",
       "Change alarm rules: an \"alarms\" object as in crusher.json, only the keys given change (400 naming a bad key)",
       {},
       "200",
       &Resources::SetAlarmRules,
       {kJson},
       kSmallBodyBytes,
       kAlarmRulesRequest.c_str(),
       kAlarmRules.c_str(),
       {{"400",
         "the body is not JSON or is nested too deeply, or names a rule or setting that does not exist or a value out "
         "of range"},
        kReadOnly}},
      {Method::kGet,
       "/api/v1/crushers/{crusher}/plan",
       "Where to cast the next liner's sensors, the expected band of each layout, and what a scan now would do "
       "(linerwatch plan, docs/plan.md)",
       {{"sensors", "integer", "K, how many sensors the next liner gets (required, 1..100)"}},
       "200",
       &Resources::Plan,
       {kJson},
       kSmallBodyBytes,
       nullptr,
       kPlanSchema,
       {{"400", "sensors is missing or not 1..100"}, {"422", "more sensors than the rows have places for"}}},
      {Method::kGet,
       "/api/v1/crushers/{crusher}/events",
       "Server-Sent Events: `reading` and `wear` as they are committed",
       {{"access_token", "string", "the bearer token (EventSource cannot set headers)"}},
       "200",
       &Resources::Events,
       {"text/event-stream"},
       kSmallBodyBytes,
       nullptr,
       nullptr,
       {{"503", "too many open event streams (on the server, or from this address); retry later"}}},
      {Method::kGet,
       "/api/v1/rejected",
       "Quarantined messages that failed validation, newest first",
       {{"limit", "integer", "1..1000, default 100"}},
       "200",
       &Resources::RejectedList,
       {kJson},
       kSmallBodyBytes,
       nullptr,
       kRejectedList.c_str(),
       {{"400", "limit is not 1..1000"}}},
      {Method::kGet,
       "/api/v1/whoami",
       "The caller's token name and scopes ({auth: false} on an open server)",
       {},
       "200",
       &Resources::WhoAmI,
       {kJson},
       kSmallBodyBytes,
       nullptr,
       kWhoAmI.c_str()},
      {Method::kGet,
       "/api/v1/openapi.json",
       "This document",
       {},
       "200",
       &Resources::OpenApi,
       {kJson},
       kSmallBodyBytes,
       nullptr,
       kOpenApi.c_str()},
      {Method::kGet,
       "/metrics",
       "Prometheus text format 0.0.4: ingest, wear worker, HTTP, event streams, store (docs/server.md, Metrics)",
       {},
       "200",
       &Resources::Metrics,
       {"text/plain"}},
  };
}

const std::vector<Route>& Resources::Routes() {
  static const std::vector<Route> routes = [] {
    std::vector<Route> all;
    for (std::vector<Route> (*group)() : {&ReadingRoutes, &WearRoutes, &AlarmAndServiceRoutes}) {
      for (Route& r : group()) all.push_back(std::move(r));
    }
    return all;
  }();
  return routes;
}

const Route& Resources::Find(Method method, std::string_view path_template) {
  for (const Route& r : Routes()) {
    if (r.method == method && r.path == path_template) return r;
  }
  throw std::out_of_range(std::string("no route ") + MethodName(method) + " " + std::string(path_template));
}

Resources::Resources(const ApiContext& context)
    : ctx_(context), max_event_streams_(static_cast<int>(std::max<size_t>(1, context.limits.workers / 2))) {}

const Crusher* Resources::CrusherOf(const Request& request, Response* error) const {
  const std::string id = request.path.empty() ? std::string() : request.path[0];
  const Crusher* c = ctx_.registry->Find(id);
  if (!c) *error = Error(404, "unknown crusher '" + id + "'");
  return c;
}

Response Resources::Health(const Request&) {
  ordered_json j = {{"status", "ok"}, {"version", "0.1.0"}};
  try {
    ctx_.read->With([](Store& s) { return s.CountRejected(); });
    j["db"] = "ok";
  } catch (const std::exception& e) {
    j["status"] = "degraded";
    j["db"] = e.what();
  }
  if (ctx_.health) {
    const ordered_json extra = ctx_.health();
    for (const auto& [k, v] : extra.items()) j[k] = v;
  }
  const int status = j["status"] == "ok" ? 200 : 503;
  return Json(status, std::move(j));
}

ordered_json Resources::ListEntryJson(const Crusher& c, const CrusherState* st, bool loaded, std::optional<int64_t> latest) {
  return {{"crusher_id", c.config.crusher_id},
          {"installed_at", core::FormatIsoTime(c.config.installed_at)},
          {"thickness_new_mm", c.config.thickness_new_mm},
          {"thickness_min_mm", c.config.thickness_min_mm},
          {"rows", RowsJson(c.config)},
          {"sensor_count", c.config.sensors.size()},
          {"map_sha256", c.map.sha256},
          {"face_count", c.map.face_count()},
          {"latest_reading_time", latest ? ordered_json(core::FormatIsoSeconds(*latest)) : ordered_json(nullptr)},
          {"min_thickness_mm", st && st->has_wear && std::isfinite(st->reconstruction.min_thickness_mm)
                                   ? ordered_json(st->reconstruction.min_thickness_mm)
                                   : ordered_json(nullptr)},
          {"wear_status", st && st->has_wear ? ordered_json(st->reconstruction.status) : ordered_json(nullptr)},
          {"thinnest_area", st && st->has_wear ? core::ThinnestAreaJson(st->areas.liner) : ordered_json(nullptr)},
          {"pending", !loaded || !st}};
}

Response Resources::Crushers(const Request&) {
  // The bytes ordered_json's compact dump gives for {"crushers": [entries]}: each entry's text is
  // kept from the request before while what it shows is unchanged, because building and dumping
  // 100 entries' JSON was the list's cost (docs/performance.md).
  std::string text = "{\"crushers\":[";
  bool first = true;
  std::lock_guard<std::mutex> lock(list_mutex_);
  for (const Crusher* c : ctx_.registry->All()) {
    // Never waits behind a wear recompute and never loads or computes anything: the wear as last
    // computed (the wear worker recomputes a changed crusher within --wear-interval-ms), the latest
    // reading time as loaded. At startup, before the wear worker's first pass reaches a crusher, its
    // entry says "pending" instead of making this request load and compute it.
    const std::string& id = c->config.crusher_id;
    std::shared_ptr<const CrusherState> st = ctx_.wear->Latest(id);
    const bool loaded = ctx_.live->Loaded(id);
    const auto latest = loaded ? ctx_.live->LatestUsableTime(id) : std::nullopt;
    ListEntry& e = list_entries_[id];
    if (e.text.empty() || e.crusher != c || e.state != st || e.loaded != loaded || e.latest != latest) {
      e.text = ListEntryJson(*c, st.get(), loaded, latest).dump(-1, ' ', false, ordered_json::error_handler_t::replace);
      e.crusher = c;
      e.state = std::move(st);
      e.loaded = loaded;
      e.latest = latest;
    }
    if (!first) text += ',';
    first = false;
    text += e.text;
  }
  text += "]}";
  Response r;
  r.raw = RawBody{std::move(text), "application/json"};
  return r;
}

Response Resources::CrusherDetail(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  if (!c) return error;
  ordered_json sensors = ordered_json::array();
  for (const auto& s : c->config.sensors) {
    sensors.push_back(
        {{"id", s.id}, {"row", s.row}, {"z_m", s.z_m}, {"theta_deg", s.theta_deg}, {"thickness_new_mm", s.thickness_new_mm}});
  }
  if (Starting(*c, false, &error)) return error;
  const int64_t stored = ctx_.live->CountReadings(c->config.crusher_id);
  const IngestCounters cc = ctx_.ingestor->CrusherCounters(c->config.crusher_id);
  return Json(
      200,
      {{"crusher_id", c->config.crusher_id},
       {"installed_at", core::FormatIsoTime(c->config.installed_at)},
       {"liner_start", core::FormatIsoTime(c->config.LinerStart())},  // readings before it: a previous liner's
       {"concave",
        {{"thickness_new_mm", c->config.thickness_new_mm},
         {"thickness_min_mm", c->config.thickness_min_mm},
         {"rows", RowsJson(c->config)}}},
       {"sensors", sensors},
       {"map",
        {{"sha256", c->map.sha256},
         {"face_count", c->map.face_count()},
         {"warnings", c->validation.warnings},
         {"has_stderr", c->map.has_wear_stderr()},
         {"windows", c->map.windows},
         {"dem_summary", c->dem_summary}}},
       {"counters",
        {{"readings_stored", stored}, {"duplicates", cc.duplicates}, {"conflicts", cc.conflicts}, {"rejected", cc.rejected}}}});
}

Response Resources::Sensors(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  if (!c) return error;
  if (Starting(*c, false, &error)) return error;
  const std::vector<Store::SensorSummary> latest = ctx_.live->LatestPerSensor(c->config.crusher_id);
  ordered_json sensors = ordered_json::array();
  for (const auto& s : c->config.sensors) {
    ordered_json o = {{"id", s.id},
                      {"row", s.row},
                      {"z_m", s.z_m},
                      {"theta_deg", s.theta_deg},
                      {"thickness_new_mm", s.thickness_new_mm},
                      {"reading_count", 0},
                      {"latest", nullptr}};
    for (const auto& l : latest) {
      if (l.latest.sensor != s.id) continue;
      o["reading_count"] = l.count;
      o["latest"] = SensorReadingJson(c->config, l.latest);
    }
    sensors.push_back(o);
  }
  return Json(200, {{"sensors", sensors}});
}

Response Resources::Readings(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  if (!c) return error;
  const std::string sensor = req.path.size() > 1 ? req.path[1] : std::string();
  if (!c->config.FindSensor(sensor)) return Error(404, "unknown sensor '" + sensor + "' on crusher " + c->config.crusher_id);
  std::string message;
  const auto query = ParseReadingsQuery(req.query, &message);
  if (!query) return Error(400, message);
  const auto format = FormatParam(req.query, {"json", "csv"}, &message);
  if (!format) return Error(400, message);
  Page page;
  try {
    page = ctx_.read->With(
        [&](Store& s) { return s.Range(c->config.crusher_id, sensor, query->from_s, query->to_s, query->limit, query->cursor); });
  } catch (const std::invalid_argument& e) {
    return Error(400, e.what());
  }
  if (*format == "csv") {
    ordered_json readings = ordered_json::array();
    for (const auto& r : page.readings) readings.push_back(SensorReadingJson(c->config, r));
    Response r;
    if (page.next_cursor) r.headers.emplace_back("X-Next-Cursor", *page.next_cursor);
    r.raw = RawBody{ReadingsCsv(readings), core::kCsvContentType};
    return r;
  }
  std::string text = "{\"readings\":[";
  text.reserve(64 + page.readings.size() * 160);
  for (size_t i = 0; i < page.readings.size(); ++i) {
    if (i) text += ',';
    ReadingText reading(&text);
    ReadingFields(c->config, page.readings[i], reading);
    reading.Close();
  }
  text += "],\"next_cursor\":";
  text += page.next_cursor ? "\"" + *page.next_cursor + "\"" : std::string("null");  // a cursor is t<digits>s<digits>
  text += '}';
  Response r;
  r.raw = RawBody{std::move(text), "application/json"};
  return r;
}

Response Resources::PostReadings(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  if (!c) return error;
  if (mqtt::JsonNestingDepth(req.body) > mqtt::kMaxReadingDepth + 2) return Error(400, "body is nested too deeply");
  std::lock_guard<std::mutex> one_at_a_time(post_mutex_);
  nlohmann::json body;
  std::string parse_error;
  if (!mqtt::ParseJsonNamingField(req.body, &body, &parse_error)) {
    const std::string_view malformed = "malformed JSON";
    return Error(400, parse_error.rfind(malformed, 0) == 0 ? "body is not valid JSON" + parse_error.substr(malformed.size())
                                                           : "body: " + parse_error);
  }
  if (!body.is_object() || !body.contains("readings") || !body["readings"].is_array()) {
    return Error(400, "body must be {\"readings\": [...]}");
  }
  if (body["readings"].size() > kMaxPostedReadings)
    return Error(413, "at most " + std::to_string(kMaxPostedReadings) + " readings per request");
  std::vector<Incoming> batch;
  for (const auto& r : body["readings"]) {
    batch.push_back({"", c->config.crusher_id, "", "", r.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace)});
  }
  const size_t posted = batch.size();
  IngestResult result;
  try {
    result = ctx_.ingestor->Ingest(std::move(batch));
  } catch (const std::exception& e) {
    return Error(503, std::string("not stored: ") + e.what());
  }
  if (ctx_.after_ingest) ctx_.after_ingest(result);
  ordered_json j = {{"stored", result.stored},       {"duplicates", result.duplicates},
                    {"conflicts", result.conflicts}, {"rejected", result.rejected},
                    {"held", result.held},           {"errors", result.log}};
  // Nothing taken: each reading was refused, or held (dated ahead of the server's clock: post it again later).
  const bool none_taken = posted > 0 && result.rejected + result.held == posted;
  if (none_taken)
    j["error"] = result.held == 0 ? "every reading was rejected" : "no reading was stored: each was rejected or held";
  return Json(none_taken ? 422 : 200, std::move(j));
}

Response Resources::Mesh(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  if (!c) return error;
  const auto& m = c->map;
  std::vector<double> pts;
  pts.reserve(m.points.size() * 3);
  for (const auto& p : m.points) {
    for (int k = 0; k < 3; ++k) pts.push_back(std::round(p[k] * 1e5) / 1e5);
  }
  std::vector<uint32_t> faces;
  faces.reserve(m.faces.size() * 3);
  for (const auto& f : m.faces) faces.insert(faces.end(), f.begin(), f.end());
  std::vector<double> z(m.face_count()), th(m.face_count());
  for (size_t i = 0; i < m.face_count(); ++i) {
    z[i] = std::round(m.z[static_cast<Eigen::Index>(i)] * 1e4) / 1e4;
    th[i] = std::round(m.theta_deg[static_cast<Eigen::Index>(i)] * 100) / 100;
  }
  return Json(200, {{"points", pts}, {"faces", faces}, {"face_z_m", z}, {"face_theta_deg", th}});
}

namespace {

/// The per-face wear as a legacy VTK file (ParaView), made in a private directory (mkdtemp, mode
/// 0700: nobody else can race a file name in it).
Response WearVtk(const Crusher& c, const CrusherState& st) {
  char tmpl[] = "/tmp/linerwatch-wear-XXXXXX";
  if (!mkdtemp(tmpl)) return Error(500, "cannot create a temporary directory");
  const std::filesystem::path tmp_dir = tmpl;
  const std::filesystem::path path = tmp_dir / "wear.vtk";
  std::stringstream ss;
  try {
    const Eigen::VectorXd& wear = st.reconstruction.wear_mm;
    const Eigen::VectorXd& remaining = st.reconstruction.remaining_mm;
    const Eigen::VectorXd& sd = st.reconstruction.remaining_sd_mm;
    core::WriteWearMapVtk(path, c.map,
                          {{"remaining_mm", &remaining},
                           {"remaining_sd_mm", &sd},
                           {"wear_mm", &wear},
                           {"dem_wear", &c.map.wear},
                           {"dem_intensity_smoothed", &c.plan.intensity}});
    std::ifstream in(path, std::ios::binary);
    ss << in.rdbuf();
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove_all(tmp_dir, ec);
    throw;
  }
  std::error_code ec;
  std::filesystem::remove_all(tmp_dir, ec);
  Response r;
  r.headers.emplace_back("Content-Disposition", "attachment; filename=\"" + c.config.crusher_id + "_wear.vtk\"");
  r.raw = RawBody{ss.str(), "application/octet-stream"};
  return r;
}

/// Whether `at_s` (GET .../wear?at=`text`) is a time the liner has wear at: not before its
/// installation, not after the server's "now" (`now_s`, the clock readings are validated against:
/// a later time has no readings yet); else *error says why, naming the parameter.
bool CheckWearTime(const core::CrusherConfig& config, const std::string& text, int64_t at_s, int64_t now_s, std::string* error) {
  if (core::FromUnixSeconds(at_s) < config.installed_at) {
    *error =
        "at='" + text + "' is before the liner's installation (installed_at " + core::FormatIsoTime(config.installed_at) + ")";
    return false;
  }
  if (at_s > now_s) {
    *error = "at='" + text + "' is in the future (the server's time is " + core::FormatIsoSeconds(now_s) + ")";
    return false;
  }
  return true;
}

}  // namespace

bool Resources::Starting(const Crusher& c, bool need_wear, Response* error) {
  if (!ctx_.starting || !ctx_.starting->load()) return false;
  const std::string& id = c.config.crusher_id;
  if (ctx_.live->Loaded(id) && (!need_wear || ctx_.wear->Latest(id))) return false;
  *error = Error(503, "the server is starting: crusher " + id + "'s " + (need_wear ? "wear is" : "readings are") + " not " +
                          (need_wear ? "computed" : "loaded") + " yet (GET /healthz: startup); retry in a few seconds");
  error->headers.emplace_back("Retry-After", "2");
  return true;
}

std::shared_ptr<const CrusherState> Resources::StateOf(const Request& req, const Crusher& c, Response* error) {
  const std::string* at_param = FindParam(req.query, "at");
  if (!at_param) {
    if (Starting(c, true, error)) return nullptr;
    auto st = ctx_.wear->Get(c.config.crusher_id);
    if (!st || !st->has_wear) {
      *error = Error(404, "no readings yet for crusher " + c.config.crusher_id);
      return nullptr;
    }
    return st;
  }
  // A past time's state: the stored readings up to it (a window loaded as the live state's) and the
  // scans up to it, through the same estimate as the live wear.
  int64_t at_s = 0;
  std::string message;
  if (!TimeParam(req.query, "at", &at_s, &message) ||
      !CheckWearTime(c.config, *at_param, at_s, ctx_.ingestor->NowS(), &message)) {
    *error = Error(400, message);
    return nullptr;
  }
  const core::TimePoint at{std::chrono::seconds(at_s)};
  const estimate::ReadingWindow window = ctx_.read->With([&](Store& s) { return LoadWindow(s, c, at_s); });
  auto st = std::make_shared<const CrusherState>(
      ComputeCrusherState(c, window.Readings(), at, nullptr, ctx_.wear->SettingChecks(c.config.crusher_id)));
  if (!st->has_wear) {
    *error = Error(404, "no readings of crusher " + c.config.crusher_id + " at or before at=" + *at_param);
    return nullptr;
  }
  return st;
}

Response Resources::Wear(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  if (!c) return error;
  const std::string* format_param = FindParam(req.query, "format");
  const std::string format = format_param ? *format_param : "json";
  if (format != "json" && format != "vtk" && format != "csv") return Error(400, "format='" + format + "': use json, vtk or csv");
  const std::shared_ptr<const CrusherState> st = StateOf(req, *c, &error);
  if (!st) return error;
  if (format == "vtk") return WearVtk(*c, *st);
  if (format == "csv") {
    Response r;
    r.headers.emplace_back("Content-Disposition", "attachment; filename=\"" + c->config.crusher_id + "_wear.csv\"");
    r.raw = RawBody{WearCsv(*st), core::kCsvContentType};
    return r;
  }
  const std::string* faces_param = FindParam(req.query, "faces");
  const bool faces = !(faces_param && *faces_param == "false");
  const std::string& body = faces ? st->wear_body : st->wear_body_no_faces;  // serialized as computed
  if (!body.empty()) {
    Response r;
    r.raw = RawBody{body, "application/json"};
    return r;
  }
  return Json(200, WearJson(*st, faces));
}

Response Resources::Forecast(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  if (!c) return error;
  std::string message;
  const auto format = FormatParam(req.query, {"json", "csv"}, &message);
  if (!format) return Error(400, message);
  const std::shared_ptr<const CrusherState> st = StateOf(req, *c, &error);
  if (!st) return error;
  if (*format == "csv") {
    Response r;
    r.raw = RawBody{ForecastCsv(ForecastJson(*st)), core::kCsvContentType};
    return r;
  }
  if (!st->forecast_body.empty()) {  // serialized as computed
    Response r;
    r.raw = RawBody{st->forecast_body, "application/json"};
    return r;
  }
  return Json(200, ForecastJson(*st));
}

Response Resources::Diagnosis(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  if (!c) return error;
  if (!ctx_.diagnosis) return Error(503, "diagnosis is not available on this server");
  Response r;
  r.raw = RawBody{ctx_.diagnosis->StatusJson(c->config.crusher_id), "application/json"};
  return r;
}

Response Resources::StartDiagnosis(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  if (!c) return error;
  if (!ctx_.diagnosis) return Error(503, "diagnosis is not available on this server");
  if (!ctx_.diagnosis->Start(c->config.crusher_id)) return Error(409, "a diagnosis is already running");
  return Json(202, {{"status", "running"}});
}

Response Resources::PostReline(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  if (!c) return error;
  if (!ctx_.campaigns) return Error(503, "campaigns are not available on this server");
  CampaignService::Outcome out;
  try {
    out = ctx_.campaigns->Reline(c->config.crusher_id, ParseRelineBody(req.body));
  } catch (const RelineError& e) {
    return Error(e.status(), e.what());
  }
  if (out.created && ctx_.after_reline) ctx_.after_reline(c->config.crusher_id);
  return Json(out.created ? 201 : 200, CampaignJson(out.campaign, ctx_.campaigns->Now()));
}

AlarmEngine* Resources::AlarmsOf(Response* error) const {
  if (!ctx_.alarms) *error = Error(503, "alarms are not kept by this server");
  return ctx_.alarms;
}

std::string Resources::TokenName(const Request& request) const {
  if (!ctx_.tokens || !ctx_.tokens->enabled()) return "anonymous";
  const auto token = ctx_.tokens->Check(request.bearer);
  return token ? token->name : "unknown";
}

Response Resources::AlarmList(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  AlarmEngine* alarms = c ? AlarmsOf(&error) : nullptr;
  if (!alarms) return error;
  std::string state;
  if (const std::string* s = FindParam(req.query, "state")) {
    state = *s;
    if (state != "active" && state != "acknowledged" && state != "cleared")
      return Error(400, "state '" + state + "' must be active, acknowledged or cleared");
  }
  int limit = 100;
  std::string message;
  if (FindParam(req.query, "limit") && !WholeNumberParam(req.query, "limit", 1, 1000, &limit, &message))
    return Error(400, message);
  constexpr int64_t kRecentS = 7 * 86400;  // "recent": cleared alarms of the last week
  ordered_json list = ordered_json::array();
  for (const AlarmRecord& a : alarms->List(c->config.crusher_id, state, ctx_.ingestor->NowS() - kRecentS, limit)) {
    const std::vector<AlarmAuditEntry> audit = alarms->Audit(a.id);
    list.push_back(AlarmJson(a, &audit));
  }
  return Json(200, {{"alarms", std::move(list)}});
}

Response Resources::AckAlarm(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  AlarmEngine* alarms = c ? AlarmsOf(&error) : nullptr;
  if (!alarms) return error;
  const std::string& id_text = req.path.at(1);
  char* end = nullptr;
  const long long id = std::strtoll(id_text.c_str(), &end, 10);
  const std::string unknown = "unknown alarm '" + id_text + "' of crusher '" + c->config.crusher_id + "'";
  if (id_text.empty() || *end != '\0' || id <= 0) return Error(404, unknown);
  AlarmRecord alarm;
  switch (alarms->Acknowledge(c->config.crusher_id, id, TokenName(req), ctx_.ingestor->NowS(), &alarm)) {
    case AlarmEngine::Ack::kUnknown:
      return Error(404, unknown);
    case AlarmEngine::Ack::kCleared:
      return Error(409, "alarm " + id_text + " was cleared at " + core::FormatIsoSeconds(alarm.cleared_s.value_or(0)) +
                            ": nothing to acknowledge");
    case AlarmEngine::Ack::kAcknowledged:
    case AlarmEngine::Ack::kAlreadyAcknowledged:
      break;
  }
  const std::vector<AlarmAuditEntry> audit = alarms->Audit(alarm.id);
  return Json(200, AlarmJson(alarm, &audit));
}

Response Resources::AlarmRules(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  AlarmEngine* alarms = c ? AlarmsOf(&error) : nullptr;
  if (!alarms) return error;
  return Json(200, {{"rules", core::AlarmConfigJson(alarms->Rules(c->config.crusher_id))}});
}

Response Resources::SetAlarmRules(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  AlarmEngine* alarms = c ? AlarmsOf(&error) : nullptr;
  if (!alarms) return error;
  if (mqtt::JsonNestingDepth(req.body) > kMaxSmallBodyDepth) return Error(400, "body is nested too deeply");
  const nlohmann::json body = nlohmann::json::parse(req.body, nullptr, false);
  if (body.is_discarded()) return Error(400, "the body is not JSON (an \"alarms\" object, docs/alarms.md)");
  try {
    const core::AlarmConfig rules = alarms->UpdateRules(c->config.crusher_id, body, TokenName(req), ctx_.ingestor->NowS());
    return Json(200, {{"rules", core::AlarmConfigJson(rules)}});
  } catch (const core::InputError& e) {
    return Error(400, e.rule());
  }
}

Response Resources::Plan(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  if (!c) return error;
  int sensors = 0;
  std::string message;
  if (!FindParam(req.query, "sensors")) return Error(400, "sensors=K is required (how many sensors the next liner gets)");
  // Each K costs a search over every candidate position: K is held to what a liner carries.
  if (!WholeNumberParam(req.query, "sensors", 1, 100, &sensors, &message)) return Error(400, message);
  estimate::PlanOptions options;
  options.sensors = static_cast<size_t>(sensors);
  estimate::SensorPlan plan;
  try {
    plan = estimate::PlanSensors(*c, options);
  } catch (const std::invalid_argument& e) {  // more sensors than the rows have places for
    return Error(422, e.what());
  }
  // The running campaign's stored readings: how much a scan now would narrow the bands.
  const int64_t now = ctx_.ingestor->NowS();
  const estimate::ReadingWindow window = ctx_.read->With([&](Store& s) { return LoadWindow(s, *c, now); });
  const std::vector<estimate::Sample> readings = window.Readings();
  if (!readings.empty()) plan.scan = estimate::AdviseScan(*c, readings);
  return Json(200, estimate::PlanJson(plan));
}

Response Resources::VoidReline(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  if (!c) return error;
  if (!ctx_.campaigns) return Error(503, "campaigns are not available on this server");
  const std::string& time_text = req.path.at(1);
  const auto time = core::ParseIsoTime(time_text);
  if (!time)
    return Error(400, "{time} '" + time_text + "' is not an ISO-8601 UTC time (the reline's, as GET .../campaigns lists it)");
  CampaignService::Outcome out;
  try {
    out = ctx_.campaigns->Void(c->config.crusher_id, *time, TokenName(req), ParseVoidBody(req.body));
  } catch (const RelineError& e) {
    return Error(e.status(), e.what());
  }
  if (out.created && ctx_.after_reline) ctx_.after_reline(c->config.crusher_id);
  return Json(200, CampaignJson(out.campaign, ctx_.campaigns->Now()));
}

Response Resources::PostSettingCheck(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  if (!c) return error;
  if (!ctx_.campaigns) return Error(503, "campaigns are not available on this server");
  CampaignService::SettingOutcome out;
  try {
    out = ctx_.campaigns->CheckSetting(c->config.crusher_id, ParseSettingCheckBody(req.body), TokenName(req));
  } catch (const RelineError& e) {
    return Error(e.status(), e.what());
  }
  // The wear is computed and published again with the setting counted from the check, as after a reline.
  if (out.created && ctx_.after_reline) ctx_.after_reline(c->config.crusher_id);
  return Json(out.created ? 201 : 200, SettingCheckJson(out.check, c->config.installed_at));
}

Response Resources::SettingCheckList(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  if (!c) return error;
  // Read from the REST reads' store, so a read-only server lists them too.
  std::vector<SettingCheckRecord> checks = ctx_.read->With([&](Store& s) { return s.SettingChecks(c->config.crusher_id); });
  // The openings live wear counts (estimated again where the stored ones could not be updated).
  for (const core::SettingCheck& counted : ctx_.wear->SettingChecks(c->config.crusher_id))
    for (SettingCheckRecord& k : checks)
      if (core::FromUnixSeconds(k.time_s) == counted.time) {
        k.opening_mm = std::isfinite(counted.opening_mm) ? std::optional(counted.opening_mm) : std::nullopt;
        k.opening_supported = k.opening_mm && counted.opening_supported;
      }
  ordered_json list = ordered_json::array();
  for (const SettingCheckRecord& k : checks) list.push_back(SettingCheckJson(k, c->config.installed_at));
  return Json(200, {{"checks", std::move(list)}});
}

Response Resources::CampaignList(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  if (!c) return error;
  if (!ctx_.campaigns) return Error(503, "campaigns are not available on this server");
  ordered_json list = ordered_json::array();
  const int64_t now = ctx_.campaigns->Now();
  for (const CampaignRecord& k : ctx_.campaigns->List(c->config.crusher_id)) list.push_back(CampaignJson(k, now));
  return Json(200, {{"campaigns", std::move(list)}});
}

Response Resources::Events(const Request& req) {
  Response error;
  const Crusher* c = CrusherOf(req, &error);
  if (!c) return error;
  const int per_client = static_cast<int>(std::max<size_t>(1, ctx_.limits.max_event_streams_per_client));
  {
    std::lock_guard<std::mutex> lock(streams_mutex_);
    if (event_streams_ >= max_event_streams_)
      return Error(503, "too many open event streams (" + std::to_string(max_event_streams_) + "); retry later");
    if (streams_per_client_[req.client] >= per_client) {
      return Error(
          503, "too many open event streams from " + req.client + " (at most " + std::to_string(per_client) + "); retry later");
    }
    ++event_streams_;
    ++streams_per_client_[req.client];
  }
  int64_t after = ctx_.events->LastId();
  // A client reconnecting after a server restart carries an id from the previous run: ids start
  // again at 1, so a larger one means "from now on", not "wait until the counter gets there".
  if (!req.last_event_id.empty()) after = std::min(after, std::max<int64_t>(0, std::atoll(req.last_event_id.c_str())));
  // Counts the stream while it exists (the HTTP layer drops it when the stream ends).
  auto slot = std::shared_ptr<void>(nullptr, [this, client = req.client](void*) {
    std::lock_guard<std::mutex> lock(streams_mutex_);
    --event_streams_;
    if (--streams_per_client_[client] <= 0) streams_per_client_.erase(client);
  });
  Response r;
  r.headers = {{"Cache-Control", "no-cache"}, {"X-Accel-Buffering", "no"}};
  const auto ends_at = std::chrono::steady_clock::now() + std::chrono::seconds(ctx_.limits.event_stream_lifetime_s);
  r.stream = std::shared_ptr<EventStream>(
      new EventStream(*ctx_.events, stopping_, c->config.crusher_id, after, std::move(slot), ends_at));
  return r;
}

Response Resources::RejectedList(const Request& req) {
  int limit = 100;
  std::string message;
  if (!WholeNumberParam(req.query, "limit", 1, 1000, &limit, &message)) return Error(400, message);
  return ctx_.read->With([&](Store& s) {
    ordered_json list = ordered_json::array();
    for (const auto& r : s.RejectedMessages(limit)) {
      list.push_back({{"received", core::FormatIsoSeconds(r.received_s)},
                      {"topic", r.topic},
                      {"payload", r.payload},
                      {"reason", r.reason},
                      {"class", r.reason_class}});
    }
    return Json(200, {{"total", s.CountRejected()}, {"evicted", s.RejectedEvicted()}, {"rejected", list}});
  });
}

Response Resources::WhoAmI(const Request& req) {
  if (!ctx_.tokens || !ctx_.tokens->enabled()) {
    return Json(200, {{"auth", false}, {"name", nullptr}, {"scopes", {"read", "write"}}});
  }
  const auto token = ctx_.tokens->Check(req.bearer);  // the HTTP layer's scope check let it through
  ordered_json scopes = ordered_json::array();
  if (token && token->read) scopes.push_back("read");
  if (token && token->write) scopes.push_back("write");
  return Json(200, {{"auth", true}, {"name", token ? token->name : ""}, {"scopes", scopes}});
}

Response Resources::Metrics(const Request&) {
  if (!ctx_.metrics) return Error(503, "metrics are not kept by this server");
  int streams = 0;
  {
    std::lock_guard<std::mutex> lock(streams_mutex_);
    streams = event_streams_;
  }
  Response r;
  r.raw =
      RawBody{ctx_.metrics->Render(*ctx_.ingestor, *ctx_.registry, streams, core::WallClockMs()), core::prometheus::kContentType};
  return r;
}

Response Resources::OpenApi(const Request&) {
  Response r;
  r.raw = RawBody{OpenApiJson(), "application/json"};
  return r;
}

}  // namespace lw::server::rest
