#pragma once
/// The commands that talk to a linerwatch-server over its REST API (docs/campaigns.md): `reline`
/// and `campaigns`. Errors are core::UsageError (exit 2) or std::runtime_error (exit 1), one line.
#include <cstddef>
#include <ostream>
#include <string>
#include <vector>

namespace lw::cli {

/// `linerwatch reline ...` (args[0] is "reline"): POST .../relines, prints what the server recorded.
int Reline(const std::vector<std::string>& args, std::ostream& out);
/// `linerwatch campaigns ...`: GET .../campaigns, prints one line per campaign (and --json OUT).
int Campaigns(const std::vector<std::string>& args, std::ostream& out);
/// `linerwatch setting-check ...`: POST .../setting/checks (or with --list, GET), prints what the server recorded.
int SettingCheck(const std::vector<std::string>& args, std::ostream& out);
/// Their part of `linerwatch --help`, option text at `column`, flags `indent` spaces in.
std::string RemoteUsage(size_t column, size_t indent);

}  // namespace lw::cli
