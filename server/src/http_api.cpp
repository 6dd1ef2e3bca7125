#include "server/http_api.hpp"

#include "http_guard.hpp"  // cpp-httplib behind the connection guard

#include <arpa/inet.h>
#include <strings.h>

#include <atomic>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>
#include <thread>

#include "server/rest.hpp"

namespace lw::server {
namespace {

using nlohmann::ordered_json;

/// Never throws: text that is not valid UTF-8 (a request path, a stored payload) is replaced, not
/// allowed to abort the worker thread.
void Reply(httplib::Response& res, int status, const ordered_json& body) {
  res.status = status;
  res.set_content(body.dump(-1, ' ', false, ordered_json::error_handler_t::replace), "application/json");
}

void Error(httplib::Response& res, int status, const std::string& message) {
  Reply(res, status, {{"error", message}});
}

/// The event stream path: the only one that takes ?access_token= (EventSource cannot send headers).
bool IsEventStream(const std::string& path) {
  const rest::RouteMatch m = rest::MatchRoute("GET", path);
  return m.route && std::string_view(m.route->path) == "/api/v1/crushers/{crusher}/events";
}

std::string BearerOf(const httplib::Request& req) {
  // The whole value: get_header_value goes through a C string and would stop at a NUL.
  const auto it = req.headers.find("Authorization");
  const std::string h = it == req.headers.end() ? std::string() : it->second;
  if (h.rfind("Bearer ", 0) == 0) return h.substr(7);
  if (req.method == "GET" && IsEventStream(req.path) && req.has_param("access_token")) return req.get_param_value("access_token");
  return {};
}

/// The dashboard's paths (RouteDashboard): GET and HEAD only.
bool IsDashboardPath(const std::string& path) {
  return path == "/" || path.rfind("/assets/", 0) == 0;
}

/// The methods served on `path`, for a 405's Allow header.
std::string AllowedMethods(const std::string& path) {
  if (IsDashboardPath(path)) return "GET, HEAD";
  std::string allow;
  for (const char* method : {"GET", "POST"}) {
    if (rest::MatchRoute(method, path).route) allow += std::string(allow.empty() ? "" : ", ") + method;
  }
  return allow;
}

/// "http://host:port" -> "host:port"; empty when `origin` is not http(s)://.
std::string OriginHost(const std::string& origin) {
  for (const char* scheme : {"http://", "https://"}) {
    if (origin.rfind(scheme, 0) == 0) return origin.substr(std::strlen(scheme));
  }
  return {};
}

/// `args`: the path's parameter values (from rest::MatchRoute).
rest::Request ToRest(const httplib::Request& req, std::vector<std::string> args) {
  rest::Request r;
  r.path = std::move(args);
  r.query = req.params;
  r.body = req.body;
  r.bearer = BearerOf(req);
  r.last_event_id = req.get_header_value("Last-Event-ID");
  r.client = req.remote_addr;
  return r;
}

/// Sends a resource's response. A 200 with a body that is not JSON made here (raw or a stream)
/// leaves the status to httplib, as those routes always have: 200, or 206 for a Range request.
void Send(rest::Response&& r, httplib::Response& res) {
  for (const auto& [name, value] : r.headers) res.set_header(name, value);
  if (r.stream) {
    if (r.status != 200) res.status = r.status;
    res.set_chunked_content_provider("text/event-stream", [stream = std::move(r.stream)](size_t, httplib::DataSink& sink) {
      const auto chunk = stream->Next([&sink] { return sink.is_writable && !sink.is_writable(); });
      return chunk && sink.write(chunk->data(), chunk->size());
    });
  } else if (r.raw) {
    if (r.status != 200) res.status = r.status;
    res.body = std::move(r.raw->content);  // what set_content does, without copying the body
    res.headers.erase("Content-Type");
    res.set_header("Content-Type", r.raw->content_type);
  } else {
    Reply(res, r.status, r.json);
  }
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
  explicit Impl(ApiContext context) : ctx(std::move(context)), resources(ctx), server(ctx.limits) {}
  ApiContext ctx;
  rest::Resources resources;
  GuardedServer server;
  std::thread thread;
  std::atomic<bool> stopping{false};

  void Routes();
  /// Before routing, so before any body is read: the Host must be ours (DNS rebinding); the
  /// method and path must be a route's (404, 405); a bearer token on /api with the scope
  /// rest::RequiredScope names; a state-changing request must come from our own origin with a
  /// JSON body (cross-site forms and text/plain posts: CSRF).
  httplib::Server::HandlerResponse Admit(const httplib::Request& req, httplib::Response& res);
  /// The bearer token's check for the scope the request needs: the refusal (401, 403) or nullopt.
  std::optional<httplib::Server::HandlerResponse> Authorize(const httplib::Request& req, httplib::Response& res);
  /// index.html at / and its bundle under /assets, nothing else from the folder (in a build tree
  /// it also holds CMake's files); a page pointing at the API when there is no dashboard.
  void RouteDashboard();
};

HttpApi::HttpApi(ApiContext context) : impl_(std::make_unique<Impl>(std::move(context))) {
  impl_->Routes();
}

HttpApi::~HttpApi() {
  Stop();
}

int HttpApi::Bind(const std::string& host, int port) {
  int bound = port;
  if (port == 0) {
    bound = impl_->server.bind_to_any_port(host);
    if (bound <= 0) throw std::runtime_error("--http " + host + ":0: cannot bind");
  } else if (!impl_->server.bind_to_port(host, port)) {
    throw std::runtime_error("--http " + host + ":" + std::to_string(port) + ": cannot bind (in use or not a local address)");
  }
  return bound;
}

void HttpApi::Start() {
  impl_->thread = std::thread([this] { impl_->server.Serve(); });
}

void HttpApi::Stop() {
  if (!impl_ || impl_->stopping.exchange(true)) return;
  impl_->resources.Stop();
  if (impl_->ctx.events) impl_->ctx.events->Close();
  impl_->server.Shutdown();
  if (impl_->thread.joinable()) impl_->thread.join();
}

void HttpApi::Impl::Routes() {
  GuardedServer& svr = server;
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
    if (res.status == 404)
      what = "no such resource: " + req.path;
    else if (res.status == 413)
      what = "request body larger than " + std::to_string(ctx.limits.max_body_bytes) + " bytes";
    else if (res.status == 400)
      what = "malformed HTTP request";
    Error(res, res.status, what);
  });

  svr.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) { return Admit(req, res); });
  // Every request httplib answers (routed, refused before routing, or not found), once its status is final.
  if (ctx.metrics) {
    svr.set_logger([this](const httplib::Request& req, const httplib::Response& res) {
      ctx.metrics->CountHttp(req.method, req.path, res.status);
    });
  }
  // A path no route has gets its 404 (or 405) from Admit, before its body is read: the limit
  // there is only the general one.
  const uint64_t general = ctx.limits.max_body_bytes;
  svr.SetBodyLimit([general](std::string_view method, std::string_view path) {
    const rest::RouteMatch m = rest::MatchRoute(method, path);
    return m.route ? m.route->max_body_bytes : general;
  });
  RouteDashboard();

  // The API: every route of the one table (rest::Resources::Routes(), from which the OpenAPI
  // document is generated).
  for (const rest::Route& route : rest::Resources::Routes()) {
    // Reached for POST routes (their body is read after Admit); GET routes are answered by Admit.
    const auto handler = [this, &route](const httplib::Request& req, httplib::Response& res) {
      std::vector<std::string> args;
      for (size_t i = 1; i < req.matches.size(); ++i) args.push_back(req.matches[i]);
      Send(resources.Call(route, ToRest(req, std::move(args))), res);
    };
    const std::string pattern = rest::PathPattern(route.path);
    if (route.method == rest::Method::kGet)
      svr.Get(pattern, handler);
    else
      svr.Post(pattern, handler);
  }
}

httplib::Server::HandlerResponse HttpApi::Impl::Admit(const httplib::Request& req, httplib::Response& res) {
  const std::string host = req.get_header_value("Host");
  if (req.has_header("Host") && !HostAllowed(host, ctx.allowed_hosts)) {
    Error(res, 421, "Host '" + host + "' is not one this server answers to (see --allowed-hosts)");
    return httplib::Server::HandlerResponse::Handled;
  }
  // The route and its scope are known before any body is read: a request no route serves is
  // answered here, its body unread (the connection then closes).
  const bool dashboard = IsDashboardPath(req.path) && (req.method == "GET" || req.method == "HEAD");
  const rest::RouteMatch route = rest::MatchRoute(req.method, req.path);
  if (!route.route && !dashboard) {
    if (!route.path_known && !IsDashboardPath(req.path)) {
      Error(res, 404, "no such resource: " + req.path);
    } else {
      res.set_header("Allow", AllowedMethods(req.path));
      Error(res, 405, req.method + " is not allowed on " + req.path + " (" + AllowedMethods(req.path) + ")");
    }
    return httplib::Server::HandlerResponse::Handled;
  }
  if (const auto refused = Authorize(req, res)) return *refused;
  if (rest::Writes(req.method)) {
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
  // A GET route with no body to read is answered here, from the route already matched: httplib
  // would match the path again against every route's regular expression in turn (std::regex, for
  // each route before this one). A request with a body goes on to httplib, which reads it first.
  if (route.route && route.route->method == rest::Method::kGet && !req.has_header("Transfer-Encoding") &&
      req.get_header_value<uint64_t>("Content-Length") == 0) {
    Send(resources.Call(*route.route, ToRest(req, route.args)), res);
    return httplib::Server::HandlerResponse::Handled;
  }
  return httplib::Server::HandlerResponse::Unhandled;
}

std::optional<httplib::Server::HandlerResponse> HttpApi::Impl::Authorize(const httplib::Request& req, httplib::Response& res) {
  const rest::Scope scope = rest::RequiredScope(req.method, req.path);
  if (!ctx.tokens || !ctx.tokens->enabled() || scope == rest::Scope::kNone) return std::nullopt;
  const auto token = ctx.tokens->Check(BearerOf(req));
  if (!token) {
    res.set_header("WWW-Authenticate", "Bearer");
    Error(res, 401, "missing or unknown bearer token");
    return httplib::Server::HandlerResponse::Handled;
  }
  if ((scope == rest::Scope::kWrite && !token->write) || (scope == rest::Scope::kRead && !token->read)) {
    Error(res, 403, std::string("token '") + token->name + "' lacks the " + rest::ScopeName(scope) + " scope");
    return httplib::Server::HandlerResponse::Handled;
  }
  return std::nullopt;
}

void HttpApi::Impl::RouteDashboard() {
  if (!ctx.web_dir.empty() && std::filesystem::exists(ctx.web_dir / "index.html")) {
    if (std::filesystem::is_directory(ctx.web_dir / "assets"))
      server.set_mount_point("/assets", (ctx.web_dir / "assets").string());
    const std::filesystem::path index = ctx.web_dir / "index.html";
    server.Get("/", [index](const httplib::Request&, httplib::Response& res) {
      std::ifstream in(index, std::ios::binary);
      std::stringstream ss;
      ss << in.rdbuf();
      if (!in) return Error(res, 503, "dashboard file " + index.string() + " is not readable");
      res.set_header("Cache-Control", "no-cache");
      res.set_content(ss.str(), "text/html; charset=utf-8");
    });
  } else {
    server.Get("/", [](const httplib::Request&, httplib::Response& res) {
      res.set_content(
          "<!doctype html><title>linerwatch</title><p>linerwatch-server: the dashboard is not built "
          "(see docs/dashboard.md). API: <a href=\"/api/v1/openapi.json\">/api/v1/openapi.json</a></p>",
          "text/html");
    });
  }
}

}  // namespace lw::server
