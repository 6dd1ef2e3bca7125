#pragma once
// Runs the `linerwatch` CLI through its library entry point and keeps what it printed.
#include <sstream>
#include <string>
#include <vector>

#include "cli/cli.hpp"

namespace lw::test {

struct CliRun {
  int code = 0;
  std::string out, err;
};

inline CliRun RunLinerwatch(const std::vector<std::string>& args) {
  std::ostringstream out, err;
  CliRun r;
  r.code = lw::cli::RunCli(args, out, err);
  r.out = out.str();
  r.err = err.str();
  return r;
}

}  // namespace lw::test
