#include "protocol/xbee_api.hpp"

#include <cstring>

namespace lw::protocol {
namespace {

bool NeedsEscape(uint8_t b) {
  return b == kStartDelimiter || b == kEscape || b == kXon || b == kXoff;
}

void Put64(uint8_t* p, uint64_t v) {
  for (int i = 7; i >= 0; --i) {
    *p++ = static_cast<uint8_t>(v >> (8 * i));
  }
}
void Put16(uint8_t* p, uint16_t v) {
  p[0] = static_cast<uint8_t>(v >> 8);
  p[1] = static_cast<uint8_t>(v);
}
uint64_t Get64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v = (v << 8) | p[i];
  return v;
}
uint16_t Get16(const uint8_t* p) {
  return static_cast<uint16_t>((p[0] << 8) | p[1]);
}

// Common prologue of every parser: non-null, long enough, right type.
Status Check(const uint8_t* data, size_t len, size_t min_len, FrameType type) {
  if (data == nullptr || len < 1) return Status::kTruncated;
  if (data[0] != static_cast<uint8_t>(type)) return Status::kWrongType;
  if (len < min_len) return Status::kTruncated;
  return Status::kOk;
}

Status Finish(size_t needed, size_t out_cap, size_t* written) {
  if (written) *written = needed;
  return needed <= out_cap ? Status::kOk : Status::kBufferTooSmall;
}

}  // namespace

const char* DeliveryStatusName(uint8_t status) {
  switch (static_cast<DeliveryStatus>(status)) {
    case DeliveryStatus::kSuccess:
      return "success";
    case DeliveryStatus::kMacAckFailure:
      return "mac_ack_failure";
    case DeliveryStatus::kCcaFailure:
      return "cca_failure";
    case DeliveryStatus::kInvalidDestinationEndpoint:
      return "invalid_destination_endpoint";
    case DeliveryStatus::kNetworkAckFailure:
      return "network_ack_failure";
    case DeliveryStatus::kNotJoinedToNetwork:
      return "not_joined_to_network";
    case DeliveryStatus::kSelfAddressed:
      return "self_addressed";
    case DeliveryStatus::kAddressNotFound:
      return "address_not_found";
    case DeliveryStatus::kRouteNotFound:
      return "route_not_found";
    case DeliveryStatus::kBroadcastSourceFailedToHearNeighbour:
      return "broadcast_source_failed_to_hear_neighbour";
    case DeliveryStatus::kInvalidBindingTableIndex:
      return "invalid_binding_table_index";
    case DeliveryStatus::kResourceErrorLackOfBuffers:
      return "resource_error_lack_of_buffers";
    case DeliveryStatus::kAttemptedBroadcastWithApsTransmission:
      return "attempted_broadcast_with_aps_transmission";
    case DeliveryStatus::kAttemptedUnicastWithApsTransmissionButEeIsZero:
      return "attempted_unicast_with_aps_but_ee_zero";
    case DeliveryStatus::kResourceErrorLackOfBuffers2:
      return "resource_error_lack_of_buffers_2";
    case DeliveryStatus::kDataPayloadTooLarge:
      return "data_payload_too_large";
    case DeliveryStatus::kIndirectMessageUnrequested:
      return "indirect_message_unrequested";
  }
  return "unknown";
}

const char* ModemStatusName(uint8_t status) {
  switch (static_cast<ModemStatusCode>(status)) {
    case ModemStatusCode::kHardwareReset:
      return "hardware_reset";
    case ModemStatusCode::kWatchdogTimerReset:
      return "watchdog_timer_reset";
    case ModemStatusCode::kJoinedNetwork:
      return "joined_network";
    case ModemStatusCode::kDisassociated:
      return "disassociated";
    case ModemStatusCode::kCoordinatorStarted:
      return "coordinator_started";
    case ModemStatusCode::kNetworkSecurityKeyUpdated:
      return "network_security_key_updated";
    case ModemStatusCode::kVoltageSupplyLimitExceeded:
      return "voltage_supply_limit_exceeded";
    case ModemStatusCode::kModemConfigChangedWhileJoining:
      return "modem_config_changed_while_joining";
  }
  return "unknown";
}

uint8_t Checksum(const uint8_t* frame_data, size_t len) {
  uint8_t sum = 0;
  for (size_t i = 0; i < len; ++i) sum = static_cast<uint8_t>(sum + frame_data[i]);
  return static_cast<uint8_t>(0xFF - sum);
}

size_t EncodeTransmitRequest(ApiMode mode, const TransmitRequest& req, uint8_t* wire, size_t wire_cap) {
  uint8_t frame[kMaxFrameData];
  size_t len = 0;
  if (BuildTransmitRequest(req, frame, sizeof frame, &len) != Status::kOk) return 0;
  return EncodeFrame(mode, frame, len, wire, wire_cap);
}

size_t EncodeReceivePacket(ApiMode mode, const ReceivePacket& rx, uint8_t* wire, size_t wire_cap) {
  uint8_t frame[kMaxFrameData];
  size_t len = 0;
  if (BuildReceivePacket(rx, frame, sizeof frame, &len) != Status::kOk) return 0;
  return EncodeFrame(mode, frame, len, wire, wire_cap);
}

size_t EncodeFrame(ApiMode mode, const uint8_t* frame_data, size_t len, uint8_t* out, size_t out_cap) {
  if (frame_data == nullptr || out == nullptr || len == 0 || len > kMaxFrameData) return 0;
  size_t n = 0;
  const bool escaped = mode == ApiMode::kEscaped;
  auto put = [&](uint8_t b) -> bool {
    if (escaped && NeedsEscape(b)) {
      if (n + 2 > out_cap) return false;
      out[n++] = kEscape;
      out[n++] = static_cast<uint8_t>(b ^ kEscapeXor);
    } else {
      if (n + 1 > out_cap) return false;
      out[n++] = b;
    }
    return true;
  };
  if (out_cap < 1) return 0;
  out[n++] = kStartDelimiter;
  if (!put(static_cast<uint8_t>(len >> 8)) || !put(static_cast<uint8_t>(len))) return 0;
  for (size_t i = 0; i < len; ++i) {
    if (!put(frame_data[i])) return 0;
  }
  if (!put(Checksum(frame_data, len))) return 0;
  return n;
}

Status BuildTransmitRequest(const TransmitRequest& req, uint8_t* out, size_t out_cap, size_t* written) {
  if (req.payload_len > kMaxRfPayload || (req.payload_len > 0 && req.payload == nullptr)) return Status::kPayloadTooLarge;
  const size_t needed = 14 + req.payload_len;
  if (Finish(needed, out_cap, written) != Status::kOk || out == nullptr) return Status::kBufferTooSmall;
  out[0] = static_cast<uint8_t>(FrameType::kTransmitRequest);
  out[1] = req.frame_id;
  Put64(out + 2, req.dest64);
  Put16(out + 10, req.dest16);
  out[12] = req.broadcast_radius;
  out[13] = req.options;
  if (req.payload_len) std::memcpy(out + 14, req.payload, req.payload_len);
  return Status::kOk;
}

size_t EncodeAtCommand(ApiMode mode, const AtCommand& cmd, uint8_t* wire, size_t wire_cap) {
  uint8_t frame[kMaxFrameData];
  size_t len = 0;
  if (BuildAtCommand(cmd, frame, sizeof frame, &len) != Status::kOk) return 0;
  return EncodeFrame(mode, frame, len, wire, wire_cap);
}

Status BuildAtCommand(const AtCommand& cmd, uint8_t* out, size_t out_cap, size_t* written) {
  if (cmd.parameter_len > kMaxFrameData - 4 || (cmd.parameter_len > 0 && cmd.parameter == nullptr)) {
    return Status::kPayloadTooLarge;
  }
  if (Finish(4 + cmd.parameter_len, out_cap, written) != Status::kOk || out == nullptr) return Status::kBufferTooSmall;
  out[0] = static_cast<uint8_t>(FrameType::kAtCommand);
  out[1] = cmd.frame_id;
  out[2] = static_cast<uint8_t>(cmd.command[0]);
  out[3] = static_cast<uint8_t>(cmd.command[1]);
  if (cmd.parameter_len) std::memcpy(out + 4, cmd.parameter, cmd.parameter_len);
  return Status::kOk;
}

Status BuildAtCommandResponse(const AtCommandResponse& rsp, uint8_t* out, size_t out_cap, size_t* written) {
  if (rsp.data_len > kMaxFrameData - 5 || (rsp.data_len > 0 && rsp.data == nullptr)) return Status::kPayloadTooLarge;
  if (Finish(5 + rsp.data_len, out_cap, written) != Status::kOk || out == nullptr) return Status::kBufferTooSmall;
  out[0] = static_cast<uint8_t>(FrameType::kAtCommandResponse);
  out[1] = rsp.frame_id;
  out[2] = static_cast<uint8_t>(rsp.command[0]);
  out[3] = static_cast<uint8_t>(rsp.command[1]);
  out[4] = rsp.status;
  if (rsp.data_len) std::memcpy(out + 5, rsp.data, rsp.data_len);
  return Status::kOk;
}

bool AtCommandResponse::Value(uint64_t* out) const {
  if (status != static_cast<uint8_t>(AtStatus::kOk) || data_len == 0 || data_len > 8 || data == nullptr) return false;
  uint64_t v = 0;
  for (size_t i = 0; i < data_len; ++i) v = (v << 8) | data[i];
  *out = v;
  return true;
}

Status BuildTransmitStatus(const TransmitStatus& st, uint8_t* out, size_t out_cap, size_t* written) {
  if (Finish(7, out_cap, written) != Status::kOk || out == nullptr) return Status::kBufferTooSmall;
  out[0] = static_cast<uint8_t>(FrameType::kTransmitStatus);
  out[1] = st.frame_id;
  Put16(out + 2, st.dest16);
  out[4] = st.retry_count;
  out[5] = st.delivery_status;
  out[6] = st.discovery_status;
  return Status::kOk;
}

Status BuildReceivePacket(const ReceivePacket& rx, uint8_t* out, size_t out_cap, size_t* written) {
  if (rx.payload_len > kMaxRfPayload || (rx.payload_len > 0 && rx.payload == nullptr)) return Status::kPayloadTooLarge;
  const size_t needed = 12 + rx.payload_len;
  if (Finish(needed, out_cap, written) != Status::kOk || out == nullptr) return Status::kBufferTooSmall;
  out[0] = static_cast<uint8_t>(FrameType::kReceivePacket);
  Put64(out + 1, rx.src64);
  Put16(out + 9, rx.src16);
  out[11] = rx.options;
  if (rx.payload_len) std::memcpy(out + 12, rx.payload, rx.payload_len);
  return Status::kOk;
}

Status BuildModemStatus(const ModemStatus& ms, uint8_t* out, size_t out_cap, size_t* written) {
  if (Finish(2, out_cap, written) != Status::kOk || out == nullptr) return Status::kBufferTooSmall;
  out[0] = static_cast<uint8_t>(FrameType::kModemStatus);
  out[1] = ms.status;
  return Status::kOk;
}

Status BuildNodeIdentification(const NodeIdentification& ni, uint8_t* out, size_t out_cap, size_t* written) {
  size_t ni_len = 0;
  while (ni_len < sizeof(ni.node_identifier) - 1 && ni.node_identifier[ni_len] != '\0') ++ni_len;
  // 0x95 | src64(8) | src16(2) | opts | remote16(2) | remote64(8) | NI.. 0x00 | parent16(2) |
  // device type | source event | profile(2) | manufacturer(2) [| DD(4)] [| RSSI]
  const size_t needed =
      1 + 8 + 2 + 1 + 2 + 8 + ni_len + 1 + 2 + 1 + 1 + 2 + 2 + (ni.has_device_type_identifier ? 4 : 0) + (ni.has_rssi ? 1 : 0);
  if (Finish(needed, out_cap, written) != Status::kOk || out == nullptr) return Status::kBufferTooSmall;
  uint8_t* p = out;
  *p++ = static_cast<uint8_t>(FrameType::kNodeIdentification);
  Put64(p, ni.sender64);
  p += 8;
  Put16(p, ni.sender16);
  p += 2;
  *p++ = ni.receive_options;
  Put16(p, ni.remote16);
  p += 2;
  Put64(p, ni.remote64);
  p += 8;
  std::memcpy(p, ni.node_identifier, ni_len);
  p += ni_len;
  *p++ = 0;
  Put16(p, ni.parent16);
  p += 2;
  *p++ = ni.device_type;
  *p++ = ni.source_event;
  Put16(p, ni.profile_id);
  p += 2;
  Put16(p, ni.manufacturer_id);
  p += 2;
  if (ni.has_device_type_identifier) {
    for (int i = 3; i >= 0; --i) *p++ = static_cast<uint8_t>(ni.device_type_identifier >> (8 * i));
  }
  if (ni.has_rssi) *p = ni.rssi;
  return Status::kOk;
}

Status ParseTransmitRequest(const uint8_t* data, size_t len, TransmitRequest* out) {
  const Status s = Check(data, len, 14, FrameType::kTransmitRequest);
  if (s != Status::kOk) return s;
  if (len - 14 > kMaxRfPayload) return Status::kPayloadTooLarge;
  out->frame_id = data[1];
  out->dest64 = Get64(data + 2);
  out->dest16 = Get16(data + 10);
  out->broadcast_radius = data[12];
  out->options = data[13];
  out->payload = data + 14;
  out->payload_len = len - 14;
  return Status::kOk;
}

Status BuildRadioSettingsAnswer(const AtCommand& cmd, uint8_t np, uint8_t ee, uint8_t* out, size_t out_cap, size_t* written) {
  AtCommandResponse rsp;
  rsp.frame_id = cmd.frame_id;
  rsp.command[0] = cmd.command[0];
  rsp.command[1] = cmd.command[1];
  uint8_t value[2] = {0, 0};
  const bool query = cmd.parameter_len == 0;
  if (query && cmd.command[0] == 'N' && cmd.command[1] == 'P') {
    value[1] = np;
    rsp.data = value;
    rsp.data_len = 2;
  } else if (query && cmd.command[0] == 'E' && cmd.command[1] == 'E') {
    value[0] = ee;
    rsp.data = value;
    rsp.data_len = 1;
  } else {
    rsp.status = static_cast<uint8_t>(AtStatus::kInvalidCommand);
  }
  return BuildAtCommandResponse(rsp, out, out_cap, written);
}

Status ParseAtCommand(const uint8_t* data, size_t len, AtCommand* out) {
  const Status s = Check(data, len, 4, FrameType::kAtCommand);
  if (s != Status::kOk) return s;
  out->frame_id = data[1];
  out->command[0] = static_cast<char>(data[2]);
  out->command[1] = static_cast<char>(data[3]);
  out->parameter = data + 4;
  out->parameter_len = len - 4;
  return Status::kOk;
}

Status ParseAtCommandResponse(const uint8_t* data, size_t len, AtCommandResponse* out) {
  const Status s = Check(data, len, 5, FrameType::kAtCommandResponse);
  if (s != Status::kOk) return s;
  out->frame_id = data[1];
  out->command[0] = static_cast<char>(data[2]);
  out->command[1] = static_cast<char>(data[3]);
  out->status = data[4];
  out->data = data + 5;
  out->data_len = len - 5;
  return Status::kOk;
}

Status ParseTransmitStatus(const uint8_t* data, size_t len, TransmitStatus* out) {
  const Status s = Check(data, len, 7, FrameType::kTransmitStatus);
  if (s != Status::kOk) return s;
  out->frame_id = data[1];
  out->dest16 = Get16(data + 2);
  out->retry_count = data[4];
  out->delivery_status = data[5];
  out->discovery_status = data[6];
  return Status::kOk;
}

Status ParseReceivePacket(const uint8_t* data, size_t len, ReceivePacket* out) {
  const Status s = Check(data, len, 12, FrameType::kReceivePacket);
  if (s != Status::kOk) return s;
  if (len - 12 > kMaxRfPayload) return Status::kPayloadTooLarge;
  out->src64 = Get64(data + 1);
  out->src16 = Get16(data + 9);
  out->options = data[11];
  out->payload = data + 12;
  out->payload_len = len - 12;
  return Status::kOk;
}

Status ParseModemStatus(const uint8_t* data, size_t len, ModemStatus* out) {
  const Status s = Check(data, len, 2, FrameType::kModemStatus);
  if (s != Status::kOk) return s;
  out->status = data[1];
  return Status::kOk;
}

Status ParseNodeIdentification(const uint8_t* data, size_t len, NodeIdentification* out) {
  // Fixed part before the NI string: 22 bytes; after its terminator: 8 bytes.
  const Status s = Check(data, len, 22 + 1 + 8, FrameType::kNodeIdentification);
  if (s != Status::kOk) return s;
  const uint8_t* p = data + 1;
  out->sender64 = Get64(p);
  p += 8;
  out->sender16 = Get16(p);
  p += 2;
  out->receive_options = *p++;
  out->remote16 = Get16(p);
  p += 2;
  out->remote64 = Get64(p);
  p += 8;
  const uint8_t* end = data + len;
  size_t ni_len = 0;
  while (p + ni_len < end && p[ni_len] != 0) ++ni_len;
  if (p + ni_len >= end) return Status::kTruncated;  // no terminator
  if (ni_len > sizeof(out->node_identifier) - 1) return Status::kPayloadTooLarge;
  if (static_cast<size_t>(end - (p + ni_len + 1)) < 8) return Status::kTruncated;
  std::memcpy(out->node_identifier, p, ni_len);
  out->node_identifier[ni_len] = '\0';
  p += ni_len + 1;
  out->parent16 = Get16(p);
  p += 2;
  out->device_type = *p++;
  out->source_event = *p++;
  out->profile_id = Get16(p);
  p += 2;
  out->manufacturer_id = Get16(p);
  p += 2;
  // Optional fields (NO setting of the receiving radio): none, RSSI (1), DD (4) or DD + RSSI (5).
  const size_t rest = static_cast<size_t>(end - p);
  if (rest == 2 || rest == 3) return Status::kTruncated;
  if (rest > 5) return Status::kPayloadTooLarge;
  out->has_device_type_identifier = rest >= 4;
  out->device_type_identifier = 0;
  if (out->has_device_type_identifier) {
    for (int i = 0; i < 4; ++i) out->device_type_identifier = (out->device_type_identifier << 8) | *p++;
  }
  out->has_rssi = rest == 1 || rest == 5;
  out->rssi = out->has_rssi ? *p : 0;
  return Status::kOk;
}

}  // namespace lw::protocol
