#include "server/openapi.hpp"

#include <nlohmann/json.hpp>

namespace lw::server {
namespace {

using nlohmann::ordered_json;

ordered_json Op(const std::string& summary, const std::string& scope, ordered_json params = ordered_json::array(),
                const std::string& ok = "200") {
  ordered_json o = {{"summary", summary},
                    {"parameters", params},
                    {"responses",
                     {{ok, {{"description", "OK"}, {"content", {{"application/json", {{"schema", {{"type", "object"}}}}}}}}},
                      {"400", {{"$ref", "#/components/responses/Error"}}},
                      {"401", {{"$ref", "#/components/responses/Error"}}},
                      {"403", {{"$ref", "#/components/responses/Error"}}},
                      {"404", {{"$ref", "#/components/responses/Error"}}}}},
                    {"x-scope", scope}};
  return o;
}

ordered_json PathParam(const std::string& name) {
  return {{"name", name}, {"in", "path"}, {"required", true}, {"schema", {{"type", "string"}}}};
}
ordered_json QueryParam(const std::string& name, const std::string& type, const std::string& description) {
  return {{"name", name}, {"in", "query"}, {"required", false}, {"description", description}, {"schema", {{"type", type}}}};
}

}  // namespace

std::string OpenApiJson() {
  const ordered_json c = PathParam("crusher");
  ordered_json paths;
  paths["/healthz"]["get"] = Op("Liveness: database and broker state", "none");
  paths["/api/v1/crushers"]["get"] = Op("Crushers with their latest minimum thickness", "read");
  paths["/api/v1/crushers/{crusher}"]["get"] = Op("Crusher geometry, sensors, map hash and counters", "read", {c});
  paths["/api/v1/crushers/{crusher}/sensors"]["get"] = Op("Latest reading of each sensor", "read", {c});
  paths["/api/v1/crushers/{crusher}/sensors/{sensor}/readings"]["get"] =
      Op("Readings of one sensor, oldest first, paged with cursors", "read",
         {c, PathParam("sensor"), QueryParam("from", "string", "ISO-8601 UTC, inclusive"),
          QueryParam("to", "string", "ISO-8601 UTC, inclusive"), QueryParam("limit", "integer", "1..5000, default 500"),
          QueryParam("cursor", "string", "next_cursor of the previous page")});
  paths["/api/v1/crushers/{crusher}/readings"]["post"] =
      Op("Store readings {\"readings\": [{sensor, seq, time, thickness_mm, loops_intact, flags, battery_mv}]}", "write", {c});
  paths["/api/v1/crushers/{crusher}/mesh"]["get"] = Op("As-new liner mesh: points, faces, face z and theta", "read", {c});
  paths["/api/v1/crushers/{crusher}/wear"]["get"] =
      Op("Global wear (seed Eq. 9): per-face remaining thickness, per-row summary, minimum and where", "read",
         {c, QueryParam("format", "string", "json (default) or vtk (legacy VTK for ParaView)"),
          QueryParam("faces", "boolean", "false: leave out the per-face array")});
  paths["/api/v1/crushers/{crusher}/forecast"]["get"] =
      Op("Per row and sensor: the date the minimum thickness is reached, with a band", "read", {c});
  paths["/api/v1/crushers/{crusher}/diagnosis"]["get"] = Op("Latest diagnosis (docs/diagnosis.md, Output) and its status", "read", {c});
  paths["/api/v1/crushers/{crusher}/diagnosis"]["post"] = Op("Start a diagnosis on the stored readings", "write", {c}, "202");
  paths["/api/v1/crushers/{crusher}/events"]["get"] =
      Op("Server-Sent Events: `reading` and `wear` as they are committed", "read",
         {c, QueryParam("access_token", "string", "the bearer token (EventSource cannot set headers)")});
  paths["/api/v1/rejected"]["get"] = Op("Quarantined messages that failed validation, newest first", "read",
                                        {QueryParam("limit", "integer", "1..1000, default 100")});
  paths["/api/v1/whoami"]["get"] = Op("The caller's token name and scopes ({auth: false} on an open server)", "read");
  paths["/api/v1/openapi.json"]["get"] = Op("This document", "read");
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
             {{"application/json",
               {{"schema", {{"type", "object"}, {"properties", {{"error", {{"type", "string"}}}}}}}}}}}}}}}}},
      {"security", ordered_json::array({{{"bearer", ordered_json::array()}}})}};
  return doc.dump(1);
}

}  // namespace lw::server
