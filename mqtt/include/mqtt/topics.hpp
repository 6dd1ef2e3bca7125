#pragma once
/// Every topic of docs/mqtt.md, built and parsed in one place. A crusher's topics live below
/// `{prefix}/{site}/{crusher}/` (prefix `linerwatch/v1` unless the server's --topic-root says
/// otherwise); `{sensor}` and `{address}` are single topic levels. Pure functions, no I/O.
#include <optional>
#include <string>
#include <string_view>

namespace lw::mqtt {

inline constexpr std::string_view kDefaultTopicPrefix = "linerwatch/v1";

/// What a topic below a crusher's root carries (docs/mqtt.md, one row each).
enum class TopicKind {
  kReading,    ///< `sensors/{sensor}/reading`: gateway -> server
  kCommitted,  ///< `sensors/{sensor}/committed`: server -> gateway
  kStatus,     ///< `gateway/status` (retained)
  kStats,      ///< `gateway/stats`
  kDevice,     ///< `gateway/devices/{address}` (retained)
  kWear,       ///< `wear` (retained): server
  kAlarms,     ///< `alarms` (retained): server, the active alarms (docs/alarms.md)
};

/// A topic taken apart.
struct ParsedTopic {
  TopicKind kind = TopicKind::kReading;
  std::string site;
  std::string crusher;
  std::string id;  ///< {sensor} of a reading or commit ack, {address} of a device; empty otherwise

  bool operator==(const ParsedTopic&) const = default;
};

/// The topics of one crusher: `{prefix}/{site}/{crusher}/...`.
class Topics {
 public:
  Topics(std::string_view site, std::string_view crusher, std::string_view prefix = kDefaultTopicPrefix);

  /// `{prefix}/{site}/{crusher}/`.
  const std::string& root() const { return root_; }

  std::string Reading(std::string_view sensor) const;
  std::string Committed(std::string_view sensor) const;
  std::string Status() const;
  std::string Stats() const;
  std::string Device(std::string_view address) const;
  std::string Wear() const;
  std::string Alarms() const;
  /// Any topic of `kind` of this crusher; `id` is the {sensor} or {address} level (ignored by the
  /// kinds that have none).
  std::string Build(TopicKind kind, std::string_view id = {}) const;

  /// Subscription to this crusher's commit acks: `{root}sensors/+/committed`.
  std::string CommittedFilter() const;
  /// Subscription to every site's and crusher's readings: `{prefix}/+/+/sensors/+/reading`.
  static std::string ReadingsFilter(std::string_view prefix = kDefaultTopicPrefix);
  /// Subscription to every gateway's retained status (and last will): `{prefix}/+/+/gateway/status`.
  static std::string StatusFilter(std::string_view prefix = kDefaultTopicPrefix);

  /// A topic of this crusher (it starts with root()); nullopt for anything else.
  std::optional<ParsedTopic> Parse(std::string_view topic) const;
  /// A topic of any site and crusher below `prefix`; nullopt for anything else (an empty level,
  /// an unknown kind, a topic outside `prefix`).
  static std::optional<ParsedTopic> ParseAny(std::string_view topic, std::string_view prefix = kDefaultTopicPrefix);

 private:
  std::string site_;
  std::string crusher_;
  std::string root_;
};

}  // namespace lw::mqtt
