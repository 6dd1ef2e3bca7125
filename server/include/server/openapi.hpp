#pragma once
#include <string>

namespace lw::server {
/// The OpenAPI 3.0 document served at /api/v1/openapi.json, generated from the route table
/// (rest::Resources::Routes()): one operation per route, nothing else.
std::string OpenApiJson();
}  // namespace lw::server
