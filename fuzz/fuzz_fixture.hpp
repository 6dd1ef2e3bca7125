#pragma once
// The fixture crusher of the targets that need a server registry (fuzz/data/crusher).
#include <filesystem>
#include <memory>

#include "fuzz_support.hpp"
#include "server/registry.hpp"

namespace lw::fuzz {

/// The fixture crusher "fz1" (sensors 1001, 1002, 1003; installed 2026-01-01), loaded once.
inline const server::Registry& FixtureRegistry() {
  static const std::unique_ptr<server::Registry> registry = [] {
    auto r = std::make_unique<server::Registry>();
    r->Add(server::Registry::LoadCrusher(std::filesystem::path(LW_FUZZ_DATA_DIR) / "crusher"));
    return r;
  }();
  return *registry;
}

}  // namespace lw::fuzz
