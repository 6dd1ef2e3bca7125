#include "server/sse_events.hpp"

#include <chrono>
#include <nlohmann/json.hpp>

#include "core/time.hpp"

namespace lw::server {

std::string ReadingEventData(const std::string& payload, const std::string& sensor, int64_t time_s) {
  nlohmann::json j = nlohmann::json::parse(payload, nullptr, false);
  if (!j.is_object()) j = nlohmann::json::object();
  j["sensor"] = sensor;
  j["time"] = core::FormatIsoSeconds(time_s);
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

std::string CampaignEventData(const std::string& crusher) {
  return nlohmann::ordered_json({{"crusher", crusher}}).dump();
}

void PublishReadingEvents(EventBus& events, const std::vector<StoredReading>& readings) {
  for (const StoredReading& s : readings) {
    events.PublishLazy(s.crusher, "reading", [payload = s.payload, sensor = s.sensor, time_s = s.time_s] {
      return ReadingEventData(payload, sensor, time_s);
    });
  }
}

}  // namespace lw::server
