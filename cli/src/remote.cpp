#include "remote.hpp"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "core/atomic_file.hpp"
#include "core/bundle.hpp"
#include "core/cmdline.hpp"
#include "core/time.hpp"

// After nlohmann: <resolv.h> (via httplib) defines macros that clash with common names.
#include <httplib.h>

namespace lw::cli {
namespace {

namespace fs = std::filesystem;
using core::Option;
using nlohmann::json;

// The server's request body limit for a reline (server/rest.hpp kMaxRelineBodyBytes): a larger scan
// is refused here, before anything is sent.
constexpr uintmax_t kMaxScanBytes = 16u << 20;
constexpr size_t kMaxBodyBytes = 16u << 20;

Option ServerOption() {
  return Option::Text("server", "URL", "the linerwatch-server, e.g. http://127.0.0.1:8080 (https:// too)").Required();
}
Option CrusherOption() {
  return Option::Text("crusher", "ID", "the crusher (its crusher.json crusher_id)").Required();
}
Option TokenOption() {
  return Option::Text("token-file", "FILE",
                      "bearer token (its first line) for a server run with --tokens;\n"
                      "default: the LINERWATCH_TOKEN environment variable");
}

const core::OptionTable& RelineTable() {
  static const core::OptionTable table({
      ServerOption(),
      CrusherOption(),
      Option::Text("time", "TIME", "when the old liner came out and the new one went in").Required(),
      Option::Number("thickness", "MM", core::NumberRange{0, core::kMaxThicknessMm, true, false},
                     "the new liner's thickness (mm)")
          .Required(),
      Option::Text("scan", "FILE.xyz", "the old liner's end-of-life laser scan (x y z metres per line)"),
      Option::Text("sensors", "FILE.json",
                   "the new liner's sensors: a JSON array of crusher.json sensor objects\n"
                   "(or {\"sensors\": [...]}); default: the same boards"),
      TokenOption(),
  });
  return table;
}

const core::OptionTable& VoidTable() {
  static const core::OptionTable table({
      ServerOption(),
      CrusherOption(),
      Option::Text("void", "TIME", "the reline to void: its time, as `linerwatch campaigns` lists it").Required(),
      Option::Text("reason", "TEXT", "why (kept with the voided campaign)"),
      TokenOption(),
  });
  return table;
}

const core::OptionTable& CampaignsTable() {
  static const core::OptionTable table({
      ServerOption(),
      CrusherOption(),
      TokenOption(),
      Option::Text("json", "OUT.json", "the server's answer as JSON"),
  });
  return table;
}

const core::OptionTable& SettingCheckTable() {
  static const core::OptionTable table({
      ServerOption(),
      CrusherOption(),
      Option::Text("time", "TIME", "when the closed-side setting was measured (with --css)"),
      Option::Number("css", "MM", core::NumberRange{0, 1000, true, false}, "the closed-side setting measured (mm)"),
      Option::Text("note", "TEXT", "kept with the check (e.g. \"mantle raised 12 mm\")"),
      Option::Switch("list", "list the crusher's measured settings instead"),
      TokenOption(),
  });
  return table;
}

/// A file's whole text; BadInput-style runtime_error naming the option and the file.
std::string ReadFile(const std::string& path, const std::string& option, uintmax_t max_bytes) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw std::runtime_error("--" + option + ": " + path + " is not a file");
  if (fs::file_size(path, ec) > max_bytes)
    throw std::runtime_error("--" + option + ": " + path + " is larger than " + std::to_string(max_bytes >> 20) + " MiB");
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  if (!in) throw std::runtime_error("--" + option + ": cannot read " + path);
  return text.str();
}

/// The token: --token-file's first line, else $LINERWATCH_TOKEN, else none. Tokens never go on the
/// command line, where every user of the machine can read them.
std::string TokenOf(const core::ParsedOptions& o) {
  std::string token;
  if (o.Has("token-file")) {
    std::istringstream lines(ReadFile(o.Text("token-file"), "token-file", 64 << 10));
    std::getline(lines, token);
    while (!token.empty() && (token.back() == '\r' || token.back() == ' ' || token.back() == '\t')) token.pop_back();
    if (token.empty()) throw std::runtime_error("--token-file: " + o.Text("token-file") + " has no token on its first line");
  } else if (const char* env = std::getenv("LINERWATCH_TOKEN")) {
    token = env;
  }
  return token;
}

/// A client for --server; the URL is checked here so a typo is a usage error, not a network one.
struct Server {
  std::string url;
  std::unique_ptr<httplib::Client> client;

  Server(const core::ParsedOptions& o) : url(o.Text("server")) {
    while (!url.empty() && url.back() == '/') url.pop_back();
    const bool http = url.rfind("http://", 0) == 0, https = url.rfind("https://", 0) == 0;
    const size_t host = http ? 7 : 8;
    const size_t colon = url.find(':', host);
    const bool port_ok = colon == std::string::npos ||
                         (colon + 1 < url.size() && url.find_first_not_of("0123456789", colon + 1) == std::string::npos);
    if ((!http && !https) || url.size() <= host || url.find('/', host) != std::string::npos || !port_ok)
      throw core::UsageError("--server: '" + o.Text("server") + "' is not http://HOST[:PORT] or https://HOST[:PORT]");
    client = std::make_unique<httplib::Client>(url);
    client->set_connection_timeout(10, 0);
    client->set_read_timeout(120, 0);  // a reline re-applies the live wear before it answers
    if (const std::string token = TokenOf(o); !token.empty()) client->set_bearer_token_auth(token);
  }

  /// The answer, or a runtime_error naming the server and what went wrong.
  httplib::Result Check(httplib::Result res, const std::string& what) const {
    if (!res) throw std::runtime_error("cannot reach " + url + " to " + what + ": " + httplib::to_string(res.error()));
    return res;
  }
};

/// The crusher's path segment: crusher.json's identifier rule, so nothing else reaches the URL.
std::string CrusherPath(const core::ParsedOptions& o) {
  const std::string id = o.Text("crusher");
  try {
    core::CheckIdentifier(id, "--crusher", "command line");
  } catch (const core::InputError& e) {
    throw core::UsageError(e.rule());
  }
  return "/api/v1/crushers/" + id;
}

/// The server's refusal as one line: its status, its `error`, and what to do about a missing scope.
[[noreturn]] void Refused(const httplib::Response& r, const std::string& what, const std::string& scan_path) {
  std::string error = r.body;
  const json j = json::parse(r.body, nullptr, false);
  if (j.is_object() && j.contains("error") && j["error"].is_string()) error = j["error"].get<std::string>();
  // The server names scan lines as scan_xyz:LINE; the user knows the file.
  if (!scan_path.empty() && error.rfind("scan_xyz:", 0) == 0) error = scan_path + error.substr(8);
  std::string hint;
  if (r.status == 401 || r.status == 403)
    hint = " (needs a token with the " +
           std::string(what == "reline" || what == "void" || what == "setting check" ? "write" : "read") +
           " scope: --token-file FILE or LINERWATCH_TOKEN)";
  throw std::runtime_error("the server refused the " + what + " (" + std::to_string(r.status) + "): " + error + hint);
}

std::string Mm(const json& v) {
  if (!v.is_number()) return "?";
  std::ostringstream s;
  s << v.get<double>();
  return s.str();
}

std::string Days(const json& v) {
  if (!v.is_number()) return "-";
  std::ostringstream s;
  s << std::fixed << std::setprecision(1) << v.get<double>();
  return s.str();
}

/// `linerwatch reline --void TIME`: POST .../relines/{TIME}/void (docs/campaigns.md, *Voiding a reline*).
int VoidReline(const std::vector<std::string>& args, std::ostream& out) {
  const core::ParsedOptions o = core::ParseOptions(VoidTable(), std::vector<std::string>(args.begin() + 1, args.end()));
  const auto t = core::ParseIsoTime(o.Text("void"));
  if (!t) throw core::UsageError("--void: '" + o.Text("void") + "' is not an ISO-8601 time (YYYY-MM-DD[THH:MM:SSZ])");
  json body = json::object();
  if (o.Has("reason")) body["reason"] = o.Text("reason");
  const std::string path = CrusherPath(o) + "/relines/" + core::FormatIsoTime(*t) + "/void";
  Server server(o);
  const httplib::Result res = server.Check(server.client->Post(path, body.dump(), "application/json"), "void the reline");
  if (res->status != 200) Refused(*res, "void", "");
  const json c = json::parse(res->body, nullptr, false);
  if (!c.is_object()) throw std::runtime_error("the server's answer to the void is not JSON: " + res->body.substr(0, 200));
  out << "reline voided: " << o.Text("crusher") << "'s campaign from " << c.value("start", "?") << " ("
      << Mm(c.value("thickness_new_mm", json())) << " mm) voided by " << c.value("voided_by", "?") << " at "
      << c.value("voided_at", "?") << "; the campaign before it runs again\n";
  return 0;
}

/// A list answer `{"KEY": [...]}` (`what` names it in the error); throws when it is not one.
json ListAnswer(const httplib::Response& r, const std::string& key, const std::string& what) {
  json j = json::parse(r.body, nullptr, false);
  if (!j.is_object() || !j.contains(key) || !j[key].is_array())
    throw std::runtime_error("the server's " + what + " is not {\"" + key + "\": [...]}: " + r.body.substr(0, 200));
  return j;
}

}  // namespace

int Reline(const std::vector<std::string>& args, std::ostream& out) {
  for (size_t k = 1; k < args.size(); ++k)
    if (args[k] == "--void" || args[k].rfind("--void=", 0) == 0) return VoidReline(args, out);
  const core::ParsedOptions o = core::ParseOptions(RelineTable(), std::vector<std::string>(args.begin() + 1, args.end()));
  const std::string time = o.Text("time");
  const auto t = core::ParseIsoTime(time);
  if (!t) throw core::UsageError("--time: '" + time + "' is not an ISO-8601 time (YYYY-MM-DD[THH:MM:SSZ])");
  json body = {{"time", core::FormatIsoTime(*t)}, {"thickness_new_mm", o.Number("thickness", 0)}};
  std::string scan_path;
  if (o.Has("scan")) {
    scan_path = o.Text("scan");
    body["scan_xyz"] = ReadFile(scan_path, "scan", kMaxScanBytes);
  }
  if (o.Has("sensors")) {
    const std::string path = o.Text("sensors");
    json s = json::parse(ReadFile(path, "sensors", 1 << 20), nullptr, false);
    if (s.is_object() && s.contains("sensors")) s = s["sensors"];
    if (!s.is_array())
      throw std::runtime_error("--sensors: " + path + " is not a JSON array of sensors (or {\"sensors\": [...]})");
    body["sensors"] = std::move(s);
  }
  const std::string path = CrusherPath(o);
  Server server(o);
  const std::string text = body.dump();
  if (text.size() > kMaxBodyBytes)
    throw std::runtime_error("--scan: " + scan_path + " makes a request of " + std::to_string(text.size() >> 20) +
                             " MiB, over the server's 16 MiB for a reline (thin the scan's points)");
  const httplib::Result res = server.Check(server.client->Post(path + "/relines", text, "application/json"), "reline");
  if (res->status != 200 && res->status != 201) Refused(*res, "reline", scan_path);
  const json c = json::parse(res->body, nullptr, false);
  if (!c.is_object()) throw std::runtime_error("the server's answer to the reline is not JSON: " + res->body.substr(0, 200));
  out << (res->status == 201 ? "reline recorded: " : "reline already recorded at this time (nothing changed): ")
      << o.Text("crusher") << "'s campaign from " << c.value("start", "?") << ", " << Mm(c.value("thickness_new_mm", json()))
      << " mm, " << c.value("sensor_count", 0) << " sensors; the old liner's scan " << (o.Has("scan") ? "kept" : "not given")
      << "\n";
  return 0;
}

int Campaigns(const std::vector<std::string>& args, std::ostream& out) {
  const core::ParsedOptions o = core::ParseOptions(CampaignsTable(), std::vector<std::string>(args.begin() + 1, args.end()));
  if (o.Has("json")) {
    const fs::path p(o.Text("json"));
    std::error_code ec;
    if (p.has_parent_path() && !fs::is_directory(p.parent_path(), ec))
      throw std::runtime_error("--json: directory " + p.parent_path().string() + " does not exist");
  }
  const std::string path = CrusherPath(o);
  Server server(o);
  const httplib::Result res = server.Check(server.client->Get(path + "/campaigns"), "list the campaigns");
  if (res->status != 200) Refused(*res, "campaign list", "");
  const json j = ListAnswer(*res, "campaigns", "campaign list");
  if (o.Has("json")) core::WriteFileAtomically(o.Text("json"), j.dump(2) + "\n");
  out << o.Text("crusher") << ": " << j["campaigns"].size() << " campaign(s), oldest first\n";
  out << "  start                 end                   life (d)  new (mm)  sensors  end-of-life scan\n";
  for (const json& c : j["campaigns"]) {
    const std::string end = c.value("voided", false)    ? "voided"
                            : c.value("running", false) ? "running"
                                                        : (c["end"].is_string() ? c["end"].get<std::string>() : "-");
    out << "  " << std::left << std::setw(22) << c.value("start", "?") << std::setw(22) << end << std::right << std::setw(8)
        << Days(c.value("life_days", json())) << std::setw(10) << Mm(c.value("thickness_new_mm", json())) << std::setw(9)
        << c.value("sensor_count", 0) << "  " << (c.value("has_scan", false) ? "yes" : "no");
    if (c.value("voided", false)) {
      const std::string reason = c.value("void_reason", "");
      out << "  (voided by " << c.value("voided_by", "?") << " at " << c.value("voided_at", "?")
          << (reason.empty() ? "" : ": " + reason) << ")";
    }
    out << "\n";
  }
  return 0;
}

namespace {

/// `linerwatch setting-check --list`: GET .../setting/checks, one line per check.
int SettingCheckList(const core::ParsedOptions& o, std::ostream& out) {
  const std::string path = CrusherPath(o);
  Server server(o);
  const httplib::Result res = server.Check(server.client->Get(path + "/setting/checks"), "list the setting checks");
  if (res->status != 200) Refused(*res, "setting check list", "");
  const json j = ListAnswer(*res, "checks", "setting check list");
  out << o.Text("crusher") << ": " << j["checks"].size() << " measured setting(s), oldest first\n";
  out << "  time                  css (mm)  opening then (mm)  counts  by\n";
  for (const json& c : j["checks"]) {
    std::string opening = c["opening_mm"].is_number() ? Mm(c["opening_mm"]) : "not known";
    if (c["opening_mm"].is_number() && !c.value("opening_supported", true)) opening += " (rough)";
    out << "  " << std::left << std::setw(22) << c.value("time", "?") << std::right << std::setw(8)
        << Mm(c.value("css_mm", json())) << std::setw(19) << opening << std::setw(8)
        << (!c.contains("counts")      ? "-"
            : c.value("counts", false) ? "yes"
                                       : "no")
        << "  " << c.value("by", "?");
    const std::string note = c.value("note", "");
    out << (note.empty() ? "" : ": " + note) << "\n";
  }
  return 0;
}

}  // namespace

int SettingCheck(const std::vector<std::string>& args, std::ostream& out) {
  const core::ParsedOptions o = core::ParseOptions(SettingCheckTable(), std::vector<std::string>(args.begin() + 1, args.end()));
  if (o.Has("list")) {
    if (o.Has("time") || o.Has("css") || o.Has("note")) throw core::UsageError("--list takes no --time, --css or --note");
    return SettingCheckList(o, out);
  }
  if (!o.Has("time") || !o.Has("css")) throw core::UsageError("--time and --css are required (or --list)");
  const auto t = core::ParseIsoTime(o.Text("time"));
  if (!t) throw core::UsageError("--time: '" + o.Text("time") + "' is not an ISO-8601 time (YYYY-MM-DD[THH:MM:SSZ])");
  json body = {{"time", core::FormatIsoTime(*t)}, {"css_mm", o.Number("css", 0)}};
  if (o.Has("note")) body["note"] = o.Text("note");
  const std::string path = CrusherPath(o);
  Server server(o);
  const httplib::Result res =
      server.Check(server.client->Post(path + "/setting/checks", body.dump(), "application/json"), "record the setting");
  if (res->status != 200 && res->status != 201) Refused(*res, "setting check", "");
  const json c = json::parse(res->body, nullptr, false);
  if (!c.is_object())
    throw std::runtime_error("the server's answer to the setting check is not JSON: " + res->body.substr(0, 200));
  out << (res->status == 201 ? "setting recorded: " : "setting already recorded at this time (nothing changed): ")
      << o.Text("crusher") << " measured " << Mm(c.value("css_mm", json())) << " mm at " << c.value("time", "?")
      << "; the concave's opening then "
      << (c["opening_mm"].is_number()
              ? Mm(c["opening_mm"]) + " mm" + (c.value("opening_supported", true) ? "" : " (a rough estimate)") +
                    "; the CSS counts from it"
              : std::string("not known (no reading up to then, or no sensor sets a scale): no CSS until it is"))
      << "\n";
  return 0;
}

std::string RemoteUsage(size_t column, size_t indent) {
  return "  reline " + RelineTable().Synopsis(9, 100) +
         "\n"
         "      Record a reline on the server (its write scope): the old liner's campaign ends at TIME with\n"
         "      its last readings and, with --scan, its end-of-life scan; the next starts with MM and, with\n"
         "      --sensors, a new sensor layout. Live wear switches at once. Posting the same TIME again\n"
         "      changes nothing (docs/campaigns.md).\n" +
         RelineTable().Help(column, indent, false) + "  reline " + VoidTable().Synopsis(9, 100) +
         "\n"
         "      Void a reline posted by mistake (wrong time or thickness, or none happened): its campaign is\n"
         "      kept, marked voided by the token's name, and the campaign it closed runs again.\n" +
         VoidTable().Help(column, indent, false) + "  campaigns " + CampaignsTable().Synopsis(12, 100) +
         "\n"
         "      List the crusher's liner campaigns on the server: start, end, life, thickness, sensors,\n"
         "      whether the end-of-life scan is kept.\n" +
         CampaignsTable().Help(column, indent, false) + "  setting-check " + SettingCheckTable().Synopsis(16, 100) +
         "\n"
         "      Record the closed-side setting measured on the crusher (after raising the mantle, say; the\n"
         "      write scope): the CSS is counted from it, and the setting_open alarm restarts its count;\n"
         "      --list prints the checks recorded (docs/wear.md, *Setting*).\n" +
         SettingCheckTable().Help(column, indent, false);
}

}  // namespace lw::cli
