#pragma once
// `linerwatch-sim run`: the virtual site against a real gateway through a pty (docs/sim.md).
#include <string>
#include <vector>

namespace lw::sim {

/// Runs the subcommand; returns the process exit code (0 done or stopped by a signal, 2 bad
/// input, 1 failure). Errors go to stderr as one line.
int RunCommand(const std::vector<std::string>& args);

}  // namespace lw::sim
