#include "server/openapi.hpp"

#include <nlohmann/json.hpp>
#include <string>

#include "server/rest.hpp"

namespace lw::server {
namespace {

using nlohmann::ordered_json;

/// One operation: its summary, parameters (the path's, then the documented query ones), the
/// success and error responses, and the token scope it needs (x-scope).
ordered_json Operation(const rest::Route& route) {
  ordered_json params = ordered_json::array();
  for (const std::string& name : rest::PathParams(route.path)) {
    params.push_back({{"name", name}, {"in", "path"}, {"required", true}, {"schema", {{"type", "string"}}}});
  }
  for (const rest::QueryDoc& q : route.query) {
    params.push_back(
        {{"name", q.name}, {"in", "query"}, {"required", false}, {"description", q.description}, {"schema", {{"type", q.type}}}});
  }
  const ordered_json object =
      route.response_schema ? ordered_json::parse(route.response_schema) : ordered_json{{"type", "object"}};
  ordered_json content = ordered_json::object();
  for (const char* type : route.content_types) {
    const std::string t = type;
    content[t] = {{"schema", t == "application/json" ? object : ordered_json{{"type", "string"}}}};
  }
  ordered_json op = {{"summary", route.summary}, {"parameters", params}};
  if (route.request_schema) {
    op["requestBody"] = {{"required", true},
                         {"content", {{"application/json", {{"schema", ordered_json::parse(route.request_schema)}}}}}};
  }
  ordered_json tail = {{"responses",
                        {{route.ok_status, {{"description", "OK"}, {"content", content}}},
                         {"400", {{"$ref", "#/components/responses/Error"}}},
                         {"401", {{"$ref", "#/components/responses/Error"}}},
                         {"403", {{"$ref", "#/components/responses/Error"}}},
                         {"404", {{"$ref", "#/components/responses/Error"}}}}},
                       {"x-scope", rest::ScopeName(rest::RequiredScope(rest::MethodName(route.method), route.path))}};
  if (route.request_schema) {
    // A body the route checks: 422 for a value that does not fit, 409 for a retry that differs;
    // a retry of a stored one answers 200 with what it made.
    if (std::string(route.ok_status) == "201")
      tail["responses"]["200"] = {{"description", "Already stored"}, {"content", content}};
    tail["responses"]["409"] = {{"$ref", "#/components/responses/Error"}};
    tail["responses"]["422"] = {{"$ref", "#/components/responses/Error"}};
  }
  for (auto& [key, value] : tail.items()) op[key] = value;
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
  const ordered_json doc = {
      {"openapi", "3.0.3"},
      {"info",
       {{"title", "linerwatch-server"},
        {"version", "0.1.0"},
        {"description",
         "Live crusher liner wear. A reading n means thickness in [n, n+1) mm. x-scope names the token scope "
         "each operation needs when the server runs with --tokens."}}},
      {"paths", paths},
      {"components",
       {{"securitySchemes", {{"bearer", {{"type", "http"}, {"scheme", "bearer"}}}}},
        {"responses",
         {{"Error",
           {{"description", "Error"},
            {"content",
             {{"application/json", {{"schema", {{"type", "object"}, {"properties", {{"error", {{"type", "string"}}}}}}}}}}}}}}}}},
      {"security", ordered_json::array({{{"bearer", ordered_json::array()}}})}};
  return doc.dump(1);
}

}  // namespace lw::server
