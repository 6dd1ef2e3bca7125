// The REST API's request bodies, straight to their resources (server::rest::Resources, as the HTTP
// layer calls them once the route and scope are known) over the fixture crusher "fz1"
// (fuzz/data/crusher) with an SQLite database in the scratch folder. First byte: the route (mod 5):
// POST .../readings, POST .../alarms/rules, POST .../relines, POST .../alarms/{id}/ack,
// POST .../relines/{time}/void. For the last two the path parameter ({id}, {time}) comes first, up
// to a newline (as httplib hands it over: decoded, without '/', not empty); the rest is the body.
// Properties: no resource throws and none answers 500 (a malformed body is a 4xx naming what was
// wrong, a 503 only where the crusher is not loaded yet); every answer's JSON serialises; alarm rules
// the API accepted are the rules in force and load the same from the database (an AlarmEngine made
// afresh over it, as at a restart); after a reline or a void the API accepted, the crusher's model
// in force is the running campaign's (its start and thickness), and that campaign is the last one
// listed that is not voided.
#include <memory>
#include <string>

#include "fuzz_support.hpp"
#include "server/campaigns.hpp"
#include "unit/server/server_fixture.hpp"

using namespace lw;
using lw::fuzz::Check;

namespace {

struct Api {
  test::ServerParts parts{LW_FUZZ_DATA_DIR, false};
  std::unique_ptr<server::rest::Resources> resources = std::make_unique<server::rest::Resources>(parts.ctx);
};

constexpr const char* kRoutes[] = {"/api/v1/crushers/{crusher}/readings", "/api/v1/crushers/{crusher}/alarms/rules",
                                   "/api/v1/crushers/{crusher}/relines", "/api/v1/crushers/{crusher}/alarms/{id}/ack",
                                   "/api/v1/crushers/{crusher}/relines/{time}/void"};

/// The model in force for fz1 is the running campaign's, and the running one is the last counted.
void CheckCampaignInForce(Api& api, const std::string& route, const std::string& answer) {
  const std::vector<server::CampaignRecord> counted = server::Counted(api.parts.campaigns->List("fz1"));
  Check(!counted.empty(), route + ": no campaign counts after " + answer);
  const server::CampaignRecord& running = counted.back();
  Check(!running.end_s.has_value(), route + ": the last campaign that counts has an end: " + answer);
  const server::Crusher* c = api.parts.registry->Find("fz1");
  Check(c != nullptr, route + ": the crusher is gone after " + answer);
  Check(c->config.installed_at.time_since_epoch().count() == running.start_s,
        route + ": the model in force starts at " + core::FormatIsoTime(c->config.installed_at) + ", the running campaign at " +
            std::to_string(running.start_s) + ": " + answer);
  Check(c->config.thickness_new_mm == running.thickness_new_mm,
        route + ": the model in force is not the running campaign's thickness: " + answer);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static std::unique_ptr<Api> api;
  static size_t runs = 0;
  if (size == 0) return 0;
  const size_t which = data[0] % 5;
  std::string rest(reinterpret_cast<const char*>(data + 1), size - 1);
  server::rest::Request req;
  req.path = {"fz1"};
  if (which >= 3) {
    const size_t nl = rest.find('\n');
    if (nl == std::string::npos || nl == 0) return 0;
    const std::string param = rest.substr(0, nl);
    if (param.find('/') != std::string::npos) return 0;  // httplib's match ([^/]+) never hands one over
    req.path.push_back(param);
    rest.erase(0, nl + 1);
  }
  if (!api || ++runs % 5000 == 0) {  // a fresh database now and then: relines and rules pile up
    api.reset();
    api = std::make_unique<Api>();
  }
  req.body = rest;
  req.client = "127.0.0.1";
  const std::string name = kRoutes[which];
  const server::rest::Route& route = server::rest::Resources::Find(server::rest::Method::kPost, name);
  server::rest::Response r;
  try {
    r = api->resources->Call(route, req);
  } catch (const std::exception& e) {
    fuzz::Fail(name + " threw (the HTTP layer answers 500): " + e.what());
  }
  const std::string answer = r.json.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  Check(r.status != 500, name + " answered 500: " + answer);
  Check(r.status >= 200 && r.status < 600, "an answer with status " + std::to_string(r.status));
  if (which == 1 && r.status == 200) {
    const std::string in_force = core::AlarmConfigJson(api->parts.alarms->Rules("fz1")).dump();
    Check(r.json["rules"].dump() == in_force, "the rules answered are not the rules in force");
    server::AlarmEngine restarted(*api->parts.registry, api->parts.alarm_store);
    Check(core::AlarmConfigJson(restarted.Rules("fz1")).dump() == in_force, "the stored alarm rules load otherwise: " + in_force);
  }
  if (which == 2 && (r.status == 200 || r.status == 201)) {
    Check(r.json.value("running", false) || r.status == 200, name + " created a campaign that is not running: " + answer);
    CheckCampaignInForce(*api, name, answer);
  }
  if (which == 4 && r.status == 200) {
    Check(r.json.value("voided", false), name + " answered 200 with a campaign that is not voided: " + answer);
    CheckCampaignInForce(*api, name, answer);
  }
  return 0;
}
