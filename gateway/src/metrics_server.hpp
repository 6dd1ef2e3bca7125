#pragma once
/// `--metrics HOST:PORT`: GET /metrics over cpp-httplib on a thread of its own. The Gateway's
/// counters belong to the main loop's thread, so the text is made there: a scrape asks for it
/// (Wanted()) and waits up to a second for the loop to Publish() it.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

namespace httplib {
class Server;
}

namespace lw::gateway {

class MetricsServer {
 public:
  /// Binds `host_port` (port 0: a free one) and serves. Throws std::runtime_error naming --metrics
  /// when it cannot bind.
  explicit MetricsServer(const std::string& host_port);
  ~MetricsServer();
  MetricsServer(const MetricsServer&) = delete;
  MetricsServer& operator=(const MetricsServer&) = delete;

  /// True while a scrape waits for fresh text.
  bool Wanted() const { return waiting_ > 0; }
  /// The exposition text the next scrapes get.
  void Publish(std::string text);
  /// "http://host:port/metrics".
  const std::string& url() const { return url_; }

 private:
  std::string Scrape();

  std::unique_ptr<httplib::Server> server_;
  std::thread thread_;
  std::string url_;
  std::atomic<int> waiting_{0};
  std::mutex mutex_;
  std::condition_variable published_;
  std::string text_;
  uint64_t generation_ = 0;
};

}  // namespace lw::gateway
