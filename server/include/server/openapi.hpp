#pragma once
#include <string>

namespace lw::server {
/// The OpenAPI 3.0 document served at /api/v1/openapi.json.
std::string OpenApiJson();
}  // namespace lw::server
