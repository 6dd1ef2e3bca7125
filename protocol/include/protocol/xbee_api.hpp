#pragma once
/// Digi XBee (Zigbee, API firmware) frame layer: framing, escaping and the frame types linerwatch
/// uses. Freestanding: no heap, no exceptions, no RTTI; all buffers belong to the caller.
///
/// A frame on the wire is `0x7E | length (u16 BE) | frame data | checksum`, where frame data starts
/// with the API identifier (frame type) and checksum = 0xFF - (sum of frame data bytes & 0xFF).
/// In API mode 2 every byte after the start delimiter that equals 0x7E, 0x7D, 0x11 or 0x13 is sent
/// as 0x7D followed by the byte XOR 0x20 (length and checksum bytes included).
#include <cstddef>
#include <cstdint>

namespace lw::protocol {

/// API mode as set with the radio's AP command.
enum class ApiMode : uint8_t {
  kUnescaped = 1,  ///< AP=1
  kEscaped = 2,    ///< AP=2
};

inline constexpr uint8_t kStartDelimiter = 0x7E;
inline constexpr uint8_t kEscape = 0x7D;
inline constexpr uint8_t kXon = 0x11;
inline constexpr uint8_t kXoff = 0x13;
inline constexpr uint8_t kEscapeXor = 0x20;

/// Largest frame data (API identifier .. last data byte) any linerwatch peer builds or accepts.
/// Big enough for a 0x10 Transmit Request / 0x90 Receive Packet carrying kMaxRfPayload bytes.
inline constexpr size_t kMaxFrameData = 128;
/// Largest RF payload per Zigbee transmission without APS encryption or fragmentation (ATNP on an
/// XBee 3 / S2C Zigbee module reports 84 = 0x54). The sensor payload never exceeds this.
inline constexpr size_t kMaxRfPayload = 84;
/// Worst-case size on the wire of one frame: every byte after the delimiter escaped.
inline constexpr size_t kMaxWireFrame = 1 + 2 * (2 + kMaxFrameData + 1);

enum class FrameType : uint8_t {
  kTransmitRequest = 0x10,
  kModemStatus = 0x8A,
  kTransmitStatus = 0x8B,
  kReceivePacket = 0x90,
  kNodeIdentification = 0x95,
};

/// Delivery status byte of a 0x8B Transmit Status frame.
enum class DeliveryStatus : uint8_t {
  kSuccess = 0x00,
  kMacAckFailure = 0x01,
  kCcaFailure = 0x02,
  kInvalidDestinationEndpoint = 0x15,
  kNetworkAckFailure = 0x21,
  kNotJoinedToNetwork = 0x22,
  kSelfAddressed = 0x23,
  kAddressNotFound = 0x24,
  kRouteNotFound = 0x25,
  kBroadcastSourceFailedToHearNeighbour = 0x26,
  kInvalidBindingTableIndex = 0x2B,
  kResourceErrorLackOfBuffers = 0x2C,
  kAttemptedBroadcastWithApsTransmission = 0x2D,
  kAttemptedUnicastWithApsTransmissionButEeIsZero = 0x2E,
  kResourceErrorLackOfBuffers2 = 0x32,
  kDataPayloadTooLarge = 0x74,
  kIndirectMessageUnrequested = 0x75,
};
/// Human-readable name of a delivery status ("success", "mac_ack_failure", ...; "unknown" otherwise).
const char* DeliveryStatusName(uint8_t status);

/// Modem status byte of a 0x8A frame (subset that Zigbee firmware emits).
enum class ModemStatusCode : uint8_t {
  kHardwareReset = 0x00,
  kWatchdogTimerReset = 0x01,
  kJoinedNetwork = 0x02,
  kDisassociated = 0x03,
  kCoordinatorStarted = 0x06,
  kNetworkSecurityKeyUpdated = 0x07,
  kVoltageSupplyLimitExceeded = 0x0D,
  kModemConfigChangedWhileJoining = 0x11,
};
const char* ModemStatusName(uint8_t status);

/// Result of building or parsing a frame.
enum class Status : uint8_t {
  kOk = 0,
  kBufferTooSmall,   ///< output buffer cannot hold the result
  kTruncated,        ///< input shorter than the frame type requires
  kWrongType,        ///< frame data starts with another API identifier
  kPayloadTooLarge,  ///< RF payload above kMaxRfPayload / frame above kMaxFrameData
};

inline constexpr uint64_t kBroadcastAddress64 = 0x000000000000FFFFull;
inline constexpr uint64_t kCoordinatorAddress64 = 0x0000000000000000ull;
inline constexpr uint16_t kUnknownAddress16 = 0xFFFE;

/// 0x10 Transmit Request. `payload` is borrowed, not copied.
struct TransmitRequest {
  uint8_t frame_id = 0;  ///< 0 = no Transmit Status wanted
  uint64_t dest64 = kCoordinatorAddress64;
  uint16_t dest16 = kUnknownAddress16;
  uint8_t broadcast_radius = 0;
  uint8_t options = 0;
  const uint8_t* payload = nullptr;
  size_t payload_len = 0;
};

/// 0x8B Transmit Status.
struct TransmitStatus {
  uint8_t frame_id = 0;
  uint16_t dest16 = 0;
  uint8_t retry_count = 0;
  uint8_t delivery_status = 0;  ///< see DeliveryStatus
  uint8_t discovery_status = 0;
};

/// 0x90 Receive Packet. `payload` points into the parsed frame data.
struct ReceivePacket {
  uint64_t src64 = 0;
  uint16_t src16 = 0;
  uint8_t options = 0;
  const uint8_t* payload = nullptr;
  size_t payload_len = 0;
};

/// 0x8A Modem Status.
struct ModemStatus {
  uint8_t status = 0;  ///< see ModemStatusCode
};

/// 0x95 Node Identification Indicator.
struct NodeIdentification {
  uint64_t sender64 = 0;
  uint16_t sender16 = 0;
  uint8_t receive_options = 0;
  uint16_t remote16 = 0;
  uint64_t remote64 = 0;
  char node_identifier[21] = {};  ///< NUL-terminated NI string (at most 20 characters)
  uint16_t parent16 = 0;
  uint8_t device_type = 0;  ///< 0 coordinator, 1 router, 2 end device
  uint8_t source_event = 0;
  uint16_t profile_id = 0;
  uint16_t manufacturer_id = 0;
  /// Optional trailing fields, present when the receiving radio's NO (node discovery options)
  /// setting asks for them: the sender's DD device type identifier (4 bytes) and the RSSI of the
  /// last hop (1 byte), in that order.
  bool has_device_type_identifier = false;
  uint32_t device_type_identifier = 0;
  bool has_rssi = false;
  uint8_t rssi = 0;
};

/// Checksum over frame data: 0xFF minus the low byte of the sum of all bytes.
uint8_t Checksum(const uint8_t* frame_data, size_t len);

/// Wraps frame data (API identifier first) into a wire frame: delimiter, length, data, checksum,
/// escaped in API mode 2. Writes at most `out_cap` bytes; returns the number written, 0 when
/// `out_cap` is too small or `len` is 0 or above kMaxFrameData.
size_t EncodeFrame(ApiMode mode, const uint8_t* frame_data, size_t len, uint8_t* out, size_t out_cap);

/// Builders: write frame data (API identifier first) into `out`; `*written` receives the length.
Status BuildTransmitRequest(const TransmitRequest& req, uint8_t* out, size_t out_cap, size_t* written);

/// BuildTransmitRequest then EncodeFrame: `req` as a complete wire frame in `mode`. Returns the wire
/// length, or 0 when the payload is too large or `wire_cap` too small.
size_t EncodeTransmitRequest(ApiMode mode, const TransmitRequest& req, uint8_t* wire, size_t wire_cap);

/// BuildReceivePacket then EncodeFrame: `rx` as a complete wire frame in `mode`, what a coordinator
/// writes to its host for a received transmission. Returns the wire length, or 0 when the payload
/// is too large or `wire_cap` too small.
size_t EncodeReceivePacket(ApiMode mode, const ReceivePacket& rx, uint8_t* wire, size_t wire_cap);

/// The frame id after `id`: 1..255 cycling (0 means "no Transmit Status wanted", so it is skipped).
constexpr uint8_t NextFrameId(uint8_t id) {
  return id == 0xFF ? uint8_t{1} : static_cast<uint8_t>(id + 1);
}
Status BuildTransmitStatus(const TransmitStatus& st, uint8_t* out, size_t out_cap, size_t* written);
Status BuildReceivePacket(const ReceivePacket& rx, uint8_t* out, size_t out_cap, size_t* written);
Status BuildModemStatus(const ModemStatus& ms, uint8_t* out, size_t out_cap, size_t* written);
Status BuildNodeIdentification(const NodeIdentification& ni, uint8_t* out, size_t out_cap, size_t* written);

/// Parsers: read frame data (API identifier first) as produced by FrameDecoder.
Status ParseTransmitRequest(const uint8_t* frame_data, size_t len, TransmitRequest* out);
Status ParseTransmitStatus(const uint8_t* frame_data, size_t len, TransmitStatus* out);
Status ParseReceivePacket(const uint8_t* frame_data, size_t len, ReceivePacket* out);
Status ParseModemStatus(const uint8_t* frame_data, size_t len, ModemStatus* out);
Status ParseNodeIdentification(const uint8_t* frame_data, size_t len, NodeIdentification* out);

}  // namespace lw::protocol
