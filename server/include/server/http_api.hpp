#pragma once
/// REST API (docs/server.md) and the dashboard's static files, on cpp-httplib.
#include <memory>
#include <string>
#include <vector>

#include "server/api_context.hpp"

namespace lw::server {

/// True when `host` (a Host header: name or address, optional :port) is an IP address literal,
/// localhost, or one of `allowed` (case-insensitive).
bool HostAllowed(const std::string& host, const std::vector<std::string>& allowed);

class HttpApi {
 public:
  explicit HttpApi(ApiContext context);
  ~HttpApi();
  HttpApi(const HttpApi&) = delete;
  HttpApi& operator=(const HttpApi&) = delete;

  /// Binds host:port (port 0: any free port). Throws std::runtime_error when it cannot.
  int Bind(const std::string& host, int port);
  /// Serves on a background thread until Stop().
  void Start();
  void Stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lw::server
