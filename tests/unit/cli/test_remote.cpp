// `linerwatch reline` and `linerwatch campaigns` against the real HTTP server on loopback (a real
// SQLite file): what they record and list, and each refusal as one line with nothing recorded.
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "core/time.hpp"
#include "unit/cli/run_cli.hpp"
#include "unit/server/http_fixture.hpp"

#include <CppUTest/TestHarness.h>  // last: its leak-detection macros clash with std headers

using nlohmann::json;

namespace {
lw::test::CrusherFolder& Folder() {
  return lw::test::HttpFolder();
}

std::string Day(double days) {
  const auto t = Folder().bundle.crusher.installed_at +
                 std::chrono::duration_cast<lw::core::TimePoint::duration>(std::chrono::duration<double>(days * 86400.0));
  return lw::core::FormatIsoTime(t);
}

/// The server with tokens and the campaign's readings stored; a token file of each scope.
struct Site {
  lw::test::LiveApi api{Folder().crushers, true};
  lw::test::TempDirectory files{"lw-cli-remote"};
  std::string write_token = files.File("write.token");
  std::string read_token = files.File("read.token");
  Site() {
    LONGS_EQUAL(200, api.PostReadings(Folder(), lw::test::ServerParts::kWriteToken));
    std::ofstream(write_token) << lw::test::ServerParts::kWriteToken << "\n";
    std::ofstream(read_token) << lw::test::ServerParts::kReadToken << "\n";
  }
  std::vector<std::string> Reline(const std::string& time, const std::string& thickness, const std::string& token) const {
    std::vector<std::string> args = {"reline", "--server", api.Url(),     "--crusher", Folder().id(),
                                     "--time", time,       "--thickness", thickness};
    if (!token.empty()) args.insert(args.end(), {"--token-file", token});
    return args;
  }
  size_t CampaignCount() const {
    auto res = api.Client(lw::test::ServerParts::kReadToken).Get("/api/v1/crushers/" + Folder().id() + "/campaigns");
    CHECK(res);
    return json::parse(res->body)["campaigns"].size();
  }
};

bool OneLine(const std::string& s) {
  return !s.empty() && s.find('\n') == s.size() - 1;
}
}  // namespace

TEST_GROUP(CliRemote){};

TEST(CliRemote, RelineIsRecordedOnceAndCampaignsListIt) {
  Site site;
  const std::string scan = site.files.File("scan_end.xyz");
  std::ofstream(scan) << "0 0 1\n0.1 0 1.2\n";
  std::vector<std::string> args = site.Reline(Day(12), "135", site.write_token);
  args.insert(args.end(), {"--scan", scan});
  lw::test::CliRun r = lw::test::RunLinerwatch(args);
  LONGS_EQUAL_TEXT(0, r.code, r.err.c_str());
  CHECK_TEXT(r.out.find("reline recorded: " + Folder().id() + "'s campaign from " + Day(12) + ", 135 mm") != std::string::npos,
             r.out.c_str());
  CHECK_TEXT(r.out.find("scan kept") != std::string::npos, r.out.c_str());
  // The same time again (a client that lost the answer): nothing new.
  r = lw::test::RunLinerwatch(site.Reline(Day(12), "135", site.write_token));
  LONGS_EQUAL_TEXT(0, r.code, r.err.c_str());
  CHECK_TEXT(r.out.find("already recorded") != std::string::npos, r.out.c_str());
  LONGS_EQUAL(2, site.CampaignCount());

  // The list, with the read scope, printed and as JSON.
  const std::string out_json = site.files.File("campaigns.json");
  r = lw::test::RunLinerwatch({"campaigns", "--server", site.api.Url() + "/", "--crusher", Folder().id(), "--token-file",
                               site.read_token, "--json", out_json});
  LONGS_EQUAL_TEXT(0, r.code, r.err.c_str());
  CHECK_TEXT(r.out.find("2 campaign(s)") != std::string::npos, r.out.c_str());
  CHECK_TEXT(r.out.find("running") != std::string::npos, r.out.c_str());
  std::ifstream in(out_json);
  const json list = json::parse(in)["campaigns"];
  LONGS_EQUAL(2, list.size());
  CHECK_TRUE(list[0]["has_scan"].get<bool>());
  CHECK(list[0]["end"] == Day(12));
  DOUBLES_EQUAL(135, list[1]["thickness_new_mm"].get<double>(), 1e-9);

  // The token may come from the environment instead of a file.
  setenv("LINERWATCH_TOKEN", lw::test::ServerParts::kWriteToken, 1);
  r = lw::test::RunLinerwatch(site.Reline(Day(14), "130", ""));
  unsetenv("LINERWATCH_TOKEN");
  LONGS_EQUAL_TEXT(0, r.code, r.err.c_str());
  LONGS_EQUAL(3, site.CampaignCount());
}

TEST(CliRemote, RefusedRelinesAreOneLineAndRecordNothing) {
  Site site;
  struct Case {
    std::vector<std::string> args;
    int code;
    std::string says;
  };
  const std::string bad_scan = site.files.File("bad.xyz");
  std::ofstream(bad_scan) << "0 0 1\n0 zero 1\n";
  std::vector<std::string> with_bad_scan = site.Reline(Day(12), "135", site.write_token);
  with_bad_scan.insert(with_bad_scan.end(), {"--scan", bad_scan});
  std::vector<std::string> missing_scan = site.Reline(Day(12), "135", site.write_token);
  missing_scan.insert(missing_scan.end(), {"--scan", site.files.File("none.xyz")});
  std::vector<std::string> bad_sensors = site.Reline(Day(12), "135", site.write_token);
  const std::string sensors = site.files.File("sensors.json");
  std::ofstream(sensors) << "{\"layout\": 3}";
  bad_sensors.insert(bad_sensors.end(), {"--sensors", sensors});
  std::vector<std::string> bad_server = site.Reline(Day(12), "135", site.write_token);
  bad_server[2] = "ftp://127.0.0.1";
  std::vector<std::string> bad_crusher = site.Reline(Day(12), "135", site.write_token);
  bad_crusher[4] = "../etc";
  const std::vector<Case> cases = {
      {site.Reline(Day(12), "135", ""), 1, "(401)"},
      {site.Reline(Day(12), "135", site.read_token), 1, "(403)"},
      {site.Reline(Day(-30), "135", site.write_token), 1, "(422)"},
      {site.Reline("last tuesday", "135", site.write_token), 2, "--time: 'last tuesday'"},
      {site.Reline(Day(12), "0", site.write_token), 2, "--thickness"},
      {with_bad_scan, 1, bad_scan + ":2"},
      {missing_scan, 1, "none.xyz is not a file"},
      {bad_sensors, 1, "is not a JSON array of sensors"},
      {bad_server, 2, "--server: 'ftp://127.0.0.1'"},
      {bad_crusher, 2, "--crusher '../etc'"},
  };
  for (const Case& c : cases) {
    const lw::test::CliRun r = lw::test::RunLinerwatch(c.args);
    LONGS_EQUAL_TEXT(c.code, r.code, (c.says + " -> " + r.err).c_str());
    CHECK_TEXT(OneLine(r.err), r.err.c_str());
    CHECK_TEXT(r.err.find(c.says) != std::string::npos, (c.says + " -> " + r.err).c_str());
  }
  const lw::test::CliRun scope = lw::test::RunLinerwatch(site.Reline(Day(12), "135", site.read_token));
  CHECK_TEXT(scope.err.find("write scope") != std::string::npos, scope.err.c_str());
  LONGS_EQUAL(1, site.CampaignCount());

  // A server that is not there: named, with what was being done.
  const std::string url = site.api.Url();
  site.api.api->Stop();
  std::vector<std::string> gone = site.Reline(Day(12), "135", site.write_token);
  const lw::test::CliRun r = lw::test::RunLinerwatch(gone);
  LONGS_EQUAL_TEXT(1, r.code, r.err.c_str());
  CHECK_TEXT(r.err.find("cannot reach " + url + " to reline") != std::string::npos, r.err.c_str());
}

// `linerwatch reline --void TIME`: the reline is voided by the token's name (its write scope), the
// list shows it voided with the reason; a reader's token and a TIME with no reline are refused on one line.
TEST(CliRemote, AVoidedRelineIsListedVoidedByTheTokensName) {
  Site site;
  LONGS_EQUAL(0, lw::test::RunLinerwatch(site.Reline(Day(12), "135", site.write_token)).code);
  const std::vector<std::string> base = {"reline", "--server", site.api.Url(), "--crusher", Folder().id()};
  auto with = [&](std::vector<std::string> more) {
    std::vector<std::string> args = base;
    args.insert(args.end(), more.begin(), more.end());
    return lw::test::RunLinerwatch(args);
  };
  lw::test::CliRun r = with({"--void", Day(12), "--token-file", site.read_token});
  LONGS_EQUAL(1, r.code);
  CHECK_TEXT(OneLine(r.err) && r.err.find("write scope") != std::string::npos, r.err.c_str());
  r = with({"--void", Day(13), "--token-file", site.write_token});
  LONGS_EQUAL(1, r.code);
  CHECK_TEXT(OneLine(r.err) && r.err.find("(404)") != std::string::npos, r.err.c_str());
  r = with({"--void", "soon", "--token-file", site.write_token});
  LONGS_EQUAL(2, r.code);
  r = with({"--void", Day(12), "--reason", "wrong day", "--token-file", site.write_token});
  LONGS_EQUAL_TEXT(0, r.code, r.err.c_str());
  CHECK_TEXT(r.out.find("reline voided: " + Folder().id() + "'s campaign from " + Day(12) + " (135 mm) voided by writer") !=
                 std::string::npos,
             r.out.c_str());
  r = lw::test::RunLinerwatch(
      {"campaigns", "--server", site.api.Url(), "--crusher", Folder().id(), "--token-file", site.read_token});
  LONGS_EQUAL_TEXT(0, r.code, r.err.c_str());
  CHECK_TEXT(r.out.find("voided") != std::string::npos && r.out.find("wrong day") != std::string::npos, r.out.c_str());
  LONGS_EQUAL(2, site.CampaignCount());
}

// `linerwatch setting-check`: the measured CSS is recorded by the token's name (its write scope)
// with the opening the server estimated then, once; --list shows it; refusals are one line.
TEST(CliRemote, AMeasuredSettingIsRecordedOnceAndListed) {
  Site site;
  const std::vector<std::string> base = {"setting-check", "--server", site.api.Url(), "--crusher", Folder().id()};
  auto with = [&](std::vector<std::string> more) {
    std::vector<std::string> args = base;
    args.insert(args.end(), more.begin(), more.end());
    return lw::test::RunLinerwatch(args);
  };
  lw::test::CliRun r = with({"--time", Day(20), "--css", "131.5", "--note", "mantle raised", "--token-file", site.write_token});
  LONGS_EQUAL_TEXT(0, r.code, r.err.c_str());
  CHECK_TEXT(r.out.find("setting recorded: " + Folder().id() + " measured 131.5 mm at " + Day(20) +
                        "; the concave's opening then ") != std::string::npos,
             r.out.c_str());
  CHECK_TEXT(r.out.find(" mm; the CSS counts from it") != std::string::npos, r.out.c_str());  // readings stored: a number
  r = with({"--time", Day(20), "--css", "131.5", "--token-file", site.write_token});
  LONGS_EQUAL_TEXT(0, r.code, r.err.c_str());
  CHECK_TEXT(r.out.find("already recorded") != std::string::npos, r.out.c_str());
  struct Case {
    std::vector<std::string> args;
    int code;
    std::string says;
  };
  const std::vector<Case> cases = {
      {{"--time", Day(21), "--css", "130", "--token-file", site.read_token}, 1, "write scope"},
      {{"--time", Day(20), "--css", "140", "--token-file", site.write_token}, 1, "(409)"},
      {{"--time", Day(-30), "--css", "130", "--token-file", site.write_token}, 1, "(422)"},
      {{"--time", Day(21), "--css", "0", "--token-file", site.write_token}, 2, "--css"},
      {{"--time", "soon", "--css", "130", "--token-file", site.write_token}, 2, "--time: 'soon'"},
      {{"--css", "130", "--token-file", site.write_token}, 2, "--time and --css are required"},
      {{"--list", "--css", "130", "--token-file", site.read_token}, 2, "--list takes no"},
  };
  for (const Case& c : cases) {
    const lw::test::CliRun bad = with(c.args);
    LONGS_EQUAL_TEXT(c.code, bad.code, (c.says + " -> " + bad.err).c_str());
    CHECK_TEXT(OneLine(bad.err), bad.err.c_str());
    CHECK_TEXT(bad.err.find(c.says) != std::string::npos, (c.says + " -> " + bad.err).c_str());
  }
  r = with({"--list", "--token-file", site.read_token});
  LONGS_EQUAL_TEXT(0, r.code, r.err.c_str());
  CHECK_TEXT(r.out.find("1 measured setting(s)") != std::string::npos, r.out.c_str());
  CHECK_TEXT(r.out.find(Day(20)) != std::string::npos && r.out.find("131.5") != std::string::npos &&
                 r.out.find("yes  writer: mantle raised") != std::string::npos,
             r.out.c_str());
}
