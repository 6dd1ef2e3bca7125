// The REST resources without HTTP: the route table, the OpenAPI document generated from it, and
// the handlers called through rest::Resources.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <set>
#include <thread>

#include "core/time.hpp"
#include "server/openapi.hpp"
#include "server/rest.hpp"
#include "unit/server/server_fixture.hpp"

#include <CppUTest/TestHarness.h>  // last: its leak-detection macros clash with std headers

using namespace lw::server;
using lw::test::ServerParts;
using nlohmann::json;

namespace {

lw::test::CrusherFolder& Folder() {
  static lw::test::CrusherFolder f(10, 5);
  return f;
}

/// The server's parts and the resources over them.
struct Fixture {
  ServerParts parts;
  std::unique_ptr<rest::Resources> resources;
  explicit Fixture(bool with_tokens = false, size_t workers = 32) : parts(Folder().crushers, with_tokens) {
    parts.ctx.limits.workers = workers;
    resources = std::make_unique<rest::Resources>(parts.ctx);
  }
  rest::Response Call(rest::Method method, const char* path, rest::Request request = {}) {
    return lw::test::WithJson(resources->Call(rest::Resources::Find(method, path), request));
  }
  rest::Response Get(const char* path, std::vector<std::string> params = {Folder().id()}, QueryParams query = {}) {
    rest::Request r;
    r.path = std::move(params);
    r.query = std::move(query);
    return Call(rest::Method::kGet, path, r);
  }
  rest::Response PostReadings(const std::string& body) {
    rest::Request r;
    r.path = {Folder().id()};
    r.body = body;
    return Call(rest::Method::kPost, "/api/v1/crushers/{crusher}/readings", r);
  }
  /// Every reading of the folder's bundle as a POST body.
  static std::string AllReadings() {
    json body = {{"readings", json::array()}};
    for (const auto& m : lw::test::Messages(Folder().bundle)) body["readings"].push_back(json::parse(m.payload));
    return body.dump();
  }
};

/// POST `body` (readings JSON) to `crusher`'s readings through `resources`; the response must be 200.
void PostReadingsTo(rest::Resources& resources, const std::string& crusher, const json& body) {
  const std::string text = body.dump();  // Request::body is a view
  rest::Request post;
  post.path = {crusher};
  post.body = text;
  const rest::Response posted =
      resources.Call(rest::Resources::Find(rest::Method::kPost, "/api/v1/crushers/{crusher}/readings"), post);
  LONGS_EQUAL_TEXT(200, posted.status, posted.json.dump().substr(0, 500).c_str());
}

/// GET `route` (a crusher route template) for `crusher` through `resources`.
rest::Response GetFrom(rest::Resources& resources, const char* route, const std::string& crusher) {
  rest::Request get;
  get.path = {crusher};
  return lw::test::WithJson(resources.Call(rest::Resources::Find(rest::Method::kGet, route), get));
}

// In `row`, the served wear (`wear`: the REST wear JSON) equals `expected` (the live wear without a
// sensor's reading) and exceeds by more than 0.5 mm what that reading (`kept`, labelled `label`)
// would have given: left out, and it mattered.
void CheckRowWearLeftOut(const json& wear, const lw::core::Reconstruction& expected, const lw::core::Reconstruction& kept,
                         const std::string& row, const char* label) {
  for (size_t k = 0; k < expected.rows.size(); ++k) {
    if (expected.rows[k].row != row) continue;
    const double live = wear["rows"][k]["mean_wear_mm"].get<double>();
    DOUBLES_EQUAL(expected.rows[k].mean_wear_mm, live, 1e-3);
    CHECK_TEXT(live > kept.rows[k].mean_wear_mm + 0.5,
               (std::to_string(live) + " mm vs " + std::to_string(kept.rows[k].mean_wear_mm) + " mm " + label).c_str());
  }
}

std::string ErrorOf(const rest::Response& r) {
  const auto it = r.json.find("error");
  return it != r.json.end() && it->is_string() ? it->get<std::string>() : std::string("(no error)");
}

}  // namespace

TEST_GROUP(RestRoutes){};

// The OpenAPI document is generated from the route table: this checks the generator. Every route
// has exactly one operation (its method under its path) and every operation is a route; each
// names its path parameters, its query parameters, its success status and the scope the HTTP
// front end enforces for it.
TEST(RestRoutes, TheOpenApiDocumentHasOneOperationPerRouteAndNoOther) {
  const json doc = json::parse(OpenApiJson());
  std::set<std::pair<std::string, std::string>> documented;
  for (const auto& [path, operations] : doc["paths"].items()) {
    for (const auto& [method, op] : operations.items()) documented.insert({method, path});
  }
  std::set<std::pair<std::string, std::string>> routed;
  for (const rest::Route& route : rest::Resources::Routes()) {
    std::string method = rest::MethodName(route.method);
    for (char& ch : method) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    CHECK_TEXT(routed.insert({method, route.path}).second, (method + " " + route.path + " is in the table twice").c_str());
    const bool has_operation = doc["paths"].contains(route.path) && doc["paths"][route.path].contains(method);
    CHECK_TEXT(has_operation, (method + " " + route.path + " has no OpenAPI operation").c_str());
    if (!has_operation) continue;
    const json& op = doc["paths"][route.path][method];
    STRCMP_EQUAL(route.summary, op["summary"].get<std::string>().c_str());
    CHECK_TEXT(op["responses"].contains(route.ok_status), route.path);
    STRCMP_EQUAL(rest::ScopeName(rest::RequiredScope(rest::MethodName(route.method), route.path)),
                 op["x-scope"].get<std::string>().c_str());
    std::vector<std::string> in_path, in_query;
    for (const auto& p : op["parameters"]) (p["in"] == "path" ? in_path : in_query).push_back(p["name"]);
    CHECK(rest::PathParams(route.path) == in_path);
    LONGS_EQUAL(route.query.size(), in_query.size());
    for (size_t i = 0; i < route.query.size(); ++i) STRCMP_EQUAL(route.query[i].name, in_query[i].c_str());
  }
  CHECK(routed == documented);
  // The operations docs/server.md lists, as the dashboard and the tests use them.
  LONGS_EQUAL(26, routed.size());
  CHECK(documented.count({"get", "/api/v1/crushers/{crusher}/alarms"}));
  CHECK(documented.count({"post", "/api/v1/crushers/{crusher}/alarms/{id}/ack"}));
  CHECK(documented.count({"get", "/api/v1/crushers/{crusher}/alarms/rules"}));
  CHECK(documented.count({"post", "/api/v1/crushers/{crusher}/alarms/rules"}));
  CHECK(documented.count({"get", "/api/v1/crushers/{crusher}/plan"}));
  CHECK(documented.count({"post", "/api/v1/crushers/{crusher}/relines"}));
  CHECK(documented.count({"get", "/api/v1/crushers/{crusher}/campaigns"}));
  CHECK(documented.count({"post", "/api/v1/crushers/{crusher}/relines/{time}/void"}));
  STRCMP_EQUAL("write",
               doc["paths"]["/api/v1/crushers/{crusher}/relines/{time}/void"]["post"]["x-scope"].get<std::string>().c_str());
  CHECK(documented.count({"post", "/api/v1/crushers/{crusher}/diagnosis"}));
  STRCMP_EQUAL("write", doc["paths"]["/api/v1/crushers/{crusher}/readings"]["post"]["x-scope"].get<std::string>().c_str());
  STRCMP_EQUAL("none", doc["paths"]["/healthz"]["get"]["x-scope"].get<std::string>().c_str());
  STRCMP_EQUAL("read", doc["paths"]["/api/v1/openapi.json"]["get"]["x-scope"].get<std::string>().c_str());
  // /metrics is text, readings and forecast JSON or CSV.
  const json& metrics = doc["paths"]["/metrics"]["get"];
  STRCMP_EQUAL("read", metrics["x-scope"].get<std::string>().c_str());
  CHECK(metrics["responses"]["200"]["content"].contains("text/plain"));
  CHECK_FALSE(metrics["responses"]["200"]["content"].contains("application/json"));
  for (const char* path : {"/api/v1/crushers/{crusher}/sensors/{sensor}/readings", "/api/v1/crushers/{crusher}/forecast",
                           "/api/v1/crushers/{crusher}/wear"}) {
    const json& content = doc.at("paths").at(path).at("get").at("responses").at("200").at("content");
    CHECK_TEXT(content.contains("application/json") && content.contains("text/csv"), path);
  }
}

namespace {
/// Every {"$ref": ...} under `node` that does not point into `doc`, and every object schema that
/// says nothing of its members (the bare {"type": "object"} the document used to have).
void FindLooseSchemas(const json& doc, const json& node, const std::string& where, std::vector<std::string>* out) {
  if (node.is_array()) {
    for (size_t i = 0; i < node.size(); ++i) FindLooseSchemas(doc, node[i], where + "/" + std::to_string(i), out);
    return;
  }
  if (!node.is_object()) return;
  if (node.contains("$ref") && node["$ref"].is_string()) {
    const std::string ref = node["$ref"];
    if (ref.rfind("#/", 0) != 0 || !doc.contains(json::json_pointer(ref.substr(1)))) out->push_back(where + ": $ref " + ref);
  }
  const bool says = node.contains("properties") || node.contains("additionalProperties") || node.contains("allOf") ||
                    node.contains("anyOf") || node.contains("$ref");
  if (node.value("type", json()) == "object" && !says) out->push_back(where + ": an object schema with no members");
  for (const auto& [key, value] : node.items()) FindLooseSchemas(doc, value, where + "/" + key, out);
}

/// The statuses the document declares for `method` `path`.
std::set<std::string> Statuses(const json& doc, const std::string& path, const std::string& method) {
  std::set<std::string> out;
  for (const auto& [status, response] : doc.at("paths").at(path).at(method).at("responses").items()) out.insert(status);
  return out;
}
}  // namespace

// The document says something: each JSON body has a schema with members (shared parts as
// components, every $ref resolving), the event stream is text/event-stream, and each operation
// lists the statuses its handler and the HTTP layer answer (test_server_openapi_live checks real
// answers against it).
TEST(RestRoutes, TheOpenApiDocumentHasSchemasStatusesAndMediaTypes) {
  const json doc = json::parse(OpenApiJson());
  std::vector<std::string> loose;
  FindLooseSchemas(doc, doc, "", &loose);
  std::string all;
  for (const std::string& l : loose) all += l + "\n";
  CHECK_TEXT(loose.empty(), all.c_str());
  for (const auto& [path, operations] : doc["paths"].items()) {
    for (const auto& [method, op] : operations.items()) {
      for (const char* status : {"400", "408", "413", "414", "421", "431", "500", "501", "503"})
        CHECK_TEXT(op["responses"].contains(status), (method + " " + path + " lacks " + status).c_str());
      const bool has_crusher = path.find("{crusher}") != std::string::npos;
      CHECK_EQUAL_TEXT(has_crusher, op["responses"].contains("404"), (method + " " + path).c_str());
      CHECK_EQUAL_TEXT(path != "/healthz", op["responses"].contains("401"), (method + " " + path).c_str());
      const json& ok = op["responses"].begin().value();
      if (ok["content"].contains("application/json")) {
        const json& schema = ok["content"]["application/json"]["schema"];
        CHECK_TEXT(schema != json({{"type", "object"}}), (method + " " + path + ": a bare object").c_str());
      }
    }
  }
  const json& events = doc["paths"]["/api/v1/crushers/{crusher}/events"]["get"]["responses"]["200"]["content"];
  CHECK(events.contains("text/event-stream"));
  CHECK_FALSE(events.contains("application/json"));
  const std::string readings = "/api/v1/crushers/{crusher}/readings";
  CHECK(doc["paths"][readings]["post"].contains("requestBody"));
  CHECK((std::set<std::string>{"200", "400", "401", "403", "404", "408", "411", "413", "414", "415", "421", "422", "431", "500",
                               "501", "503"}) == Statuses(doc, readings, "post"));
  CHECK((std::set<std::string>{"200", "400", "408", "413", "414", "415", "421", "431", "500", "501", "503"}) ==
        Statuses(doc, "/healthz", "get"));
  // /healthz's 503 is its own body (degraded) or the HTTP layer's error (busy).
  CHECK(doc["paths"]["/healthz"]["get"]["responses"]["503"]["content"]["application/json"]["schema"].contains("anyOf"));
  CHECK(Statuses(doc, "/api/v1/crushers/{crusher}/relines", "post").count("409"));
  CHECK(Statuses(doc, "/api/v1/crushers/{crusher}/alarms/{id}/ack", "post").count("409"));
  CHECK(Statuses(doc, "/api/v1/crushers/{crusher}/diagnosis", "post").count("202"));
  CHECK_FALSE(Statuses(doc, "/api/v1/crushers/{crusher}/mesh", "get").count("422"));
  const json& wear = doc["paths"]["/api/v1/crushers/{crusher}/wear"]["get"];
  CHECK(wear["responses"]["200"]["content"].contains("application/octet-stream"));
  for (const json& p : wear["parameters"]) {
    if (p["name"] == "format") CHECK(p["schema"]["enum"] == json({"json", "vtk", "csv"}));
  }
}

TEST(RestRoutes, PathTemplatesBecomeRoutingPatternsAndParameters) {
  STRCMP_EQUAL("/api/v1/crushers/([^/]+)/sensors/([^/]+)/readings",
               rest::PathPattern("/api/v1/crushers/{crusher}/sensors/{sensor}/readings").c_str());
  STRCMP_EQUAL("/healthz", rest::PathPattern("/healthz").c_str());
  CHECK((std::vector<std::string>{"crusher", "sensor"}) ==
        rest::PathParams("/api/v1/crushers/{crusher}/sensors/{sensor}/readings"));
  CHECK(rest::PathParams("/api/v1/rejected").empty());
  CHECK_THROWS(std::invalid_argument, rest::PathPattern("/api/v1/crushers/{crusher"));
  CHECK_THROWS(std::invalid_argument, rest::PathParams("/api/v1/crushers/{crusher"));
  CHECK_THROWS(std::out_of_range, rest::Resources::Find(rest::Method::kPost, "/api/v1/crushers"));
}

TEST(RestRoutes, ScopesFollowTheMethodInsideApiOnly) {
  CHECK(rest::Scope::kNone == rest::RequiredScope("GET", "/healthz"));
  CHECK(rest::Scope::kNone == rest::RequiredScope("POST", "/"));
  CHECK(rest::Scope::kRead == rest::RequiredScope("GET", "/metrics"));
  CHECK(rest::Scope::kRead == rest::RequiredScope("GET", "/api/v1/crushers"));
  CHECK(rest::Scope::kRead == rest::RequiredScope("HEAD", "/api/v1/crushers"));
  CHECK(rest::Scope::kWrite == rest::RequiredScope("POST", "/api/v1/crushers/x/readings"));
  CHECK(rest::Scope::kWrite == rest::RequiredScope("DELETE", "/api/v1/crushers"));
  CHECK_FALSE(rest::Writes("GET"));
  CHECK(rest::Writes("PUT"));
}

TEST_GROUP(RestHandlers){};

TEST(RestHandlers, EveryCrusherRouteAnswers404ForAnUnknownCrusher) {
  Fixture f;
  int crusher_routes = 0;
  for (const rest::Route& route : rest::Resources::Routes()) {
    if (rest::PathParams(route.path).empty()) continue;
    ++crusher_routes;
    rest::Request r;
    r.path = {"nope", "1001"};
    r.body = "{}";
    const rest::Response res = f.resources->Call(route, r);
    LONGS_EQUAL_TEXT(404, res.status, route.path);
    STRCMP_EQUAL("unknown crusher 'nope'", ErrorOf(res).c_str());
  }
  LONGS_EQUAL(20, crusher_routes);
}

// After a reline the old boards' last reports fall in the day of slack before installed_at: the readings
// and the sensors' latest mark a worn one "previous_liner" (live wear leaves it out; the dashboard's
// chart too), and not an unworn one, which may be a new board whose clock is ahead.
TEST(RestHandlers, APreviousLinersReadingIsMarkedInReadingsAndLatest) {
  Fixture f;
  const lw::core::CrusherConfig& crusher = Folder().bundle.crusher;
  const std::string worn = crusher.sensors.at(0).id, unworn = crusher.sensors.at(1).id;
  const double new_mm = crusher.sensors.at(0).thickness_new_mm;
  const std::string slack = lw::core::FormatIsoTime(lw::core::AddDays(crusher.installed_at, -0.5));
  json body = {{"readings", json::array()}};
  for (const auto& [sensor, mm] : {std::pair{worn, new_mm - 40}, std::pair{unworn, new_mm - 1}})
    body["readings"].push_back({{"sensor", sensor},
                                {"seq", 1},
                                {"time", slack},
                                {"thickness_mm", mm},
                                {"loops_intact", mm},
                                {"flags", 0},
                                {"battery_mv", 3300}});
  PostReadingsTo(*f.resources, Folder().id(), body);

  const char* readings = "/api/v1/crushers/{crusher}/sensors/{sensor}/readings";
  const rest::Response old_page = f.Get(readings, {Folder().id(), worn});
  STRCMP_CONTAINS("\"previous_liner\":true}", old_page.raw->content.c_str());
  const json old = old_page.json["readings"];
  LONGS_EQUAL(1, old.size());
  CHECK(old[0].value("previous_liner", false));
  const json fresh = f.Get(readings, {Folder().id(), unworn}).json["readings"];
  LONGS_EQUAL(1, fresh.size());
  CHECK_FALSE(fresh[0].contains("previous_liner"));
  const json sensors = f.Get("/api/v1/crushers/{crusher}/sensors").json["sensors"];
  for (const auto& s : sensors) {
    if (s["id"] == worn) CHECK(s["latest"].value("previous_liner", false));
    if (s["id"] == unworn) CHECK_FALSE(s["latest"].contains("previous_liner"));
  }
}

// The readings answer, field by field: each reading's keys in this order and nothing else (no
// sensor id, no payload), the values as posted, `received` the server's store time, pages of
// `limit` joined by next_cursor ("t<time>s<seq>" of a page's last reading), null on the last page,
// and from/to inclusive.
TEST(RestHandlers, TheReadingsAnswerCarriesTheDocumentedFieldsPageByPage) {
  Fixture f;
  const std::string sensor = Folder().bundle.crusher.sensors.at(2).id;
  const lw::core::TimePoint t0 = lw::core::AddDays(Folder().bundle.crusher.installed_at, 1);
  json body = {{"readings", json::array()}};
  for (int i = 1; i <= 5; ++i)
    body["readings"].push_back({{"sensor", sensor},
                                {"seq", 10 + i},
                                {"time", lw::core::FormatIsoTime(t0 + std::chrono::seconds(3600 * (i / 2)))},
                                {"thickness_mm", 80 - i},
                                {"loops_intact", 80 - i},
                                {"flags", 0},
                                {"battery_mv", 3300 + i}});
  PostReadingsTo(*f.resources, Folder().id(), body);
  const char* route = "/api/v1/crushers/{crusher}/sensors/{sensor}/readings";
  std::vector<nlohmann::ordered_json> got, cursors;  // ordered: the keys as the server wrote them
  std::string cursor;
  for (int page = 0; page < 10; ++page) {
    QueryParams q = {{"limit", "2"}};
    if (!cursor.empty()) q.emplace("cursor", cursor);
    const rest::Response r = f.Get(route, {Folder().id(), sensor}, q);
    LONGS_EQUAL(200, r.status);
    // The page is written as text: the bytes a compact dump of the same tree gives, numbers in
    // nlohmann's form (a whole thickness keeps its ".0").
    CHECK(r.raw.has_value());
    STRCMP_EQUAL(nlohmann::ordered_json::parse(r.raw->content).dump().c_str(), r.raw->content.c_str());
    STRCMP_CONTAINS(",\"thickness_mm\":", r.raw->content.c_str());
    CHECK(r.raw->content.find(".0,\"loops_intact\":") != std::string::npos);
    std::vector<std::string> top;
    for (const auto& [k, v] : r.json.items()) top.push_back(k);
    CHECK((top == std::vector<std::string>{"readings", "next_cursor"}));
    for (const auto& reading : r.json["readings"]) got.push_back(reading);
    cursors.push_back(r.json["next_cursor"]);
    if (r.json["next_cursor"].is_null()) break;
    cursor = r.json["next_cursor"].get<std::string>();
  }
  LONGS_EQUAL(5, got.size());
  LONGS_EQUAL(3, cursors.size());
  for (int i = 1; i <= 5; ++i) {
    const nlohmann::ordered_json& r = got[static_cast<size_t>(i - 1)];
    std::vector<std::string> keys;
    for (const auto& [k, v] : r.items()) keys.push_back(k);
    CHECK((keys == std::vector<std::string>{"time", "seq", "thickness_mm", "loops_intact", "flags", "battery_mv", "received"}));
    STRCMP_EQUAL(lw::core::FormatIsoTime(t0 + std::chrono::seconds(3600 * (i / 2))).c_str(),
                 r["time"].get<std::string>().c_str());
    LONGS_EQUAL(10 + i, r["seq"].get<int>());
    DOUBLES_EQUAL(80 - i, r["thickness_mm"].get<double>(), 0);
    LONGS_EQUAL(80 - i, r["loops_intact"].get<int>());
    LONGS_EQUAL(0, r["flags"].get<int>());
    LONGS_EQUAL(3300 + i, r["battery_mv"].get<int>());
    CHECK(lw::core::ParseIsoTime(r["received"].get<std::string>()).has_value());
  }
  const int64_t t0_s = t0.time_since_epoch().count();
  STRCMP_EQUAL(("t" + std::to_string(t0_s + 3600) + "s12").c_str(), cursors[0].get<std::string>().c_str());
  STRCMP_EQUAL(("t" + std::to_string(t0_s + 7200) + "s14").c_str(), cursors[1].get<std::string>().c_str());
  // from/to inclusive: the hour holding seqs 12 and 13.
  const std::string hour = lw::core::FormatIsoTime(t0 + std::chrono::seconds(3600));
  const nlohmann::ordered_json window = f.Get(route, {Folder().id(), sensor}, {{"from", hour}, {"to", hour}}).json;
  LONGS_EQUAL(2, window["readings"].size());
  LONGS_EQUAL(12, window["readings"][0]["seq"].get<int>());
  CHECK(window["next_cursor"].is_null());
}

TEST(RestHandlers, PostedReadingsAreStoredOnceAndServedBack) {
  Fixture f;
  int after_ingest = 0;
  const auto publish = f.parts.ctx.after_ingest;
  f.parts.ctx.after_ingest = [&](const IngestResult& r) {
    ++after_ingest;
    publish(r);
  };
  f.resources = std::make_unique<rest::Resources>(f.parts.ctx);
  const size_t n = lw::test::Messages(Folder().bundle).size();
  const std::string all = Fixture::AllReadings();
  rest::Response res = f.PostReadings(all);
  LONGS_EQUAL(200, res.status);
  LONGS_EQUAL(n, res.json["stored"].get<size_t>());
  res = f.PostReadings(all);  // a redelivery
  LONGS_EQUAL(200, res.status);
  LONGS_EQUAL(0, res.json["stored"].get<size_t>());
  LONGS_EQUAL(n, res.json["duplicates"].get<size_t>());
  LONGS_EQUAL(2, after_ingest);
  // Every reading rejected: 422 with the reasons; each one quarantined, none lost.
  res = f.PostReadings(R"({"readings":[{"sensor":"1001","seq":1,"time":"2099-01-01T00:00:00Z"}]})");
  LONGS_EQUAL(422, res.status);
  STRCMP_EQUAL("every reading was rejected", ErrorOf(res).c_str());
  LONGS_EQUAL(1, res.json["errors"].size());
  // A reading dated an hour after the server's clock (4e9 s here) is held: not stored, counted, to be
  // posted again later; with nothing else in the post, 422.
  res = f.PostReadings(
      R"({"readings":[{"sensor":"1001","seq":77,"time":"2096-10-02T08:06:40Z","thickness_mm":100,"loops_intact":100,)"
      R"("flags":0,"battery_mv":3500}]})");
  LONGS_EQUAL(422, res.status);
  LONGS_EQUAL(1, res.json["held"].get<size_t>());
  LONGS_EQUAL(0, res.json["rejected"].get<size_t>());
  STRCMP_EQUAL("no reading was stored: each was rejected or held", ErrorOf(res).c_str());
  CHECK(res.json["errors"][0].get<std::string>().rfind("held REST reading: ", 0) == 0);
  STRCMP_EQUAL("body is not valid JSON", ErrorOf(f.PostReadings("{oops")).c_str());
  STRCMP_EQUAL("body must be {\"readings\": [...]}", ErrorOf(f.PostReadings("[1]")).c_str());
  STRCMP_EQUAL("body is nested too deeply", ErrorOf(f.PostReadings(R"({"readings":[[[[[[[[[[[[]]]]]]]]]]]]})")).c_str());
  LONGS_EQUAL(4, after_ingest);

  // The crusher's counters, its sensors' latest readings, and one sensor's readings page by page.
  const json detail = f.Get("/api/v1/crushers/{crusher}").json;
  LONGS_EQUAL(n, detail["counters"]["readings_stored"].get<size_t>());
  LONGS_EQUAL(n, detail["counters"]["duplicates"].get<size_t>());
  // This liner's readings start a day before installed_at (earlier ones: a previous liner's).
  STRCMP_EQUAL(lw::core::FormatIsoTime(lw::core::AddDays(Folder().bundle.crusher.installed_at, -1)).c_str(),
               detail["liner_start"].get<std::string>().c_str());
  const json sensors = f.Get("/api/v1/crushers/{crusher}/sensors").json;
  LONGS_EQUAL(Folder().bundle.crusher.sensors.size(), sensors["sensors"].size());
  size_t expected = 0;
  for (const auto& r : Folder().bundle.readings) expected += r.sensor_id == "1001";
  size_t got = 0;
  std::string cursor;
  const char* readings = "/api/v1/crushers/{crusher}/sensors/{sensor}/readings";
  do {
    QueryParams q = {{"limit", "50"}};
    if (!cursor.empty()) q.emplace("cursor", cursor);
    const rest::Response page = f.Get(readings, {Folder().id(), "1001"}, q);
    LONGS_EQUAL(200, page.status);
    CHECK(page.json["readings"].size() <= 50);
    got += page.json["readings"].size();
    cursor = page.json["next_cursor"].is_null() ? "" : page.json["next_cursor"].get<std::string>();
  } while (!cursor.empty());
  LONGS_EQUAL(expected, got);
  LONGS_EQUAL(400, f.Get(readings, {Folder().id(), "1001"}, {{"cursor", "bogus"}}).status);
  STRCMP_EQUAL("limit=0 must be in [1, 5000]", ErrorOf(f.Get(readings, {Folder().id(), "1001"}, {{"limit", "0"}})).c_str());
  const rest::Response unknown = f.Get(readings, {Folder().id(), "9999"});
  LONGS_EQUAL(404, unknown.status);
  STRCMP_EQUAL(("unknown sensor '9999' on crusher " + Folder().id()).c_str(), ErrorOf(unknown).c_str());

  // The quarantined message is listed; a bad limit is named.
  const rest::Response rejected = f.Get("/api/v1/rejected", {});
  LONGS_EQUAL(1, rejected.json["total"].get<int>());
  STRCMP_EQUAL("limit='x' is not a whole number in [1, 1000]", ErrorOf(f.Get("/api/v1/rejected", {}, {{"limit", "x"}})).c_str());
}

TEST(RestHandlers, WearAndForecastOnceThereAreReadings) {
  Fixture f;
  const char* wear = "/api/v1/crushers/{crusher}/wear";
  rest::Response res = f.Get(wear);
  LONGS_EQUAL(404, res.status);
  STRCMP_EQUAL(("no readings yet for crusher " + Folder().id()).c_str(), ErrorOf(res).c_str());
  LONGS_EQUAL(404, f.Get("/api/v1/crushers/{crusher}/forecast").status);
  LONGS_EQUAL(200, f.PostReadings(Fixture::AllReadings()).status);

  res = f.Get(wear);
  LONGS_EQUAL(200, res.status);
  LONGS_EQUAL(Folder().bundle.map.face_count(), res.json["remaining_mm"].size());
  CHECK_FALSE(f.Get(wear, {Folder().id()}, {{"faces", "false"}}).json.contains("remaining_mm"));
  // The setting's opening at the discharge ring: the lowest row's bottom, a number with its band,
  // no CSS without crusher.json's setting.css_mm.
  {
    const json& setting = res.json["setting"];
    const auto& rows = Folder().bundle.crusher.rows;
    const auto lowest =
        std::min_element(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a.z_min_m < b.z_min_m; });
    STRCMP_EQUAL(lowest->name.c_str(), setting["ring"]["row"].get<std::string>().c_str());
    const double opening = setting["opening_mm"].get<double>();
    CHECK(setting["opening_band_mm"][0].get<double>() <= opening && opening <= setting["opening_band_mm"][1].get<double>());
    DOUBLES_EQUAL(Folder().bundle.crusher.thickness_new_mm - setting["ring"]["thickness_mm"].get<double>(), opening, 0.02);
    CHECK(setting["css_mm"].is_null());
  }
  res = f.Get(wear, {Folder().id()}, {{"format", "png"}});
  LONGS_EQUAL(400, res.status);
  STRCMP_EQUAL("format='png': use json, vtk or csv", ErrorOf(res).c_str());
  // Per face as CSV: a header and one line per face, remaining thickness as in the JSON.
  res = f.Get(wear, {Folder().id()}, {{"format", "csv"}});
  CHECK(res.raw.has_value());
  STRCMP_EQUAL("text/csv; charset=utf-8", res.raw->content_type.c_str());
  CHECK(res.raw->content.rfind("face,row,z_m,theta_deg,remaining_mm,remaining_sd_mm,wear_mm\r\n", 0) == 0);
  LONGS_EQUAL(Folder().bundle.map.face_count() + 1, std::count(res.raw->content.begin(), res.raw->content.end(), '\n'));
  {
    const std::string& csv = res.raw->content;
    const size_t l1 = csv.find('\n') + 1;
    std::string first = csv.substr(l1, csv.find('\n', l1) - l1);
    for (int k = 0; k < 4; ++k) first = first.substr(first.find(',') + 1);
    DOUBLES_EQUAL(f.Get(wear).json["remaining_mm"][0].get<double>(), std::stod(first), 1e-3);
  }
  res = f.Get(wear, {Folder().id()}, {{"format", "vtk"}});
  CHECK(res.raw.has_value());
  STRCMP_EQUAL("application/octet-stream", res.raw->content_type.c_str());
  CHECK(res.raw->content.rfind("# vtk DataFile Version", 0) == 0);
  CHECK(res.raw->content.find("remaining_mm") != std::string::npos);
  CHECK(res.headers == (std::vector<std::pair<std::string, std::string>>{
                           {"Content-Disposition", "attachment; filename=\"" + Folder().id() + "_wear.vtk\""}}));

  const rest::Response forecast = f.Get("/api/v1/crushers/{crusher}/forecast");
  LONGS_EQUAL(200, forecast.status);
  LONGS_EQUAL(3, forecast.json["rows"].size());
  // A row's date is never later than its own sensors' (within a day and one loop's wear); the
  // sensor named as setting it belongs to that row.
  for (const auto& row : forecast.json["rows"]) {
    CHECK_TEXT(row.contains("reach_set_by_sensor"), row.dump().c_str());
    const std::string name = row["row"].get<std::string>();
    if (!row["reach_set_by_sensor"].is_null()) {
      const auto* info = Folder().bundle.crusher.FindSensor(row["reach_set_by_sensor"].get<std::string>());
      CHECK_TEXT(info != nullptr && info->row == name, row.dump().c_str());
    }
    if (!row["reach_date"].is_string()) continue;
    const auto row_reach = *lw::core::ParseIsoTime(row["reach_date"].get<std::string>());
    for (const auto& s : forecast.json["sensors"]) {
      const auto* info = Folder().bundle.crusher.FindSensor(s["id"].get<std::string>());
      if (!info || info->row != name || !(s.contains("ok") && s["ok"] == true) || !s["reach_date"].is_string()) continue;
      const double rate = std::max(s["rate_mm_per_day"].get<double>(), 1e-3);
      const auto limit = *lw::core::ParseIsoTime(s["reach_date"].get<std::string>()) +
                         std::chrono::seconds(static_cast<int64_t>((2.0 + 1.0 / rate) * 86400));
      CHECK_TEXT(row_reach <= limit, (row.dump() + " vs " + s.dump().substr(0, 200)).c_str());
    }
  }
  const rest::Response mesh = f.Get("/api/v1/crushers/{crusher}/mesh");
  LONGS_EQUAL(Folder().bundle.map.face_count() * 3, mesh.json["faces"].size());
  // The list shows the wear as last computed.
  const json list = f.Get("/api/v1/crushers", {}).json;
  LONGS_EQUAL(1, list["crushers"].size());
  DOUBLES_EQUAL(f.Get(wear).json["min_thickness_mm"].get<double>(), list["crushers"][0]["min_thickness_mm"].get<double>(), 1e-3);
}

// At startup the server answers while its wear worker loads and computes each crusher: the crusher
// list neither loads nor computes one on the request path (the first request is as fast as the
// later ones), and says "pending" until the crusher's wear is there.
TEST(RestHandlers, TheCrusherListNeverLoadsOrComputesAndSaysPending) {
  Fixture first;
  LONGS_EQUAL(200, first.PostReadings(Fixture::AllReadings()).status);
  ServerParts restarted(Folder().crushers, false, "", first.parts.db_path);
  // As the server starts: states loaded lazily (by the wear worker), nothing computed yet.
  restarted.live->LoadLazily(std::make_unique<lw::server::Store>(first.parts.db_path));
  std::atomic<bool> starting{true};
  restarted.ctx.starting = &starting;
  rest::Resources resources(restarted.ctx);
  const auto list = [&] {
    return lw::test::WithJson(resources.Call(rest::Resources::Find(rest::Method::kGet, "/api/v1/crushers"), {}))
        .json["crushers"][0];
  };
  // A crusher's own resources answer 503 until what they need is there, and compute nothing.
  const auto starting_503 = [&](const char* route, const char* what) {
    const rest::Response r = GetFrom(resources, route, Folder().id());
    LONGS_EQUAL_TEXT(503, r.status, route);
    CHECK_TEXT(r.json["error"].get<std::string>().find(what) != std::string::npos, r.json.dump().c_str());
    CHECK(std::find(r.headers.begin(), r.headers.end(), std::make_pair(std::string("Retry-After"), std::string("2"))) !=
          r.headers.end());
  };
  starting_503("/api/v1/crushers/{crusher}/sensors", "readings are not loaded yet");
  starting_503("/api/v1/crushers/{crusher}", "readings are not loaded yet");
  starting_503("/api/v1/crushers/{crusher}/wear", "wear is not computed yet");
  json entry = list();
  CHECK(entry["pending"].get<bool>());
  CHECK(entry["min_thickness_mm"].is_null());
  CHECK(entry["latest_reading_time"].is_null());
  CHECK_FALSE(restarted.live->Loaded(Folder().id()));       // the request loaded nothing
  CHECK(restarted.wear->Latest(Folder().id()) == nullptr);  // and computed nothing
  // The wear worker's first pass: loaded, then computed.
  CHECK(restarted.live->LatestUsableTime(Folder().id()).has_value());
  entry = list();
  CHECK(entry["pending"].get<bool>());
  CHECK(entry["latest_reading_time"].is_string());
  LONGS_EQUAL(200, GetFrom(resources, "/api/v1/crushers/{crusher}/sensors", Folder().id()).status);
  starting_503("/api/v1/crushers/{crusher}/forecast", "wear is not computed yet");
  CHECK(restarted.wear->Latest(Folder().id()) == nullptr);
  const auto st = restarted.wear->Get(Folder().id());
  LONGS_EQUAL(200, GetFrom(resources, "/api/v1/crushers/{crusher}/forecast", Folder().id()).status);
  entry = list();
  CHECK_FALSE(entry["pending"].get<bool>());
  DOUBLES_EQUAL(st->reconstruction.min_thickness_mm, entry["min_thickness_mm"].get<double>(), 1e-9);
  const json wear = GetFrom(resources, "/api/v1/crushers/{crusher}/wear", Folder().id()).json;
  DOUBLES_EQUAL(wear["min_thickness_mm"].get<double>(), entry["min_thickness_mm"].get<double>(), 1e-3);
}

// The list keeps each crusher's entry as text while what it shows is unchanged: after more
// readings are committed it shows the new latest reading time, byte for byte what a list built
// from nothing shows.
TEST(RestHandlers, TheCrusherListShowsNewReadingsAsAListBuiltAfreshDoes) {
  Fixture f;
  const json all = json::parse(Fixture::AllReadings());
  const auto split = lw::core::FormatIsoTime(lw::core::AddDays(Folder().bundle.crusher.installed_at, 3));
  json early = {{"readings", json::array()}}, late = {{"readings", json::array()}};
  for (const auto& r : all["readings"]) (r["time"].get<std::string>() < split ? early : late)["readings"].push_back(r);
  CHECK(!early["readings"].empty() && !late["readings"].empty());
  const auto list = [](rest::Resources& resources) {
    const rest::Response r = resources.Call(rest::Resources::Find(rest::Method::kGet, "/api/v1/crushers"), {});
    LONGS_EQUAL(200, r.status);
    return r.raw ? r.raw->content : r.json.dump();
  };
  PostReadingsTo(*f.resources, Folder().id(), early);
  const std::string first = list(*f.resources);
  STRCMP_EQUAL(first.c_str(), list(*f.resources).c_str());
  PostReadingsTo(*f.resources, Folder().id(), late);
  const std::string second = list(*f.resources);
  rest::Resources fresh(f.parts.ctx);
  STRCMP_EQUAL(list(fresh).c_str(), second.c_str());
  const json a = json::parse(first)["crushers"][0], b = json::parse(second)["crushers"][0];
  CHECK(a["latest_reading_time"].is_string() && b["latest_reading_time"].is_string());
  CHECK_TEXT(a["latest_reading_time"].get<std::string>() < split, a.dump().substr(0, 300).c_str());
  CHECK_TEXT(b["latest_reading_time"].get<std::string>() >= split, b.dump().substr(0, 300).c_str());
}

// The headline of GET .../wear (and of each row) is the thinnest area the data support, in the
// documented shape, as core computes it offline (what `linerwatch reconstruct` prints); the faces'
// own counts of zero thickness stay with the faces, never as "worn through".
void CheckArea(const json& served, const lw::core::ThinnestArea& expected) {
  for (const char* key :
       {"thickness_mm", "band_mm", "patch_m", "z_m", "theta_deg", "supported", "extrapolated", "nearest_sensor_m"})
    CHECK_TEXT(served.contains(key), key);
  const json want = json::parse(lw::core::ThinnestAreaJson(expected).dump());
  DOUBLES_EQUAL(want["thickness_mm"].get<double>(), served["thickness_mm"].get<double>(), 0.011);
  LONGS_EQUAL(2, served["band_mm"].size());
  DOUBLES_EQUAL(want["band_mm"][1].get<double>(), served["band_mm"][1].get<double>(), 0.011);
  CHECK(want["patch_m"] == served["patch_m"]);
  CHECK(want["supported"] == served["supported"]);
  CHECK(want["extrapolated"] == served["extrapolated"]);
  CHECK(want["row"] == served["row"]);
}

TEST(RestHandlers, WearLeadsWithTheThinnestAreaTheDataSupportAtTheLinerAndEachRow) {
  Fixture f;
  LONGS_EQUAL(200, f.PostReadings(Fixture::AllReadings()).status);
  const json wear = f.Get("/api/v1/crushers/{crusher}/wear").json;
  const lw::core::ThinnestAreas expected = lw::test::OfflineThinnestAreas(Folder().bundle, lw::core::TimePoint::max());
  CheckArea(wear["thinnest_area"], expected.liner);
  LONGS_EQUAL(expected.rows.size(), wear["rows"].size());
  for (size_t k = 0; k < expected.rows.size(); ++k) CheckArea(wear["rows"][k]["thinnest_area"], expected.rows[k]);
  CHECK(wear["worn_through"] == wear["thinnest_area"]["worn_through"]);
  CHECK_FALSE(wear.contains("worn_through_faces"));
  CHECK(wear["face_level"].contains("estimate_at_zero_faces"));
  // The forecast's rows say whether they are below the minimum and why a date is missing.
  const json forecast = f.Get("/api/v1/crushers/{crusher}/forecast").json;
  for (const auto& r : forecast["rows"]) {
    CHECK(r.contains("below_minimum_since"));
    CHECK(r.contains("rate_sd_mm_per_day"));
    if (r["reach_date"].is_null() && !r.contains("note")) CHECK_TEXT(r.contains("reach_note"), r.dump().c_str());
  }
}

// docs/server.md, *Laser scans*: "Every wear result names the scan it applied (`scan`: file, date,
// points used, faces corrected, `faces_filled` from their neighbours, median corrected/map ratio,
// the map's relative pattern error; `null` without a scan; `applied: false` with a `detail` when no
// row had a sensor reading at the scan's date)." Checked on GET .../wear against the correction
// computed offline from the same folder and readings (core's ProjectScanToFaces and ApplyScan, as
// `linerwatch reconstruct` does).
TEST(RestHandlers, WearNamesTheScanItAppliedWithTheDocumentedFields) {
  Fixture f;
  LONGS_EQUAL(200, f.PostReadings(Fixture::AllReadings()).status);
  const lw::core::Bundle& b = Folder().bundle;
  const lw::core::Scan* scan = lw::core::LatestScanAt(b.scans, lw::core::TimePoint::max());
  CHECK(scan != nullptr);
  const lw::core::ScanFaces faces = lw::core::ProjectScanToFaces(b.map, *scan);
  lw::core::ReconstructionPlan plan = lw::core::PrepareReconstruction(b.crusher, b.map);
  const lw::core::ScanCorrection expected =
      lw::core::ApplyScan(plan, faces, lw::core::SensorWearAt(b.crusher, b.readings, scan->date));
  CHECK_TRUE(expected.detail.empty());

  for (const char* with_faces : {"true", "false"}) {
    const rest::Response res = f.Get("/api/v1/crushers/{crusher}/wear", {Folder().id()}, {{"faces", with_faces}});
    LONGS_EQUAL(200, res.status);
    const json& j = res.json.at("scan");
    std::set<std::string> keys;
    for (const auto& [key, value] : j.items()) keys.insert(key);
    CHECK_TEXT(keys == (std::set<std::string>{"file", "date", "points_used", "points_total", "applied", "faces_corrected",
                                              "faces_filled", "median_ratio", "map_model_error_relative"}),
               j.dump().c_str());
    STRCMP_EQUAL(scan->file.c_str(), j["file"].get<std::string>().c_str());
    STRCMP_EQUAL(lw::core::FormatIsoTime(scan->date).c_str(), j["date"].get<std::string>().c_str());
    CHECK_TRUE(j["applied"].get<bool>());
    LONGS_EQUAL(faces.points_total, j["points_total"].get<size_t>());
    LONGS_EQUAL(faces.points_used, j["points_used"].get<size_t>());
    LONGS_EQUAL(scan->points.size(), j["points_total"].get<size_t>());
    CHECK(j["points_used"].get<size_t>() > 0 && j["points_used"].get<size_t>() <= j["points_total"].get<size_t>());
    LONGS_EQUAL(expected.faces_corrected, j["faces_corrected"].get<size_t>());
    LONGS_EQUAL(expected.faces_filled, j["faces_filled"].get<size_t>());
    CHECK(j["faces_corrected"].get<size_t>() > 0 && j["faces_corrected"].get<size_t>() <= b.map.face_count());
    DOUBLES_EQUAL(expected.median_ratio, j["median_ratio"].get<double>(), 0.5e-3 + 1e-12);
    DOUBLES_EQUAL(expected.map_model_error_rel, j["map_model_error_relative"].get<double>(), 0.5e-3 + 1e-12);
    CHECK(j["median_ratio"].get<double>() > 0);
    CHECK(j["map_model_error_relative"].get<double>() >= 0);
  }
}

TEST(RestHandlers, WearWithoutAScanHasScanNull) {
  // The fixture's crusher folder without its scans/.
  lw::test::TempDirectory dir{"lw-rest-noscan"};
  const std::filesystem::path folder = std::filesystem::path(dir.File("crushers")) / "demo";
  std::filesystem::create_directories(folder);
  for (const char* file : {"crusher.json", "wear_map.vtk"})
    std::filesystem::copy_file(Folder().folder + "/" + file, folder / file);
  ServerParts parts(dir.File("crushers"), false);
  CHECK_TRUE(parts.registry->Find(Folder().id())->scans.empty());
  rest::Resources resources(parts.ctx);
  const std::string readings = Fixture::AllReadings();  // Request::body is a view
  rest::Request post;
  post.path = {Folder().id()};
  post.body = readings;
  const rest::Response posted =
      resources.Call(rest::Resources::Find(rest::Method::kPost, "/api/v1/crushers/{crusher}/readings"), post);
  LONGS_EQUAL_TEXT(200, posted.status, posted.json.dump().substr(0, 500).c_str());
  rest::Request get;
  get.path = {Folder().id()};
  const rest::Response res =
      lw::test::WithJson(resources.Call(rest::Resources::Find(rest::Method::kGet, "/api/v1/crushers/{crusher}/wear"), get));
  LONGS_EQUAL(200, res.status);
  CHECK_TEXT(res.json.contains("scan"), res.json.dump().substr(0, 500).c_str());
  CHECK_TRUE(res.json["scan"].is_null());
}

TEST(RestHandlers, AScanWithoutReadingsAtItsDateIsNamedNotApplied) {
  // Only the readings after the scan's date: no row has a reading at that date.
  lw::test::CrusherFolder folder(10, 5, 3);
  const lw::core::Scan& scan = folder.bundle.scans.at(0);
  ServerParts parts(folder.crushers, false);
  rest::Resources resources(parts.ctx);
  json body = {{"readings", json::array()}};
  for (const auto& m : lw::test::Messages(folder.bundle)) {
    json r = json::parse(m.payload);
    if (lw::core::ParseIsoTime(r["time"].get<std::string>()).value() > scan.date) body["readings"].push_back(r);
  }
  CHECK(!body["readings"].empty());
  PostReadingsTo(resources, folder.id(), body);
  const rest::Response res = GetFrom(resources, "/api/v1/crushers/{crusher}/wear", folder.id());
  LONGS_EQUAL(200, res.status);
  const json& j = res.json.at("scan");
  std::set<std::string> keys;
  for (const auto& [key, value] : j.items()) keys.insert(key);
  CHECK_TEXT(keys == (std::set<std::string>{"file", "date", "points_used", "points_total", "applied", "detail"}),
             j.dump().c_str());
  CHECK_FALSE(j["applied"].get<bool>());
  STRCMP_EQUAL("no row has a sensor reading at the scan's date", j["detail"].get<std::string>().c_str());
  STRCMP_EQUAL(scan.file.c_str(), j["file"].get<std::string>().c_str());
  STRCMP_EQUAL(lw::core::FormatIsoTime(scan.date).c_str(), j["date"].get<std::string>().c_str());
}

// docs/wear.md, *Global wear*: a sensor whose latest reading lags the newest by more than 8 of
// its reporting periods (a dead sensor) sets no row scale and is named in `sensors_stale`. Its old
// reading would give the wear of its last day, too little. The live wear must equal the wear
// computed without that sensor at all, and differ from the one its stale wear would give.
TEST(RestHandlers, ADeadSensorSetsNoRowScaleAndIsNamedStale) {
  lw::test::CrusherFolder folder(10, 5);
  const lw::core::Bundle& b = folder.bundle;
  // A sensor that shares its row with another: the row keeps a scale without it.
  std::string dead;
  for (const auto& s : b.crusher.sensors) {
    int in_row = 0;
    for (const auto& o : b.crusher.sensors) in_row += o.row == s.row;
    if (in_row >= 2) {
      dead = s.id;
      break;
    }
  }
  CHECK(!dead.empty());
  const lw::core::TimePoint cut = lw::core::AddDays(b.crusher.installed_at, 3.0);
  json body = {{"readings", json::array()}};
  lw::core::Bundle without = b;  // the same crusher with the dead sensor never reporting
  std::erase_if(without.readings, [&](const lw::core::Reading& r) { return r.sensor_id == dead; });
  std::vector<lw::core::Reading> posted_readings;
  lw::core::TimePoint last{};
  for (const auto& m : lw::test::Messages(b)) {
    json r = json::parse(m.payload);
    const lw::core::TimePoint t = lw::core::ParseIsoTime(r["time"].get<std::string>()).value();
    if (r["sensor"] == dead && t > cut) continue;
    body["readings"].push_back(r);
    last = std::max(last, t);
  }
  for (const auto& r : b.readings)
    if (r.sensor_id != dead || r.time <= cut) posted_readings.push_back(r);
  ServerParts parts(folder.crushers, false);
  rest::Resources resources(parts.ctx);
  PostReadingsTo(resources, folder.id(), body);
  const rest::Response res = GetFrom(resources, "/api/v1/crushers/{crusher}/wear", folder.id());
  LONGS_EQUAL(200, res.status);
  CHECK_TEXT(res.json["sensors_stale"] == json::array({dead}), res.json["sensors_stale"].dump().c_str());
  for (const auto& u : res.json["readings_used"]) CHECK(u["sensor"] != dead);
  LONGS_EQUAL(b.crusher.sensors.size() - 1, res.json["readings_used"].size());
  const lw::core::Reconstruction expected = lw::test::OfflineLiveWear(without, last);
  DOUBLES_EQUAL(expected.min_thickness_mm, res.json["min_thickness_mm"].get<double>(), 1e-3);
  // The stale wear would have set the row's scale (at the scan's date and now): less wear there.
  lw::core::ReconstructionPlan plan = lw::core::PrepareReconstruction(b.crusher, b.map);
  const lw::core::Scan* scan = lw::core::LatestScanAt(b.scans, lw::core::TimePoint::max());
  CHECK(scan != nullptr);
  lw::core::ApplyScan(plan, lw::core::ProjectScanToFaces(b.map, *scan),
                      lw::core::SensorWearAt(b.crusher, posted_readings, scan->date));
  const lw::core::Reconstruction stale = lw::core::Reconstruct(plan, lw::core::SensorWearAt(b.crusher, posted_readings, last));
  const std::string row = b.crusher.FindSensor(dead)->row;
  CheckRowWearLeftOut(res.json, expected, stale, row, "stale");
  // The row keeps its reline date from the fresh sensor.
  const rest::Response forecast = GetFrom(resources, "/api/v1/crushers/{crusher}/forecast", folder.id());
  for (const auto& r : forecast.json["rows"])
    if (r["row"] == row) CHECK_TEXT(!r.contains("note"), r.dump().c_str());
}

namespace {

// docs/wear.md, *Global wear*: a sensor that keeps reporting one value while the other sensors of
// its row wear (moisture across its loops) sets no row scale and is named in `sensors_stuck`. Its
// frozen value would give its row too little wear: the live wear is the one without its reading.
// The scan is corrected with the sensors' wear at its date: without the stuck sensor's when its value
// had already frozen then (core::ScanSensorWear).
void CheckStuckSensor(double days, double scan_day, double frozen_from_day) {
  lw::test::CrusherFolder folder(days, 7, scan_day);
  const lw::core::Bundle& b = folder.bundle;
  std::string stuck;  // a sensor of the lowest row (the fastest wear), which has others
  for (const auto& s : b.crusher.sensors) {
    int in_row = 0;
    for (const auto& o : b.crusher.sensors) in_row += o.row == s.row;
    if (in_row >= 2 && s.row == b.crusher.rows.front().name) stuck = s.id;
  }
  CHECK(!stuck.empty());
  // From `frozen_from_day` its value stops moving; it keeps reporting (heartbeats).
  const lw::core::TimePoint from = lw::core::AddDays(b.crusher.installed_at, frozen_from_day);
  double frozen = 0;
  for (const auto& r : b.readings)
    if (r.sensor_id == stuck && r.time <= from) frozen = r.thickness_mm;
  lw::core::Bundle posted = b;
  for (auto& r : posted.readings)
    if (r.sensor_id == stuck && r.time > from) r.thickness_mm = frozen;
  json body = {{"readings", json::array()}};
  lw::core::TimePoint last{};
  for (const auto& m : lw::test::Messages(posted)) {
    json r = json::parse(m.payload);
    last = std::max(last, lw::core::ParseIsoTime(r["time"].get<std::string>()).value());
    body["readings"].push_back(r);
  }
  ServerParts parts(folder.crushers, false);
  rest::Resources resources(parts.ctx);
  PostReadingsTo(resources, folder.id(), body);
  const rest::Response res = GetFrom(resources, "/api/v1/crushers/{crusher}/wear", folder.id());
  LONGS_EQUAL(200, res.status);
  CHECK_TEXT(res.json["sensors_stuck"] == json::array({stuck}), res.json["sensors_stuck"].dump().c_str());
  CHECK_TEXT(res.json["sensors_stale"].empty(), res.json["sensors_stale"].dump().c_str());
  for (const auto& u : res.json["readings_used"]) CHECK(u["sensor"] != stuck);
  // Expected: the newest scan's correction with the sensors' wear at its date (the stuck one's only
  // when it had not frozen yet), the live scales without the stuck sensor's wear; with it, its row
  // would show less wear.
  const lw::core::Scan* scan = lw::core::LatestScanAt(b.scans, lw::core::TimePoint::max());
  CHECK(scan != nullptr);
  const bool frozen_at_scan = from < scan->date;
  const std::vector<lw::core::SensorWear> at_scan = lw::core::ScanSensorWear(b.crusher, posted.readings, scan->date, {stuck});
  const std::vector<lw::core::SensorWear> all_at_scan = lw::core::FreshSensorWearAt(b.crusher, posted.readings, scan->date);
  LONGS_EQUAL(all_at_scan.size() - (frozen_at_scan ? 1 : 0), at_scan.size());
  lw::core::ReconstructionPlan plan = lw::core::PrepareReconstruction(b.crusher, b.map);
  lw::core::ReconstructionPlan plan_all = plan;
  lw::core::ApplyScan(plan, lw::core::ProjectScanToFaces(b.map, *scan), at_scan);
  lw::core::ApplyScan(plan_all, lw::core::ProjectScanToFaces(b.map, *scan), all_at_scan);
  std::vector<lw::core::SensorWear> with = lw::core::FreshSensorWearAt(b.crusher, posted.readings, last);
  std::vector<lw::core::SensorWear> without = with;
  std::erase_if(without, [&](const lw::core::SensorWear& w) { return w.sensor_id == stuck; });
  LONGS_EQUAL(with.size() - 1, without.size());
  const lw::core::Reconstruction expected = lw::core::Reconstruct(plan, without);
  const lw::core::Reconstruction frozen_rec = lw::core::Reconstruct(plan, with);
  DOUBLES_EQUAL(expected.min_thickness_mm, res.json["min_thickness_mm"].get<double>(), 1e-3);
  CheckRowWearLeftOut(res.json, expected, frozen_rec, b.crusher.FindSensor(stuck)->row, "frozen");
  if (frozen_at_scan) {
    // The frozen wear at the scan would have set the scan's correction otherwise: by 7 mm at some
    // faces here (its row's scale at the scan moves the correction around the sensors).
    const lw::core::Reconstruction scan_with = lw::core::Reconstruct(plan_all, without);
    const double moved = (expected.remaining_mm - scan_with.remaining_mm).cwiseAbs().maxCoeff();
    CHECK_TEXT(moved > 2.0, std::to_string(moved).c_str());
  }
  // Its frozen curve gives no forecast: `ok` false, no reach date, a note saying why.
  const rest::Response forecast = GetFrom(resources, "/api/v1/crushers/{crusher}/forecast", folder.id());
  int seen = 0;
  for (const auto& f : forecast.json["sensors"]) {
    if (f["id"] != stuck) continue;
    ++seen;
    CHECK_FALSE(f["ok"].get<bool>());
    CHECK_TEXT(f["note"].get<std::string>().find("stuck") != std::string::npos, f.dump().c_str());
    CHECK_TEXT(!f.contains("reach_date") || f["reach_date"].is_null(), f.dump().c_str());
  }
  LONGS_EQUAL(1, seen);
}

}  // namespace

TEST(RestHandlers, AStuckSensorSetsNoRowScaleAndIsNamedStuck) {
  CheckStuckSensor(30, 10, 20);
}

TEST(RestHandlers, ASensorFrozenBeforeTheScanSetsNoScaleAtTheScanEither) {
  CheckStuckSensor(60, 30, 20);
}

TEST(RestHandlers, HealthMergesTheServersFieldsAndReportsDegraded) {
  Fixture f;
  rest::Response res = f.Get("/healthz", {});
  LONGS_EQUAL(200, res.status);
  STRCMP_EQUAL(R"({"status":"ok","version":"0.1.0","db":"ok"})", res.json.dump().c_str());
  f.parts.ctx.health = [] { return nlohmann::ordered_json{{"status", "degraded"}, {"reason", "disk full"}}; };
  f.resources = std::make_unique<rest::Resources>(f.parts.ctx);
  res = f.Get("/healthz", {});
  LONGS_EQUAL(503, res.status);
  STRCMP_EQUAL(R"({"status":"degraded","version":"0.1.0","db":"ok","reason":"disk full"})", res.json.dump().c_str());
}

TEST(RestHandlers, WhoAmINamesTheTokensScopes) {
  Fixture open;
  STRCMP_EQUAL(R"({"auth":false,"name":null,"scopes":["read","write"]})", open.Get("/api/v1/whoami", {}).json.dump().c_str());
  Fixture with_tokens(true);
  rest::Request r;
  r.bearer = ServerParts::kReadToken;
  STRCMP_EQUAL(R"({"auth":true,"name":"reader","scopes":["read"]})",
               with_tokens.Call(rest::Method::kGet, "/api/v1/whoami", r).json.dump().c_str());
  r.bearer = ServerParts::kWriteToken;
  STRCMP_EQUAL(R"({"auth":true,"name":"writer","scopes":["read","write"]})",
               with_tokens.Call(rest::Method::kGet, "/api/v1/whoami", r).json.dump().c_str());
}

TEST(RestHandlers, TheOpenApiRouteServesTheGeneratedDocument) {
  Fixture f;
  const rest::Response res = f.Get("/api/v1/openapi.json", {});
  CHECK(res.raw.has_value());
  STRCMP_EQUAL("application/json", res.raw->content_type.c_str());
  CHECK(res.raw->content == OpenApiJson());
}

TEST(RestHandlers, DiagnosisStatusAndAFailedRun) {
  Fixture f;
  const char* diagnosis = "/api/v1/crushers/{crusher}/diagnosis";
  rest::Response res = f.Get(diagnosis);
  CHECK(res.raw.has_value());
  STRCMP_EQUAL(R"({"status":"none","time":null,"result":null})", res.raw->content.c_str());
  // A run that fails (the runner is asked about a crusher it cannot find) reports why.
  CHECK(f.parts.diagnosis->Start("no-such-crusher"));
  json status;
  for (int i = 0; i < 6000; ++i) {  // up to 60 s: the run is a thread, slow to start on a loaded machine
    status = json::parse(f.parts.diagnosis->StatusJson("no-such-crusher"));
    if (status["status"] != "running") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  STRCMP_EQUAL("failed", status["status"].get<std::string>().c_str());
  STRCMP_EQUAL("unknown crusher", status["error"].get<std::string>().c_str());
  // Without a runner both diagnosis routes answer 503.
  f.parts.ctx.diagnosis = nullptr;
  f.resources = std::make_unique<rest::Resources>(f.parts.ctx);
  LONGS_EQUAL(503, f.Get(diagnosis).status);
  rest::Request post;
  post.path = {Folder().id()};
  res = f.Call(rest::Method::kPost, diagnosis, post);
  LONGS_EQUAL(503, res.status);
  STRCMP_EQUAL("diagnosis is not available on this server", ErrorOf(res).c_str());
}

TEST(RestHandlers, EventStreamsAreCountedAndCarryTheCrushersEvents) {
  Fixture f(false, 2);  // 2 workers: one event stream at most
  const char* events = "/api/v1/crushers/{crusher}/events";
  rest::Response first = f.Get(events);
  CHECK(first.stream != nullptr);
  CHECK(first.headers ==
        (std::vector<std::pair<std::string, std::string>>{{"Cache-Control", "no-cache"}, {"X-Accel-Buffering", "no"}}));
  rest::Response refused = f.Get(events);
  LONGS_EQUAL(503, refused.status);
  STRCMP_EQUAL("too many open event streams (1); retry later", ErrorOf(refused).c_str());

  const auto never_gone = [] { return false; };
  STRCMP_EQUAL("retry: 3000\n: connected\n\n", first.stream->Next(never_gone).value().c_str());
  f.parts.events.Publish("other-crusher", "reading", "{}");
  f.parts.events.Publish(Folder().id(), "wear", R"({"x":1})");
  STRCMP_EQUAL("id: 2\nevent: wear\ndata: {\"x\":1}\n\n", first.stream->Next(never_gone).value().c_str());
  // A client gone is noticed within a second while no event arrives.
  CHECK_FALSE(first.stream->Next([] { return true; }));

  first = {};  // the stream ends: its slot is free again
  rest::Request resume;
  resume.path = {Folder().id()};
  resume.last_event_id = "12000";  // from before a restart: "from now on"
  rest::Response second = f.Call(rest::Method::kGet, events, resume);
  CHECK(second.stream != nullptr);
  second.stream->Next(never_gone);
  f.parts.events.Publish(Folder().id(), "reading", R"({"seq":1})");
  STRCMP_EQUAL("id: 3\nevent: reading\ndata: {\"seq\":1}\n\n", second.stream->Next(never_gone).value().c_str());
  f.resources->Stop();
  CHECK_FALSE(second.stream->Next(never_gone));
}
