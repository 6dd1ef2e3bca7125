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
/// Largest RF payload of one unfragmented Zigbee unicast: no encryption (EE=0), no APS security,
/// no source route (Digi, XBee 3 Zigbee "Maximum RF payload size"). Buffers are sized for it; what
/// a link actually carries is RfPayloadLimit() of the module's NP and EE answers, often less.
inline constexpr size_t kMaxRfPayload = 84;
/// The same with network encryption (EE=1): 18 bytes of security overhead.
inline constexpr size_t kEncryptedRfPayload = 66;
/// APS end-to-end encryption (transmit option 0x20) costs 9 bytes more per packet.
inline constexpr size_t kApsEncryptionOverhead = 9;
/// The NP value an XBee 3 Zigbee module reports in API mode: the most a fragmented transmission
/// carries, not the single-packet limit (older S2/S2C firmware report the single-packet limit).
inline constexpr uint8_t kNpFragmentedMaximum = 0xFF;

/// The largest RF payload one unfragmented unicast carries, from the module's answers: `np` its
/// NP (-1: unknown), `ee` its EE (-1: unknown). NP below 0xFF is the module's own single-packet
/// limit; 0xFF (XBee 3 in API mode) says only that fragmentation reaches 255, so the EE table
/// decides: 84 bytes unencrypted, 66 encrypted, 66 when EE is unknown. Returns 0 when NP is
/// unknown: the caller then uses the smallest payload it supports. Never above kMaxRfPayload.
constexpr size_t RfPayloadLimit(int np, int ee) {
  if (np < 0 || np > 0xFF) return 0;
  const size_t table = ee == 0 ? kMaxRfPayload : kEncryptedRfPayload;
  if (np == kNpFragmentedMaximum) return table;
  return static_cast<size_t>(np) < kMaxRfPayload ? static_cast<size_t>(np) : kMaxRfPayload;
}
/// Worst-case size on the wire of one frame: every byte after the delimiter escaped.
inline constexpr size_t kMaxWireFrame = 1 + 2 * (2 + kMaxFrameData + 1);

enum class FrameType : uint8_t {
  kAtCommand = 0x08,
  kTransmitRequest = 0x10,
  kAtCommandResponse = 0x88,
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

/// 0x08 local AT Command: reads a setting when `parameter_len` is 0 (the module answers with a
/// 0x88 carrying the value), sets it otherwise. `parameter` is borrowed, not copied.
struct AtCommand {
  uint8_t frame_id = 0;  ///< 0 = no response wanted
  char command[2] = {};  ///< two ASCII characters, e.g. 'N', 'P'
  const uint8_t* parameter = nullptr;
  size_t parameter_len = 0;
};

/// Status byte of a 0x88 AT Command Response.
enum class AtStatus : uint8_t { kOk = 0, kError = 1, kInvalidCommand = 2, kInvalidParameter = 3, kTxFailure = 4 };

/// 0x88 AT Command Response. `data` points into the parsed frame data (the value, big-endian;
/// empty after a set).
struct AtCommandResponse {
  uint8_t frame_id = 0;
  char command[2] = {};
  uint8_t status = 0;  ///< see AtStatus
  const uint8_t* data = nullptr;
  size_t data_len = 0;
  /// The value as an unsigned number (big-endian, at most 8 bytes); false when the status is not
  /// kOk or there is no value.
  bool Value(uint64_t* out) const;
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

/// BuildAtCommand then EncodeFrame: a local AT command (a query when it has no parameter) as a
/// complete wire frame in `mode`. Returns the wire length, 0 when `wire_cap` is too small.
size_t EncodeAtCommand(ApiMode mode, const AtCommand& cmd, uint8_t* wire, size_t wire_cap);

/// The frame id after `id`: 1..255 cycling (0 means "no Transmit Status wanted", so it is skipped).
constexpr uint8_t NextFrameId(uint8_t id) {
  return id == 0xFF ? uint8_t{1} : static_cast<uint8_t>(id + 1);
}
Status BuildAtCommand(const AtCommand& cmd, uint8_t* out, size_t out_cap, size_t* written);
Status BuildAtCommandResponse(const AtCommandResponse& rsp, uint8_t* out, size_t out_cap, size_t* written);
/// The local AT response a module whose settings are NP = `np` and EE = `ee` gives to `cmd`: NP in
/// two bytes and EE in one, as Digi's modules answer those queries; any other command (or a
/// command that sets a value) is answered "invalid command". The host port's radio and the
/// simulator's coordinator both answer with it.
Status BuildRadioSettingsAnswer(const AtCommand& cmd, uint8_t np, uint8_t ee, uint8_t* out, size_t out_cap, size_t* written);
Status BuildTransmitStatus(const TransmitStatus& st, uint8_t* out, size_t out_cap, size_t* written);
Status BuildReceivePacket(const ReceivePacket& rx, uint8_t* out, size_t out_cap, size_t* written);
Status BuildModemStatus(const ModemStatus& ms, uint8_t* out, size_t out_cap, size_t* written);
Status BuildNodeIdentification(const NodeIdentification& ni, uint8_t* out, size_t out_cap, size_t* written);

/// Parsers: read frame data (API identifier first) as produced by FrameDecoder.
Status ParseTransmitRequest(const uint8_t* frame_data, size_t len, TransmitRequest* out);
Status ParseAtCommand(const uint8_t* frame_data, size_t len, AtCommand* out);
Status ParseAtCommandResponse(const uint8_t* frame_data, size_t len, AtCommandResponse* out);
Status ParseTransmitStatus(const uint8_t* frame_data, size_t len, TransmitStatus* out);
Status ParseReceivePacket(const uint8_t* frame_data, size_t len, ReceivePacket* out);
Status ParseModemStatus(const uint8_t* frame_data, size_t len, ModemStatus* out);
Status ParseNodeIdentification(const uint8_t* frame_data, size_t len, NodeIdentification* out);

}  // namespace lw::protocol
