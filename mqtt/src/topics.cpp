#include "mqtt/topics.hpp"

#include <vector>

namespace lw::mqtt {
namespace {

constexpr std::string_view kSensors = "sensors/";
constexpr std::string_view kDevices = "gateway/devices/";

std::vector<std::string_view> Split(std::string_view s) {
  std::vector<std::string_view> out;
  size_t start = 0;
  while (true) {
    const size_t p = s.find('/', start);
    out.push_back(s.substr(start, p == std::string_view::npos ? std::string_view::npos : p - start));
    if (p == std::string_view::npos) break;
    start = p + 1;
  }
  return out;
}

/// The part of a topic below a crusher's root: `sensors/{sensor}/reading`, `wear`, ...; each
/// level non-empty. Fills kind and id.
bool ParseBelowRoot(std::string_view rest, ParsedTopic* out) {
  const auto levels = Split(rest);
  for (const std::string_view level : levels) {
    if (level.empty()) return false;
  }
  if (levels.size() == 3 && levels[0] == "sensors" && (levels[2] == "reading" || levels[2] == "committed")) {
    out->kind = levels[2] == "reading" ? TopicKind::kReading : TopicKind::kCommitted;
    out->id = std::string(levels[1]);
    return true;
  }
  if (levels.size() == 3 && levels[0] == "gateway" && levels[1] == "devices") {
    out->kind = TopicKind::kDevice;
    out->id = std::string(levels[2]);
    return true;
  }
  if (levels.size() == 2 && levels[0] == "gateway" && (levels[1] == "status" || levels[1] == "stats")) {
    out->kind = levels[1] == "status" ? TopicKind::kStatus : TopicKind::kStats;
    return true;
  }
  if (levels.size() == 1 && (levels[0] == "wear" || levels[0] == "alarms")) {
    out->kind = levels[0] == "wear" ? TopicKind::kWear : TopicKind::kAlarms;
    return true;
  }
  return false;
}

}  // namespace

Topics::Topics(std::string_view site, std::string_view crusher, std::string_view prefix)
    : site_(site), crusher_(crusher), root_(std::string(prefix) + "/" + site_ + "/" + crusher_ + "/") {}

std::string Topics::Build(TopicKind kind, std::string_view id) const {
  switch (kind) {
    case TopicKind::kReading:
      return root_ + std::string(kSensors) + std::string(id) + "/reading";
    case TopicKind::kCommitted:
      return root_ + std::string(kSensors) + std::string(id) + "/committed";
    case TopicKind::kStatus:
      return root_ + "gateway/status";
    case TopicKind::kStats:
      return root_ + "gateway/stats";
    case TopicKind::kDevice:
      return root_ + std::string(kDevices) + std::string(id);
    case TopicKind::kWear:
      return root_ + "wear";
    case TopicKind::kAlarms:
      return root_ + "alarms";
  }
  return root_;
}

std::string Topics::Reading(std::string_view sensor) const {
  return Build(TopicKind::kReading, sensor);
}
std::string Topics::Committed(std::string_view sensor) const {
  return Build(TopicKind::kCommitted, sensor);
}
std::string Topics::Status() const {
  return Build(TopicKind::kStatus);
}
std::string Topics::Stats() const {
  return Build(TopicKind::kStats);
}
std::string Topics::Device(std::string_view address) const {
  return Build(TopicKind::kDevice, address);
}
std::string Topics::Wear() const {
  return Build(TopicKind::kWear);
}

std::string Topics::Alarms() const {
  return Build(TopicKind::kAlarms);
}

std::string Topics::CommittedFilter() const {
  return Committed("+");
}

std::string Topics::ReadingsFilter(std::string_view prefix) {
  return Topics("+", "+", prefix).Reading("+");
}

std::string Topics::StatusFilter(std::string_view prefix) {
  return Topics("+", "+", prefix).Status();
}

std::optional<ParsedTopic> Topics::Parse(std::string_view topic) const {
  if (topic.substr(0, root_.size()) != root_) return std::nullopt;
  ParsedTopic out{TopicKind::kReading, site_, crusher_, {}};
  if (!ParseBelowRoot(topic.substr(root_.size()), &out)) return std::nullopt;
  return out;
}

std::optional<ParsedTopic> Topics::ParseAny(std::string_view topic, std::string_view prefix) {
  if (topic.size() <= prefix.size() || topic.substr(0, prefix.size()) != prefix || topic[prefix.size()] != '/') {
    return std::nullopt;
  }
  const std::string_view rest = topic.substr(prefix.size() + 1);
  const size_t site_end = rest.find('/');
  if (site_end == std::string_view::npos || site_end == 0) return std::nullopt;
  const size_t crusher_end = rest.find('/', site_end + 1);
  if (crusher_end == std::string_view::npos || crusher_end == site_end + 1) return std::nullopt;
  ParsedTopic out{TopicKind::kReading,
                  std::string(rest.substr(0, site_end)),
                  std::string(rest.substr(site_end + 1, crusher_end - site_end - 1)),
                  {}};
  if (!ParseBelowRoot(rest.substr(crusher_end + 1), &out)) return std::nullopt;
  return out;
}

}  // namespace lw::mqtt
