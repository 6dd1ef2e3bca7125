#include "metrics_server.hpp"

#include <httplib.h>

#include <chrono>
#include <stdexcept>

#include "core/prometheus.hpp"

namespace lw::gateway {
namespace {

void JsonError(httplib::Response& res, int status, const std::string& message) {
  res.status = status;
  std::string escaped;
  for (char c : message) {
    if (c == '"' || c == '\\') escaped += '\\';
    escaped += c;
  }
  res.set_content("{\"error\": \"" + escaped + "\"}", "application/json");
}

}  // namespace

MetricsServer::MetricsServer(const std::string& host_port) : server_(std::make_unique<httplib::Server>()) {
  const size_t colon = host_port.rfind(':');
  const std::string host = host_port.substr(0, colon);
  const int port = std::stoi(host_port.substr(colon + 1));
  // A scrape is one small GET: two workers, short timeouts, no body.
  server_->new_task_queue = [] { return new httplib::ThreadPool(2); };
  server_->set_read_timeout(5, 0);
  server_->set_write_timeout(5, 0);
  server_->set_payload_max_length(1024);
  server_->Get("/metrics", [this](const httplib::Request&, httplib::Response& res) {
    const std::string text = Scrape();
    if (text.empty()) return JsonError(res, 503, "metrics not ready yet");
    res.set_content(text, core::prometheus::kContentType);
  });
  server_->set_error_handler([](const httplib::Request& req, httplib::Response& res) {
    if (res.status == 404) JsonError(res, 404, "no such resource: " + req.path + " (the gateway serves /metrics only)");
  });
  const int bound = port == 0 ? server_->bind_to_any_port(host) : (server_->bind_to_port(host, port) ? port : -1);
  if (bound <= 0) throw std::runtime_error("--metrics " + host_port + ": cannot bind (in use or not a local address)");
  url_ = "http://" + host + ":" + std::to_string(bound) + "/metrics";
  thread_ = std::thread([this] { server_->listen_after_bind(); });
}

MetricsServer::~MetricsServer() {
  server_->stop();
  if (thread_.joinable()) thread_.join();
}

void MetricsServer::Publish(std::string text) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    text_ = std::move(text);
    ++generation_;
  }
  published_.notify_all();
}

std::string MetricsServer::Scrape() {
  std::unique_lock<std::mutex> lock(mutex_);
  const uint64_t asked_at = generation_;
  ++waiting_;
  published_.wait_for(lock, std::chrono::seconds(1), [&] { return generation_ != asked_at; });
  --waiting_;
  return text_;
}

}  // namespace lw::gateway
