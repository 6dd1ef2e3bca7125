#pragma once
/// The data of the server's live events (EventBus, served as Server-Sent Events; docs/dashboard.md):
/// what a dashboard receives for a new reading and for a reline. Wear and alarm events carry the
/// retained MQTT messages as they are (mqtt::EncodeWear, AlarmsMessage).
#include <cstdint>
#include <string>
#include <vector>

#include "server/events.hpp"
#include "server/store.hpp"

namespace lw::server {

/// A reading event's data: the message as received (a JSON object; anything else becomes an empty
/// one) with its "sensor" and its sample "time" (ISO 8601) set. One line; invalid UTF-8 replaced.
std::string ReadingEventData(const std::string& payload, const std::string& sensor, int64_t time_s);

/// A campaign event's data: {"crusher": ...}, at which the dashboard reads the campaign list again.
std::string CampaignEventData(const std::string& crusher);

/// One "reading" event per reading, on its crusher; each one's data is built only when a reader
/// takes it (EventBus::PublishLazy).
void PublishReadingEvents(EventBus& events, const std::vector<StoredReading>& readings);

}  // namespace lw::server
