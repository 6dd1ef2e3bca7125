#pragma once
/// The REST API (docs/server.md) as resources apart from HTTP: each route is a handler that takes
/// a Request (its path parameters, query, body, token) and returns a Response ({status, json}, or
/// a body of another type, or an event stream). One table, Routes(), lists every route with what
/// the OpenAPI document says of it: HttpApi (server/http_api.hpp) routes requests by it and
/// OpenApiJson() (server/openapi.hpp) is generated from it, so neither can list a route the other
/// does not.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "server/api_context.hpp"
#include "server/query.hpp"

namespace lw::server::rest {

enum class Method { kGet, kPost };
const char* MethodName(Method method);  ///< "GET", "POST"

/// True for a state-changing method: every method but GET and HEAD.
bool Writes(std::string_view method);

/// The token scope a request needs when the server runs with --tokens.
enum class Scope { kNone, kRead, kWrite };
const char* ScopeName(Scope scope);  ///< "none", "read", "write" (OpenAPI's x-scope)
/// The rule the HTTP front end enforces before routing, and the OpenAPI document states: nothing
/// outside /api/ but /metrics (read), the write scope for a method that Writes(), the read scope otherwise.
Scope RequiredScope(std::string_view method, std::string_view path);

struct Request {
  std::vector<std::string> path;  ///< the route's path parameters, in order ({crusher}, {sensor})
  QueryParams query;              ///< decoded query parameters
  std::string_view body;          ///< the request body (valid while the handler runs)
  std::string bearer;             ///< the bearer token presented (empty: none)
  std::string last_event_id;      ///< the Last-Event-ID header (event stream; empty: none)
  std::string client;             ///< the client's IP address (per-address limits)
};

/// A body that is not JSON made here (the OpenAPI text, a VTK file, a JSON document made elsewhere).
struct RawBody {
  std::string content;
  std::string content_type;
};

class EventStream;

struct Response {
  int status = 200;
  nlohmann::ordered_json json;  ///< the body, sent as application/json, unless `raw` or `stream` is set
  std::optional<RawBody> raw;
  std::shared_ptr<EventStream> stream;                       ///< set: a text/event-stream body
  std::vector<std::pair<std::string, std::string>> headers;  ///< extra response headers
};

/// {status, {"error": message}}: every error of the API (docs/server.md).
Response Error(int status, const std::string& message);

/// One open Server-Sent Events stream of a crusher (GET .../events). The HTTP layer calls Next() on
/// the worker thread that serves the stream, one call at a time, and sends each chunk it returns.
class EventStream {
 public:
  /// The next chunk: first the `retry` preamble, then the events after the last one sent (waiting
  /// up to 15 s for one, then a keepalive comment). nullopt when the stream must end: the server is
  /// stopping, `client_gone()` (asked about once a second while waiting) says the client left, or
  /// the stream reached its lifetime (HttpLimits::event_stream_lifetime_s; EventSource reconnects
  /// with Last-Event-ID and misses nothing).
  std::optional<std::string> Next(const std::function<bool()>& client_gone);

 private:
  friend class Resources;
  EventStream(EventBus& events, const std::atomic<bool>& stopping, std::string crusher, int64_t after, std::shared_ptr<void> slot,
              std::chrono::steady_clock::time_point ends_at)
      : events_(events),
        stopping_(stopping),
        crusher_(std::move(crusher)),
        after_(after),
        slot_(std::move(slot)),
        ends_at_(ends_at) {}
  bool Expired() const { return std::chrono::steady_clock::now() >= ends_at_; }
  EventBus& events_;
  const std::atomic<bool>& stopping_;
  std::string crusher_;
  int64_t after_;
  bool first_ = true;
  std::shared_ptr<void> slot_;  ///< counts this stream while it exists
  std::chrono::steady_clock::time_point ends_at_;
};

class Resources;

/// A documented query parameter (OpenAPI).
struct QueryDoc {
  const char* name;
  const char* type;  ///< "string", "integer", "boolean"
  const char* description;
  std::vector<const char*> values = {};  ///< the values it takes (an OpenAPI enum); empty: any of its type
};

/// A body limit for routes whose body is a small JSON document or nothing.
inline constexpr uint64_t kSmallBodyBytes = 64 * 1024;
/// The deepest nesting of [ and { an alarm rules, reline or void body may have (theirs is 3 at
/// most: a reline's sensor objects). A deeper body is refused before it is parsed: copying or
/// printing a parsed JSON value recurses once per level, and 64 KiB nest 32,000 deep.
inline constexpr size_t kMaxSmallBodyDepth = 8;
/// A reline's body: its end-of-life scan may be a few hundred thousand points (~30 bytes a line).
inline constexpr uint64_t kMaxRelineBodyBytes = 16u << 20;
/// Readings one POST may carry.
inline constexpr size_t kMaxPostedReadings = 10000;
/// Bytes allowed for each posted reading: the largest reading the gateway encodes (every optional
/// field, a 64-character sensor id and gateway name: about 450 bytes) with room for whitespace.
inline constexpr uint64_t kPostedReadingBytes = 1024;
/// The readings route's body limit: 10,000 readings of kPostedReadingBytes and the envelope, so
/// that a body is refused as it arrives, not after it is parsed whole.
inline constexpr uint64_t kMaxReadingsBodyBytes = kMaxPostedReadings * kPostedReadingBytes + 4096;

/// A status a route's handler answers besides its success status (OpenAPI): why, and the body's
/// schema (null: the API's error body {"error": ...}). The statuses of the HTTP layer (http_api.cpp,
/// http_guard.cpp) are added to every operation by the OpenAPI generator.
struct StatusDoc {
  const char* status;
  const char* description;
  const char* schema = nullptr;
};

struct Route {
  Method method;
  /// OpenAPI path template; {name} is one path segment, passed in Request::path in order.
  const char* path;
  const char* summary;
  std::vector<QueryDoc> query;
  const char* ok_status;  ///< the success status the OpenAPI document names ("200", "202")
  Response (Resources::*handler)(const Request&);
  /// The media types of the success response (OpenAPI): JSON unless the route says otherwise.
  std::vector<const char*> content_types = {"application/json"};
  /// The largest request body the route accepts, checked as the head arrives (Content-Length) or
  /// as a chunked body arrives, before any of it is buffered: 413 beyond.
  uint64_t max_body_bytes = kSmallBodyBytes;
  /// JSON schemas (OpenAPI, as JSON text) of the request body and the success response (JSON
  /// routes; server/src/rest_schemas.hpp); null: a body-less request, a response that is not JSON.
  const char* request_schema = nullptr;
  const char* response_schema = nullptr;
  /// The other statuses the handler answers (404 for an unknown {crusher} is the generator's).
  std::vector<StatusDoc> statuses = {};
};

/// How a request's method and decoded path meet the route table: the HTTP front end answers 404
/// (no route has the path) or 405 (another method has it) before it reads a body.
struct RouteMatch {
  const Route* route = nullptr;  ///< the route serving the request; null when none
  bool path_known = false;       ///< some route has the path
  /// The values of the route's {name} segments in order (what its regular expression captures).
  std::vector<std::string> args;
};
/// `path` is the decoded request path (no query); HEAD is matched as GET.
RouteMatch MatchRoute(std::string_view method, std::string_view path);

/// The names of `path_template`'s parameters in order: "crusher", "sensor".
std::vector<std::string> PathParams(std::string_view path_template);
/// The regular expression the HTTP layer routes `path_template` by: each {name} becomes ([^/]+),
/// the rest is kept as it is.
std::string PathPattern(std::string_view path_template);

/// The API's resources over the server's parts. Handlers are called on the HTTP worker threads,
/// several at once; each is safe to call concurrently (readings posts are handled one at a time).
class Resources {
 public:
  explicit Resources(const ApiContext& context);
  Resources(const Resources&) = delete;
  Resources& operator=(const Resources&) = delete;

  /// Every route of the API, in the order of the OpenAPI document.
  static const std::vector<Route>& Routes();
  /// The route of `method` and `path_template`; throws std::out_of_range when there is none.
  static const Route& Find(Method method, std::string_view path_template);

  /// Runs `route`'s handler. Throws what the handler throws (the HTTP layer answers 500).
  Response Call(const Route& route, const Request& request) { return (this->*route.handler)(request); }

  /// Ends every event stream (their next Next() returns nullopt); new streams end at once.
  void Stop() { stopping_ = true; }

 private:
  /// Routes(), in three parts (each a table of its handlers).
  static std::vector<Route> ReadingRoutes();
  static std::vector<Route> WearRoutes();
  static std::vector<Route> AlarmAndServiceRoutes();
  Response Health(const Request&);
  Response Crushers(const Request&);
  Response CrusherDetail(const Request&);
  Response Sensors(const Request&);
  Response Readings(const Request&);
  Response PostReadings(const Request&);
  Response Mesh(const Request&);
  /// The live state, or with ?at=TIME a past time's (400 naming `at`, 404 before any reading).
  std::shared_ptr<const CrusherState> StateOf(const Request& req, const Crusher& c, Response* error);
  /// While the server starts: true (and *error a 503 with Retry-After) when `c`'s state is not
  /// loaded yet (`need_wear`: or its wear not computed yet), so that no request loads or computes it.
  bool Starting(const Crusher& c, bool need_wear, Response* error);
  Response Wear(const Request&);
  Response Forecast(const Request&);
  Response Diagnosis(const Request&);
  Response StartDiagnosis(const Request&);
  Response PostReline(const Request&);
  Response CampaignList(const Request&);
  Response VoidReline(const Request&);
  Response PostSettingCheck(const Request&);
  Response SettingCheckList(const Request&);
  Response AlarmList(const Request&);
  Response AckAlarm(const Request&);
  Response AlarmRules(const Request&);
  Response SetAlarmRules(const Request&);
  /// The alarm engine, or nullptr with *error set to the 503 of a server that keeps none.
  AlarmEngine* AlarmsOf(Response* error) const;
  /// The name of the token that made `request` (the audit trail's "by"): "anonymous" on an open API.
  std::string TokenName(const Request& request) const;
  Response Plan(const Request&);
  Response Events(const Request&);
  Response RejectedList(const Request&);
  Response WhoAmI(const Request&);
  Response OpenApi(const Request&);
  Response Metrics(const Request&);

  /// The crusher named by the first path parameter, or nullptr with *error set to the 404.
  const Crusher* CrusherOf(const Request& request, Response* error) const;

  ApiContext ctx_;
  std::atomic<bool> stopping_{false};
  /// Each event stream holds one worker thread for its lifetime: at most half the workers, so
  /// ordinary requests always find a thread, and HttpLimits::max_event_streams_per_client from
  /// one address, so that one address cannot hold every slot.
  int max_event_streams_;
  std::mutex streams_mutex_;  ///< guards the two counts below
  int event_streams_ = 0;
  std::map<std::string, int> streams_per_client_;
  std::mutex post_mutex_;  ///< one readings body parsed at a time (a parsed body is ~20x its bytes)
  /// A crusher's entry in the crusher list as JSON text, with what it was made from: the list
  /// rebuilds an entry only when its crusher (a new object at each Registry::Replace), its wear
  /// state or its latest reading time changed. The state is held so that its address is not reused.
  struct ListEntry {
    const Crusher* crusher = nullptr;
    std::shared_ptr<const CrusherState> state;
    bool loaded = false;
    std::optional<int64_t> latest;
    std::string text;
  };
  std::mutex list_mutex_;  ///< guards list_entries_
  std::map<std::string, ListEntry> list_entries_;
  /// The list entry's JSON (an object of the crusher list), as Crushers() sends it.
  static nlohmann::ordered_json ListEntryJson(const Crusher& c, const CrusherState* st, bool loaded,
                                              std::optional<int64_t> latest);
};

}  // namespace lw::server::rest
