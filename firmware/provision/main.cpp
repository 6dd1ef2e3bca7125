// linerwatch-provision: the host half of scripts/flash (docs/firmware.md, *Flashing and
// provisioning*).
//   check  --board B --image FILE.bin   refuses an image built for another board or too big
//   record --board B --sensor-id N [--api-mode 1|2] [--ladder-loops N] --out FILE
//                                       writes the 16-byte record and prints where it goes
//   show   --board B --record FILE      decodes a record (read back from a board)
//   board  --board B                    the board's table entry as name=value lines (scripts/flash
//                                       reads its addresses and chip id from here)
// Exit status: 0 done, 1 refused (the line says why), 2 bad command line.
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "core/cmdline.hpp"
#include "protocol/provision.hpp"

namespace {

namespace proto = lw::protocol;

struct Refused : std::runtime_error {
  using std::runtime_error::runtime_error;
};

std::string BoardNames() {
  std::string s;
  for (const proto::BoardInfo& b : proto::kBoards) s += (s.empty() ? "" : ", ") + std::string(b.name);
  return s;
}

const proto::BoardInfo& BoardByName(const std::string& name) {
  for (const proto::BoardInfo& b : proto::kBoards)
    if (name == b.name) return b;
  throw lw::core::UsageError("--board: unknown board '" + name + "' (one of " + BoardNames() + ")");
}

std::vector<uint8_t> ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Refused("cannot read " + path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// The board id of the image's marker, or -1 when it has none.
int MarkerBoard(const std::vector<uint8_t>& image) {
  for (size_t i = 0; i + proto::kBoardMarkerSize <= image.size(); i += 4) {
    if (image[i] == 'L' && image[i + 1] == 'W' && image[i + 2] == 'B' && image[i + 3] == 'D' && image[i + 6] == 0xFF &&
        image[i + 7] == 0xFF)
      return image[i + 4] | (image[i + 5] << 8);
  }
  return -1;
}

int Check(const proto::BoardInfo& board, const std::string& path) {
  const std::vector<uint8_t> image = ReadFile(path);
  if (image.size() >= 4 && image[0] == 0x7F && image[1] == 'E' && image[2] == 'L' && image[3] == 'F')
    throw Refused(
        path +
        " is an ELF file; give the .bin beside it (the cross build writes one; arm-none-eabi-objcopy -O binary makes one)");
  const int id = MarkerBoard(image);
  if (id < 0) throw Refused(path + " is not a linerwatch firmware image (no board marker 'LWBD' in it)");
  if (id != board.id) {
    const proto::BoardInfo* other = proto::FindBoardById(static_cast<uint16_t>(id));
    throw Refused(path + " is an image for " +
                  (other ? std::string(other->name) + " (" + other->part + ")" : "board id " + std::to_string(id)) +
                  ", not for " + board.name + " (" + board.part + ")");
  }
  if (image.size() > board.image_max)
    throw Refused(path + " is " + std::to_string(image.size()) + " B, over the " + std::to_string(board.image_max) + " B " +
                  board.name + " has below its provisioning page");
  std::printf("image %s: %s (%s), %zu B of %u B, at 0x%08X\n", path.c_str(), board.name, board.part, image.size(),
              board.image_max, board.flash_base);
  return 0;
}

int Record(const proto::BoardInfo& board, const lw::core::ParsedOptions& o) {
  proto::Provision p;
  p.board = board.id;
  p.sensor_id = o.Integer<uint32_t>("sensor-id", 0);
  p.api_mode = o.Integer<uint8_t>("api-mode", 2);
  p.ladder_loops = o.Integer<uint8_t>("ladder-loops", 100);
  uint8_t bytes[proto::kProvisionSize];
  proto::EncodeProvision(p, bytes);
  const std::string out = o.Text("out");
  std::ofstream f(out, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(bytes), sizeof bytes);
  if (!f.flush()) throw Refused("cannot write " + out);
  std::printf("record %s: board %s, sensor %u, api mode %u, %u loops, %zu B at 0x%08X\n", out.c_str(), board.name, p.sensor_id,
              unsigned{p.api_mode}, unsigned{p.ladder_loops}, sizeof bytes, board.provision_address);
  return 0;
}

int Show(const proto::BoardInfo& board, const std::string& path) {
  const std::vector<uint8_t> bytes = ReadFile(path);
  proto::Provision p;
  const proto::ProvisionStatus s =
      bytes.size() < proto::kProvisionSize ? proto::ProvisionStatus::kMissing : proto::DecodeProvision(bytes.data(), &p);
  switch (s) {
    case proto::ProvisionStatus::kOk:
      break;
    case proto::ProvisionStatus::kMissing:
      throw Refused(path + ": no provisioning record (no 'LWPR' magic)");
    case proto::ProvisionStatus::kBadCrc:
      throw Refused(path + ": provisioning record fails its CRC");
    case proto::ProvisionStatus::kBadVersion:
      throw Refused(path + ": provisioning record of an unknown version");
    case proto::ProvisionStatus::kBadValue:
      throw Refused(path + ": provisioning record with a value out of range");
  }
  if (p.board != board.id) {
    const proto::BoardInfo* other = proto::FindBoardById(p.board);
    throw Refused(path + ": a record for " + (other ? std::string(other->name) : "board id " + std::to_string(p.board)) +
                  ", not for " + board.name);
  }
  std::printf("record %s: board %s, sensor %u, api mode %u, %u loops\n", path.c_str(), board.name, p.sensor_id,
              unsigned{p.api_mode}, unsigned{p.ladder_loops});
  return 0;
}

int Board(const proto::BoardInfo& board) {
  std::printf(
      "name=%s\npart=%s\nid=0x%04X\nchip_id=0x%03X\nflash_base=0x%08X\nimage_max=%u\nprovision_address=0x%08X\nrecord_size=%zu\n",
      board.name, board.part, unsigned{board.id}, unsigned{board.chip_id}, board.flash_base, board.image_max,
      board.provision_address, proto::kProvisionSize);
  return 0;
}

const lw::core::OptionTable& Table() {
  static const lw::core::OptionTable table{
      {lw::core::Option::Text("board", "NAME", "netduinoplus2 or l431").Required(),
       lw::core::Option::Text("image", "FILE", "check: the image (.bin)"),
       lw::core::Option::Whole("sensor-id", "N", 1, 4294967295, "record: the sensor's id (as in crusher.json)"),
       lw::core::Option::Whole("api-mode", "N", 1, 2, "record: the radio's AP setting (default 2)"),
       lw::core::Option::Whole("ladder-loops", "N", 1, 128, "record: loops on the ladder (default 100)"),
       lw::core::Option::Text("out", "FILE", "record: where to write the record"),
       lw::core::Option::Text("record", "FILE", "show: a record read back from a board")},
      "COMMAND"};
  return table;
}

const std::string& Need(const lw::core::ParsedOptions& o, const std::string& cmd, const std::string& name) {
  static std::string v;
  v = o.Text(name);
  if (v.empty()) throw lw::core::UsageError(cmd + " needs --" + name);
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  try {
    const lw::core::ParsedOptions o = lw::core::ParseOptions(Table(), args);
    if (o.help()) {
      std::printf("usage: linerwatch-provision check|record|show|board %s\n%s", Table().Synopsis().c_str(),
                  Table().Help().c_str());
      return 0;
    }
    const proto::BoardInfo& board = BoardByName(o.Text("board"));
    const std::string& cmd = o.positional();
    if (cmd == "check") return Check(board, Need(o, cmd, "image"));
    if (cmd == "record") {
      if (!o.Has("sensor-id")) throw lw::core::UsageError("record needs --sensor-id");
      Need(o, cmd, "out");
      return Record(board, o);
    }
    if (cmd == "show") return Show(board, Need(o, cmd, "record"));
    if (cmd == "board") return Board(board);
    throw lw::core::UsageError("unknown command '" + cmd + "' (check, record, show or board)");
  } catch (const Refused& e) {
    std::fprintf(stderr, "linerwatch-provision: refused: %s\n", e.what());
    return 1;
  } catch (const lw::core::UsageError& e) {
    std::fprintf(stderr, "linerwatch-provision: error: %s\n", e.what());
    return 2;
  }
}
