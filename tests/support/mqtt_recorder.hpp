#pragma once
// An MQTT client for integration tests that records every message it receives (Paho C++).
//   lw::test::MqttRecorder observer(broker.uri(), "observer", "user", "password" [, ca_file]);
//   observer.Subscribe("linerwatch/#");
//   observer.WaitFor(topic, "needle");          // exact topic, payload containing needle
//   observer.Count("/sensors/", "\"seq\":9");   // topics containing a part
// A refused subscription or publication is not an error here: what arrives is what tests check.
#include <atomic>
#include <chrono>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <mqtt/async_client.h>

namespace lw::test {

class MqttRecorder {
 public:
  /// How long a connect, SUBACK, PUBACK or awaited message may take: on loopback milliseconds, but
  /// a broker or program starved on a loaded machine can take seconds. A connect or subscription
  /// not complete when its wait ends would lose what follows, so only a real failure should end
  /// one; the waits return as soon as the answer comes.
  static constexpr std::chrono::seconds kPatience{60};

  struct Message {
    std::string topic, payload;
    bool retained;
  };
  /// Connects (a clean session unless `clean_session` is false) with a user name and password;
  /// `ca_file` set: the URI is ssl:// and the broker's certificate is checked against it.
  MqttRecorder(const std::string& uri, const std::string& id, const std::string& user, const std::string& password,
               const std::string& ca_file = "", bool clean_session = true)
      : client_(uri, id, nullptr) {
    client_.set_message_callback([this](mqtt::const_message_ptr m) {
      std::lock_guard<std::mutex> lock(mutex_);
      received_.push_back({m->get_topic(), m->to_string(), m->is_retained()});
    });
    client_.set_connection_lost_handler([this](const std::string&) { ++lost_; });
    mqtt::connect_options opts;
    opts.set_clean_session(clean_session);
    opts.set_user_name(user);
    opts.set_password(password);
    if (!ca_file.empty()) {
      mqtt::ssl_options ssl;
      ssl.set_trust_store(ca_file);
      opts.set_ssl(ssl);
    }
    client_.connect(opts)->wait_for(kPatience);
  }
  ~MqttRecorder() {
    try {
      client_.disconnect()->wait_for(std::chrono::seconds(2));
    } catch (const std::exception&) {
    }
  }
  MqttRecorder(const MqttRecorder&) = delete;
  MqttRecorder& operator=(const MqttRecorder&) = delete;

  void Subscribe(const std::string& filter) {
    try {
      client_.subscribe(filter, 1)->wait_for(kPatience);
    } catch (const std::exception&) {
      // A refused subscription: nothing will arrive on it, which is what the checks look at.
    }
  }
  void Publish(const std::string& topic, const std::string& payload, bool retained = false) {
    client_.publish(topic, payload, 1, retained)->wait_for(kPatience);
  }
  std::vector<Message> received() {
    std::lock_guard<std::mutex> lock(mutex_);
    return received_;
  }
  /// A message on exactly `topic` whose payload contains `needle`.
  bool Saw(const std::string& topic, const std::string& needle = "") {
    for (const Message& m : received()) {
      if (m.topic == topic && m.payload.find(needle) != std::string::npos) return true;
    }
    return false;
  }
  bool WaitFor(const std::string& topic, const std::string& needle = "", std::chrono::milliseconds timeout = kPatience) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < until) {
      if (Saw(topic, needle)) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
  }
  /// How often the connection was lost (the broker closed it); there is no automatic reconnect.
  int lost() const { return lost_; }
  /// The payload of the newest message on exactly `topic` ("" when none arrived).
  std::string Last(const std::string& topic) {
    std::string last;
    for (const Message& m : received()) {
      if (m.topic == topic) last = m.payload;
    }
    return last;
  }
  /// Messages whose topic contains `topic_part` and whose payload contains `needle`.
  size_t Count(const std::string& topic_part, const std::string& needle = "") {
    size_t n = 0;
    for (const Message& m : received()) {
      if (m.topic.find(topic_part) != std::string::npos && m.payload.find(needle) != std::string::npos) ++n;
    }
    return n;
  }

 private:
  mqtt::async_client client_;
  std::mutex mutex_;
  std::vector<Message> received_;
  std::atomic<int> lost_{0};
};

}  // namespace lw::test
