#include "server/http_api.hpp"

#include "http_guard.hpp"  // cpp-httplib behind the connection guard

#include <arpa/inet.h>
#include <cmath>
#include <stdlib.h>
#include <strings.h>
#include <unistd.h>

#include <algorithm>

#include <atomic>
#include <cstring>
#include <fstream>
#include <sstream>
#include <thread>

#include "core/time.hpp"
#include "server/openapi.hpp"
#include "server/query.hpp"

namespace lw::server {
namespace {

using nlohmann::ordered_json;

/// Never throws: text that is not valid UTF-8 (a request path, a stored payload) is replaced, not
/// allowed to abort the worker thread.
void Reply(httplib::Response& res, int status, const ordered_json& body) {
  res.status = status;
  res.set_content(body.dump(-1, ' ', false, ordered_json::error_handler_t::replace), "application/json");
}

void Error(httplib::Response& res, int status, const std::string& message) { Reply(res, status, {{"error", message}}); }

std::string Iso(int64_t unix_s) { return core::FormatIsoTime(core::TimePoint(std::chrono::seconds(unix_s))); }

ordered_json ReadingJson(const StoredReading& r) {
  return {{"sensor", r.sensor},
          {"time", Iso(r.time_s)},
          {"seq", r.seq},
          {"thickness_mm", r.thickness_mm},
          {"loops_intact", r.loops_intact},
          {"flags", r.flags},
          {"battery_mv", r.battery_mv},
          {"received", Iso(r.received_s)}};
}

/// The event stream path: the only one that takes ?access_token= (EventSource cannot send headers).
bool IsEventStream(const std::string& path) {
  return path.rfind("/api/v1/crushers/", 0) == 0 && path.size() > 7 && path.compare(path.size() - 7, 7, "/events") == 0;
}

std::string BearerOf(const httplib::Request& req) {
  const std::string h = req.get_header_value("Authorization");
  if (h.rfind("Bearer ", 0) == 0) return h.substr(7);
  if (req.method == "GET" && IsEventStream(req.path) && req.has_param("access_token")) return req.get_param_value("access_token");
  return {};
}

/// "http://host:port" -> "host:port"; empty when `origin` is not http(s)://.
std::string OriginHost(const std::string& origin) {
  for (const char* scheme : {"http://", "https://"}) {
    if (origin.rfind(scheme, 0) == 0) return origin.substr(std::strlen(scheme));
  }
  return {};
}

}  // namespace

bool HostAllowed(const std::string& host_header, const std::vector<std::string>& allowed) {
  std::string host = host_header;
  if (!host.empty() && host[0] == '[') {  // [v6]:port
    const size_t close = host.find(']');
    if (close == std::string::npos) return false;
    host = host.substr(1, close - 1);
    in6_addr a6{};
    return ::inet_pton(AF_INET6, host.c_str(), &a6) == 1;
  }
  const size_t colon = host.rfind(':');
  if (colon != std::string::npos) host = host.substr(0, colon);
  if (host.empty()) return false;
  in_addr a4{};
  if (::inet_pton(AF_INET, host.c_str(), &a4) == 1) return true;  // an address cannot be rebound
  if (strcasecmp(host.c_str(), "localhost") == 0) return true;
  for (const auto& name : allowed) {
    if (strcasecmp(host.c_str(), name.c_str()) == 0) return true;
  }
  return false;
}

struct HttpApi::Impl {
  ApiContext ctx;
  std::unique_ptr<GuardedServer> server;
  GuardedServer& svr_ref() { return *server; }
  std::thread thread;
  std::atomic<bool> stopping{false};
  std::atomic<int> sse_clients{0};
  /// Each event stream holds one worker thread for its lifetime: at most half the workers, so
  /// ordinary requests always find a thread.
  int max_event_streams = 16;
  std::mutex post_mutex;  ///< one readings body parsed at a time (a parsed body is ~20x its bytes)

  const Crusher* CrusherOr404(const httplib::Request& req, httplib::Response& res) {
    const std::string id = req.matches[1];
    const Crusher* c = ctx.registry->Find(id);
    if (!c) Error(res, 404, "unknown crusher '" + id + "'");
    return c;
  }

  void Routes();
};

HttpApi::HttpApi(ApiContext context) : impl_(std::make_unique<Impl>()) {
  impl_->ctx = std::move(context);
  impl_->server = std::make_unique<GuardedServer>(impl_->ctx.limits);
  impl_->max_event_streams = static_cast<int>(std::max<size_t>(1, impl_->ctx.limits.workers / 2));
  impl_->Routes();
}

HttpApi::~HttpApi() { Stop(); }

int HttpApi::Bind(const std::string& host, int port) {
  int bound = port;
  if (port == 0) {
    bound = impl_->server->bind_to_any_port(host);
    if (bound <= 0) throw std::runtime_error("--http " + host + ":0: cannot bind");
  } else if (!impl_->server->bind_to_port(host, port)) {
    throw std::runtime_error("--http " + host + ":" + std::to_string(port) + ": cannot bind (in use or not a local address)");
  }
  return bound;
}

void HttpApi::Start() {
  impl_->thread = std::thread([this] { impl_->server->Serve(); });
}

void HttpApi::Stop() {
  if (!impl_ || impl_->stopping.exchange(true)) return;
  if (impl_->ctx.events) impl_->ctx.events->Close();
  impl_->server->Shutdown();
  if (impl_->thread.joinable()) impl_->thread.join();
}

void HttpApi::Impl::Routes() {
  GuardedServer& svr = svr_ref();
  svr.set_payload_max_length(static_cast<size_t>(ctx.limits.max_body_bytes));
  svr.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
    std::string what = "internal error";
    try {
      if (ep) std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      what = std::string("internal error: ") + e.what();
    } catch (...) {
    }
    Error(res, 500, what);
  });
  svr.set_error_handler([this](const httplib::Request& req, httplib::Response& res) {  // runs outside httplib's try
    if (!res.body.empty()) return;
    std::string what = "request failed";
    if (res.status == 404) what = "no such resource: " + req.path;
    else if (res.status == 413) what = "request body larger than " + std::to_string(ctx.limits.max_body_bytes) + " bytes";
    else if (res.status == 400) what = "malformed HTTP request";
    Error(res, res.status, what);
  });

  // Before routing: the Host must be ours (DNS rebinding); a state-changing request must come from
  // our own origin with a JSON body (cross-site forms and text/plain posts: CSRF); then bearer
  // tokens on /api: read scope for GET, write scope for everything else.
  svr.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    const std::string host = req.get_header_value("Host");
    if (req.has_header("Host") && !HostAllowed(host, ctx.allowed_hosts)) {
      Error(res, 421, "Host '" + host + "' is not one this server answers to (see --allowed-hosts)");
      return httplib::Server::HandlerResponse::Handled;
    }
    const bool write = req.method != "GET" && req.method != "HEAD";
    if (write) {
      const std::string origin = req.get_header_value("Origin");
      if (req.has_header("Origin") && strcasecmp(OriginHost(origin).c_str(), host.c_str()) != 0) {
        Error(res, 403, "cross-origin request from '" + origin + "' refused");
        return httplib::Server::HandlerResponse::Handled;
      }
      const std::string type = req.get_header_value("Content-Type");
      if (type.rfind("application/json", 0) != 0) {
        Error(res, 415, "a " + req.method + " needs Content-Type: application/json");
        return httplib::Server::HandlerResponse::Handled;
      }
    }
    if (!ctx.tokens || !ctx.tokens->enabled() || req.path.rfind("/api/", 0) != 0) return httplib::Server::HandlerResponse::Unhandled;
    const auto token = ctx.tokens->Check(BearerOf(req));
    if (!token) {
      res.set_header("WWW-Authenticate", "Bearer");
      Error(res, 401, "missing or unknown bearer token");
      return httplib::Server::HandlerResponse::Handled;
    }
    if ((write && !token->write) || (!write && !token->read)) {
      Error(res, 403, std::string("token '") + token->name + "' lacks the " + (write ? "write" : "read") + " scope");
      return httplib::Server::HandlerResponse::Handled;
    }
    return httplib::Server::HandlerResponse::Unhandled;
  });

  // The dashboard: index.html at / and its bundle under /assets, nothing else from the folder
  // (in a build tree it also holds CMake's files).
  if (!ctx.web_dir.empty() && std::filesystem::exists(ctx.web_dir / "index.html")) {
    if (std::filesystem::is_directory(ctx.web_dir / "assets")) svr.set_mount_point("/assets", (ctx.web_dir / "assets").string());
    const std::filesystem::path index = ctx.web_dir / "index.html";
    svr.Get("/", [index](const httplib::Request&, httplib::Response& res) {
      std::ifstream in(index, std::ios::binary);
      std::stringstream ss;
      ss << in.rdbuf();
      if (!in) return Error(res, 503, "dashboard file " + index.string() + " is not readable");
      res.set_header("Cache-Control", "no-cache");
      res.set_content(ss.str(), "text/html; charset=utf-8");
    });
  } else {
    svr.Get("/", [](const httplib::Request&, httplib::Response& res) {
      res.set_content(
          "<!doctype html><title>linerwatch</title><p>linerwatch-server: the dashboard is not built "
          "(see docs/dashboard.md). API: <a href=\"/api/v1/openapi.json\">/api/v1/openapi.json</a></p>",
          "text/html");
    });
  }

  // What the caller's token may do (the dashboard hides write actions for read-only tokens).
  svr.Get("/api/v1/whoami", [this](const httplib::Request& req, httplib::Response& res) {
    if (!ctx.tokens || !ctx.tokens->enabled()) {
      return Reply(res, 200, {{"auth", false}, {"name", nullptr}, {"scopes", {"read", "write"}}});
    }
    const auto token = ctx.tokens->Check(BearerOf(req));  // the pre-routing check let it through
    ordered_json scopes = ordered_json::array();
    if (token && token->read) scopes.push_back("read");
    if (token && token->write) scopes.push_back("write");
    Reply(res, 200, {{"auth", true}, {"name", token ? token->name : ""}, {"scopes", scopes}});
  });

  svr.Get("/healthz", [this](const httplib::Request&, httplib::Response& res) {
    ordered_json j = {{"status", "ok"}, {"version", "0.1.0"}};
    try {
      std::lock_guard<std::mutex> lock(*ctx.read_mutex);
      ctx.read->CountRejected();
      j["db"] = "ok";
    } catch (const std::exception& e) {
      j["status"] = "degraded";
      j["db"] = e.what();
    }
    if (ctx.health) {
      const ordered_json extra = ctx.health();
      for (const auto& [k, v] : extra.items()) j[k] = v;
    }
    Reply(res, j["status"] == "ok" ? 200 : 503, j);
  });

  svr.Get("/api/v1/openapi.json", [](const httplib::Request&, httplib::Response& res) {
    res.set_content(OpenApiJson(), "application/json");
  });

  svr.Get("/api/v1/crushers", [this](const httplib::Request&, httplib::Response& res) {
    ordered_json list = ordered_json::array();
    for (const Crusher* c : ctx.registry->All()) {
      // Never waits behind a wear recompute: the wear as last computed (the wear worker recomputes a
      // changed crusher within --wear-interval-ms); the latest reading time is always current.
      const auto st = ctx.wear->Latest(c->config.crusher_id);
      const auto latest = ctx.live->LatestUsableTime(c->config.crusher_id);
      ordered_json rows = ordered_json::array();
      for (const auto& r : c->config.rows) rows.push_back({{"name", r.name}, {"z_min_m", r.z_min_m}, {"z_max_m", r.z_max_m}});
      list.push_back({{"crusher_id", c->config.crusher_id},
                      {"installed_at", core::FormatIsoTime(c->config.installed_at)},
                      {"thickness_new_mm", c->config.thickness_new_mm},
                      {"thickness_min_mm", c->config.thickness_min_mm},
                      {"rows", rows},
                      {"sensor_count", c->config.sensors.size()},
                      {"map_sha256", c->map.sha256},
                      {"face_count", c->map.face_count()},
                      {"latest_reading_time", latest ? ordered_json(Iso(*latest)) : ordered_json(nullptr)},
                      {"min_thickness_mm", st && st->has_wear && std::isfinite(st->reconstruction.min_thickness_mm)
                                               ? ordered_json(st->reconstruction.min_thickness_mm) : ordered_json(nullptr)},
                      {"wear_status", st && st->has_wear ? ordered_json(st->reconstruction.status) : ordered_json(nullptr)}});
    }
    Reply(res, 200, {{"crushers", list}});
  });

  svr.Get(R"(/api/v1/crushers/([^/]+))", [this](const httplib::Request& req, httplib::Response& res) {
    const Crusher* c = CrusherOr404(req, res);
    if (!c) return;
    ordered_json rows = ordered_json::array();
    for (const auto& r : c->config.rows) rows.push_back({{"name", r.name}, {"z_min_m", r.z_min_m}, {"z_max_m", r.z_max_m}});
    ordered_json sensors = ordered_json::array();
    for (const auto& s : c->config.sensors) {
      sensors.push_back({{"id", s.id}, {"row", s.row}, {"z_m", s.z_m}, {"theta_deg", s.theta_deg}, {"thickness_new_mm", s.thickness_new_mm}});
    }
    const int64_t stored = ctx.live->CountReadings(c->config.crusher_id);
    const IngestCounters cc = ctx.ingestor->CrusherCounters(c->config.crusher_id);
    Reply(res, 200,
          {{"crusher_id", c->config.crusher_id},
           {"installed_at", core::FormatIsoTime(c->config.installed_at)},
           {"concave", {{"thickness_new_mm", c->config.thickness_new_mm}, {"thickness_min_mm", c->config.thickness_min_mm}, {"rows", rows}}},
           {"sensors", sensors},
           {"map", {{"sha256", c->map.sha256},
                    {"face_count", c->map.face_count()},
                    {"warnings", c->validation.warnings},
                    {"has_stderr", c->map.has_wear_stderr()}, {"windows", c->map.windows},
                    {"dem_summary", c->dem_summary}}},
           {"counters", {{"readings_stored", stored}, {"duplicates", cc.duplicates}, {"conflicts", cc.conflicts}, {"rejected", cc.rejected}}}});
  });

  svr.Get(R"(/api/v1/crushers/([^/]+)/sensors)", [this](const httplib::Request& req, httplib::Response& res) {
    const Crusher* c = CrusherOr404(req, res);
    if (!c) return;
    const std::vector<Store::SensorSummary> latest = ctx.live->LatestPerSensor(c->config.crusher_id);
    ordered_json sensors = ordered_json::array();
    for (const auto& s : c->config.sensors) {
      ordered_json o = {{"id", s.id}, {"row", s.row}, {"z_m", s.z_m}, {"theta_deg", s.theta_deg},
                        {"thickness_new_mm", s.thickness_new_mm}, {"reading_count", 0}, {"latest", nullptr}};
      for (const auto& l : latest) {
        if (l.latest.sensor != s.id) continue;
        o["reading_count"] = l.count;
        ordered_json r = ReadingJson(l.latest);
        r.erase("sensor");
        o["latest"] = r;
      }
      sensors.push_back(o);
    }
    Reply(res, 200, {{"sensors", sensors}});
  });

  svr.Get(R"(/api/v1/crushers/([^/]+)/sensors/([^/]+)/readings)", [this](const httplib::Request& req, httplib::Response& res) {
    const Crusher* c = CrusherOr404(req, res);
    if (!c) return;
    const std::string sensor = req.matches[2];
    if (!c->config.FindSensor(sensor)) return Error(res, 404, "unknown sensor '" + sensor + "' on crusher " + c->config.crusher_id);
    std::string error;
    const auto query = ParseReadingsQuery(req.params, &error);
    if (!query) return Error(res, 400, error);
    Page page;
    try {
      std::lock_guard<std::mutex> lock(*ctx.read_mutex);
      page = ctx.read->Range(c->config.crusher_id, sensor, query->from_s, query->to_s, query->limit, query->cursor);
    } catch (const std::invalid_argument& e) {
      return Error(res, 400, e.what());
    }
    ordered_json readings = ordered_json::array();
    for (const auto& r : page.readings) {
      ordered_json o = ReadingJson(r);
      o.erase("sensor");
      readings.push_back(o);
    }
    Reply(res, 200, {{"readings", readings}, {"next_cursor", page.next_cursor ? ordered_json(*page.next_cursor) : ordered_json(nullptr)}});
  });

  svr.Post(R"(/api/v1/crushers/([^/]+)/readings)", [this](const httplib::Request& req, httplib::Response& res) {
    const Crusher* c = CrusherOr404(req, res);
    if (!c) return;
    if (JsonNestingDepth(req.body) > kMaxJsonDepth + 2) return Error(res, 400, "body is nested too deeply");
    std::lock_guard<std::mutex> one_at_a_time(post_mutex);
    nlohmann::json body;
    std::string parse_error;
    if (!ParseJsonNamingField(req.body, &body, &parse_error)) {
      return Error(res, 400, parse_error == "malformed JSON" ? "body is not valid JSON" : "body: " + parse_error);
    }
    if (!body.is_object() || !body.contains("readings") || !body["readings"].is_array()) {
      return Error(res, 400, "body must be {\"readings\": [...]}");
    }
    if (body["readings"].size() > 10000) return Error(res, 413, "at most 10000 readings per request");
    std::vector<Incoming> batch;
    for (const auto& r : body["readings"]) {
      batch.push_back({"", c->config.crusher_id, "", "", r.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace)});
    }
    IngestResult result;
    try {
      result = ctx.ingestor->Ingest(batch);
    } catch (const std::exception& e) {
      return Error(res, 503, std::string("not stored: ") + e.what());
    }
    if (ctx.after_ingest) ctx.after_ingest(result);
    ordered_json j = {{"stored", result.stored}, {"duplicates", result.duplicates}, {"conflicts", result.conflicts},
                      {"rejected", result.rejected}, {"errors", result.log}};
    if (result.rejected > 0 && result.rejected == batch.size()) j["error"] = "every reading was rejected";
    Reply(res, result.rejected > 0 && result.rejected == batch.size() ? 422 : 200, j);
  });

  svr.Get(R"(/api/v1/crushers/([^/]+)/mesh)", [this](const httplib::Request& req, httplib::Response& res) {
    const Crusher* c = CrusherOr404(req, res);
    if (!c) return;
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
    Reply(res, 200, {{"points", pts}, {"faces", faces}, {"face_z_m", z}, {"face_theta_deg", th}});
  });

  svr.Get(R"(/api/v1/crushers/([^/]+)/wear)", [this](const httplib::Request& req, httplib::Response& res) {
    const Crusher* c = CrusherOr404(req, res);
    if (!c) return;
    const auto st = ctx.wear->Get(c->config.crusher_id);
    if (!st || !st->has_wear) return Error(res, 404, "no readings yet for crusher " + c->config.crusher_id);
    const std::string format = req.has_param("format") ? req.get_param_value("format") : "json";
    if (format == "vtk") {
      // A private directory (mkdtemp, mode 0700): nobody else can race a file name in it.
      char tmpl[] = "/tmp/linerwatch-wear-XXXXXX";
      if (!mkdtemp(tmpl)) return Error(res, 500, "cannot create a temporary directory");
      const std::filesystem::path tmp_dir = tmpl;
      const std::filesystem::path path = tmp_dir / "wear.vtk";
      std::stringstream ss;
      try {
        const Eigen::VectorXd& wear = st->reconstruction.wear_mm;
        const Eigen::VectorXd& remaining = st->reconstruction.remaining_mm;
        const Eigen::VectorXd& sd = st->reconstruction.remaining_sd_mm;
        core::WriteWearMapVtk(path, c->map, {{"remaining_mm", &remaining}, {"remaining_sd_mm", &sd}, {"wear_mm", &wear},
                                             {"dem_wear", &c->map.wear}, {"dem_intensity_smoothed", &c->plan.intensity}});
        std::ifstream in(path, std::ios::binary);
        ss << in.rdbuf();
      } catch (...) {
        std::error_code ec;
        std::filesystem::remove_all(tmp_dir, ec);
        throw;
      }
      std::error_code ec;
      std::filesystem::remove_all(tmp_dir, ec);
      res.set_header("Content-Disposition", "attachment; filename=\"" + c->config.crusher_id + "_wear.vtk\"");
      res.set_content(ss.str(), "application/octet-stream");
      return;
    }
    if (format != "json") return Error(res, 400, "format='" + format + "': use json or vtk");
    const bool faces = !(req.has_param("faces") && req.get_param_value("faces") == "false");
    Reply(res, 200, WearJson(*st, faces));
  });

  svr.Get(R"(/api/v1/crushers/([^/]+)/forecast)", [this](const httplib::Request& req, httplib::Response& res) {
    const Crusher* c = CrusherOr404(req, res);
    if (!c) return;
    const auto st = ctx.wear->Get(c->config.crusher_id);
    if (!st || !st->has_wear) return Error(res, 404, "no readings yet for crusher " + c->config.crusher_id);
    Reply(res, 200, ForecastJson(*st));
  });

  svr.Get(R"(/api/v1/crushers/([^/]+)/diagnosis)", [this](const httplib::Request& req, httplib::Response& res) {
    const Crusher* c = CrusherOr404(req, res);
    if (!c) return;
    if (!ctx.diagnosis) return Error(res, 503, "diagnosis is not available on this server");
    res.set_content(ctx.diagnosis->StatusJson(c->config.crusher_id), "application/json");
  });

  svr.Post(R"(/api/v1/crushers/([^/]+)/diagnosis)", [this](const httplib::Request& req, httplib::Response& res) {
    const Crusher* c = CrusherOr404(req, res);
    if (!c) return;
    if (!ctx.diagnosis) return Error(res, 503, "diagnosis is not available on this server");
    const bool started = ctx.diagnosis->Start(c->config.crusher_id);
    Reply(res, started ? 202 : 409, started ? ordered_json{{"status", "running"}} : ordered_json{{"error", "a diagnosis is already running"}});
  });

  svr.Get("/api/v1/rejected", [this](const httplib::Request& req, httplib::Response& res) {
    int limit = 100;
    std::string error;
    if (!WholeNumberParam(req.params, "limit", 1, 1000, &limit, &error)) return Error(res, 400, error);
    ordered_json list = ordered_json::array();
    std::lock_guard<std::mutex> lock(*ctx.read_mutex);
    for (const auto& r : ctx.read->RejectedMessages(limit)) {
      list.push_back({{"received", Iso(r.received_s)}, {"topic", r.topic}, {"payload", r.payload}, {"reason", r.reason}});
    }
    Reply(res, 200, {{"total", ctx.read->CountRejected()}, {"evicted", ctx.read->RejectedEvicted()}, {"rejected", list}});
  });

  svr.Get(R"(/api/v1/crushers/([^/]+)/events)", [this](const httplib::Request& req, httplib::Response& res) {
    const Crusher* c = CrusherOr404(req, res);
    if (!c) return;
    if (sse_clients.load() >= max_event_streams) {
      return Error(res, 503, "too many open event streams (" + std::to_string(max_event_streams) + "); retry later");
    }
    int64_t after = ctx.events->LastId();
    const std::string last = req.get_header_value("Last-Event-ID");
    // A client reconnecting after a server restart carries an id from the previous run: ids start
    // again at 1, so a larger one means "from now on", not "wait until the counter gets there".
    if (!last.empty()) after = std::min(after, std::max<int64_t>(0, std::atoll(last.c_str())));
    const std::string crusher = c->config.crusher_id;
    res.set_header("Cache-Control", "no-cache");
    res.set_header("X-Accel-Buffering", "no");
    auto first = std::make_shared<bool>(true);
    // Counts this stream while its provider exists (httplib destroys it when the stream ends).
    auto slot = std::shared_ptr<void>(nullptr, [this](void*) { --sse_clients; });
    ++sse_clients;
    res.set_chunked_content_provider("text/event-stream", [this, crusher, after, first, slot](size_t, httplib::DataSink& sink) mutable {
      if (stopping || ctx.events->closed()) return false;
      std::string out;
      if (*first) {
        *first = false;
        out = "retry: 3000\n: connected\n\n";
        return sink.write(out.data(), out.size());
      }
      // Wait up to 15 s for events (then a keepalive), but look every second whether the client
      // is still there: a closed stream frees its slot and its worker at once.
      std::vector<Event> events;
      for (int waited = 0; waited < 15 && events.empty(); ++waited) {
        events = ctx.events->WaitAfter(&after, crusher, std::chrono::milliseconds(1000));
        if (stopping || ctx.events->closed()) return false;
        if (events.empty() && sink.is_writable && !sink.is_writable()) return false;
      }
      if (events.empty()) out = ": keepalive\n\n";
      for (const Event& e : events) out += "id: " + std::to_string(e.id) + "\nevent: " + e.name + "\ndata: " + e.data + "\n\n";
      return sink.write(out.data(), out.size());
    });
  });
}

}  // namespace lw::server
