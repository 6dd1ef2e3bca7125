#pragma once
/// The `linerwatch` user CLI as a library, so tests drive it without spawning processes.
#include <ostream>
#include <string>
#include <vector>

namespace lw::cli {

/// Runs `linerwatch` with `args` (without the program name). Returns the process exit code:
/// 0 success (a diagnosis that ran, whatever it found), 1 bad input (one-line reason on `err`),
/// 2 usage error. Never leaves partial output files behind.
int RunCli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

}  // namespace lw::cli
