#include "server/openapi.hpp"

#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "rest_schemas.hpp"
#include "server/rest.hpp"

namespace lw::server {
namespace {

using nlohmann::ordered_json;

const char* const kErrorRef = "#/components/schemas/Error";

/// The statuses the HTTP layer answers on any operation before (or instead of) its handler:
/// http_guard.cpp refuses a request head or body, http_api.cpp a Host, and an exception is a 500.
const std::vector<rest::StatusDoc>& HttpLayerStatuses() {
  static const std::vector<rest::StatusDoc> statuses = {
      {"400", "malformed HTTP request (request line, header fields or body framing)"},
      {"408", "the request head or body did not arrive in time"},
      {"413", "a request body (Content-Length) larger than the operation accepts"},
      {"414", "request line too long"},
      {"415", "a compressed request body (Content-Encoding)"},
      {"421", "a Host this server does not answer to (--allowed-hosts)"},
      {"431", "request head too large: too many or too long header fields"},
      {"500", "internal error"},
      {"501", "a Transfer-Encoding other than chunked"},
      {"503", "server busy: too many connections (or too many from this address); retry later"},
  };
  return statuses;
}

/// A response body's schema per media type: JSON by the route's schema, the others as text.
ordered_json MediaSchema(const std::string& type, const rest::Route& route) {
  if (type == "application/json")
    return route.response_schema ? ordered_json::parse(route.response_schema) : ordered_json{{"type", "object"}};
  if (type == "text/event-stream") return ordered_json::parse(rest::schemas::kEventStream);
  if (type == "text/csv") return {{"type", "string"}, {"description", "RFC 4180 CSV, a header record first (?format=csv)"}};
  if (type == "application/octet-stream")
    return {{"type", "string"}, {"format", "binary"}, {"description", "a legacy VTK file for ParaView (?format=vtk)"}};
  if (type == "text/plain") return {{"type", "string"}, {"description", "Prometheus text exposition format 0.0.4"}};
  return {{"type", "string"}};
}

/// Every status an operation answers besides its success, each with why (the reasons of all that
/// answer it, joined) and its body's schemas (the error body unless a handler says otherwise).
struct Answer {
  std::string description;
  std::vector<std::string> schemas;  ///< JSON schema texts; several: any of them
};

std::map<std::string, Answer> OtherStatuses(const rest::Route& route) {
  std::map<std::string, Answer> out;
  const auto add = [&out](const std::string& status, const std::string& why, const char* schema) {
    Answer& a = out[status];
    a.description += (a.description.empty() ? "" : "; ") + why;
    const std::string text = schema ? schema : std::string(R"({"$ref":")") + kErrorRef + "\"}";
    bool known = false;
    for (const std::string& s : a.schemas) known = known || s == text;
    if (!known) a.schemas.push_back(text);
  };
  const std::string method = rest::MethodName(route.method);
  const rest::Scope scope = rest::RequiredScope(method, route.path);
  if (scope != rest::Scope::kNone) {
    add("401", "missing or unknown bearer token (a server run with --tokens; WWW-Authenticate: Bearer)", nullptr);
    add("403", std::string("the token lacks the ") + rest::ScopeName(scope) + " scope", nullptr);
  }
  if (rest::Writes(method)) {
    add("403", "a cross-origin request (its Origin is not this server)", nullptr);
    add("411", "no Content-Length and not chunked", nullptr);
    add("415", "Content-Type is not application/json", nullptr);
  }
  if (std::string(route.path).find("{crusher}") != std::string::npos) add("404", "unknown crusher", nullptr);
  for (const rest::StatusDoc& s : route.statuses) add(s.status, s.description, s.schema);
  for (const rest::StatusDoc& s : HttpLayerStatuses()) add(s.status, s.description, s.schema);
  return out;
}

/// One operation: its summary, parameters (the path's, then the documented query ones), every
/// response it can get, and the token scope it needs (x-scope).
ordered_json Operation(const rest::Route& route) {
  ordered_json params = ordered_json::array();
  for (const std::string& name : rest::PathParams(route.path)) {
    params.push_back({{"name", name}, {"in", "path"}, {"required", true}, {"schema", {{"type", "string"}}}});
  }
  for (const rest::QueryDoc& q : route.query) {
    ordered_json schema = {{"type", q.type}};
    if (!q.values.empty()) schema["enum"] = q.values;
    params.push_back(
        {{"name", q.name}, {"in", "query"}, {"required", false}, {"description", q.description}, {"schema", schema}});
  }
  ordered_json content = ordered_json::object();
  for (const char* type : route.content_types) content[type] = {{"schema", MediaSchema(type, route)}};
  ordered_json op = {{"summary", route.summary}, {"parameters", params}};
  if (route.request_schema) {
    op["requestBody"] = {{"required", true},
                         {"content", {{"application/json", {{"schema", ordered_json::parse(route.request_schema)}}}}}};
  }
  std::map<std::string, ordered_json> responses = {{route.ok_status, {{"description", "OK"}, {"content", content}}}};
  for (const auto& [status, answer] : OtherStatuses(route)) {
    ordered_json schema = ordered_json::parse(answer.schemas.front());
    if (answer.schemas.size() > 1) {
      schema = {{"anyOf", ordered_json::array()}};
      for (const std::string& s : answer.schemas) schema["anyOf"].push_back(ordered_json::parse(s));
    }
    responses[status] = {{"description", answer.description}, {"content", {{"application/json", {{"schema", schema}}}}}};
  }
  op["responses"] = ordered_json::object();
  for (auto& [status, response] : responses) op["responses"][status] = std::move(response);  // in status order
  op["x-scope"] = rest::ScopeName(rest::RequiredScope(rest::MethodName(route.method), route.path));
  return op;
}

}  // namespace

std::string OpenApiJson() {
  ordered_json paths;
  for (const rest::Route& route : rest::Resources::Routes()) {
    std::string method = rest::MethodName(route.method);
    for (char& ch : method) ch = static_cast<char>(ch - 'A' + 'a');  // OpenAPI's "get", "post"
    paths[route.path][method] = Operation(route);
  }
  ordered_json schemas = ordered_json::object();
  for (const auto& [name, text] : rest::schemas::SharedSchemas()) schemas[name] = ordered_json::parse(text);
  const ordered_json doc = {
      {"openapi", "3.0.3"},
      {"info",
       {{"title", "linerwatch-server"},
        {"version", "0.1.0"},
        {"description",
         "Live crusher liner wear. A reading n means thickness in [n, n+1) mm. x-scope names the token scope "
         "each operation needs when the server runs with --tokens. Every error is {\"error\": message} "
         "(components/schemas/Error); a method no operation of a path has is answered 405 with an Allow header, "
         "a path no operation has 404, HEAD as GET."}}},
      {"paths", paths},
      {"components", {{"securitySchemes", {{"bearer", {{"type", "http"}, {"scheme", "bearer"}}}}}, {"schemas", schemas}}},
      {"security", ordered_json::array({{{"bearer", ordered_json::array()}}})}};
  return doc.dump(1);
}

}  // namespace lw::server
