#pragma once
/// The OpenAPI 3.0 schemas (JSON text) of the REST answers and request bodies: what each handler in
/// rest.cpp (and the wear worker's bodies, wear_service.cpp) writes. `required` lists only the fields
/// always present, `nullable` marks those that can be null. Shared parts are components of the
/// document (SharedSchemas), referred to as {"$ref": "#/components/schemas/<name>"}. The live test
/// (tests/integration/server/test_server_openapi.cpp) checks real answers against them.
#include <string>
#include <utility>
#include <vector>

namespace lw::server::rest::schemas {

/// components.schemas of the document: {name, schema text}.
const std::vector<std::pair<const char*, std::string>>& SharedSchemas();

extern const std::string kHealth;
extern const std::string kCrusherList;
extern const std::string kCrusherDetail;
extern const std::string kSensorList;
extern const std::string kReadingsPage;
extern const std::string kPostReadingsRequest;
extern const std::string kPostReadingsResult;
extern const std::string kPostReadingsNoneTaken;  ///< the 422: the result with its "error"
extern const std::string kMesh;
extern const std::string kWear;
extern const std::string kForecast;
extern const std::string kDiagnosis;
extern const std::string kDiagnosisStarted;
extern const std::string kAlarmRules;         ///< every rule with every setting (core::AlarmConfigJson)
extern const std::string kAlarmRulesRequest;  ///< the rules and settings to change
extern const std::string kRejectedList;
extern const std::string kWhoAmI;
extern const std::string kOpenApi;
extern const std::string kEventStream;  ///< the text/event-stream body, as a string schema with its events described

}  // namespace lw::server::rest::schemas
