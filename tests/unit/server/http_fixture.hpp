#pragma once
// A real HttpApi on 127.0.0.1 (any free port) over ServerParts: the server as REST clients meet it.
// Include after every Eigen header and before CppUTest (see test_http_api.cpp).
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "server/http_api.hpp"
#include "unit/server/server_fixture.hpp"

#include <httplib.h>  // after Eigen: <resolv.h> (via httplib) defines the macro _res, a name inside Eigen

namespace lw::test {

/// The crusher folder the HTTP tests serve (a 20-day campaign, seed 11): one per test program.
inline CrusherFolder& HttpFolder() {
  static CrusherFolder f(20, 11);
  return f;
}

struct LiveApi {
  ServerParts parts;
  std::unique_ptr<server::HttpApi> api;
  int port = 0;

  explicit LiveApi(const std::string& crushers, bool with_tokens, const std::string& web_dir = "", const std::string& db = "",
                   const server::HttpLimits& limits = {})
      : parts(crushers, with_tokens, web_dir, db) {
    parts.ctx.limits = limits;
    api = std::make_unique<server::HttpApi>(parts.ctx);
    port = api->Bind("127.0.0.1", 0);
    api->Start();
  }
  ~LiveApi() { api->Stop(); }
  LiveApi(const LiveApi&) = delete;
  LiveApi& operator=(const LiveApi&) = delete;

  std::string Url() const { return "http://127.0.0.1:" + std::to_string(port); }
  httplib::Client Client(const char* token = nullptr) const {
    httplib::Client c("127.0.0.1", port);
    c.set_read_timeout(60, 0);
    if (token) c.set_bearer_token_auth(token);
    return c;
  }
  /// Posts every reading of `folder`'s bundle through REST; returns the HTTP status (0: no answer).
  int PostReadings(const CrusherFolder& folder, const char* token = nullptr) const {
    nlohmann::json body = {{"readings", nlohmann::json::array()}};
    for (const auto& m : Messages(folder.bundle)) body["readings"].push_back(nlohmann::json::parse(m.payload));
    auto res = Client(token).Post("/api/v1/crushers/" + folder.id() + "/readings", body.dump(), "application/json");
    return res ? res->status : 0;
  }
};

}  // namespace lw::test
