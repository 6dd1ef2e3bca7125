// linerwatch-backup: docs/deploy.md, *Backup and restore*; run daily by linerwatch-backup.timer.
#include <chrono>
#include <iostream>

#include "server/backup.hpp"

int main(int argc, char** argv) {
  lw::server::BackupOptions options;
  try {
    options = lw::server::ParseBackupOptions(std::vector<std::string>(argv + 1, argv + argc));
  } catch (const std::exception& e) {
    std::cerr << "linerwatch-backup: " << e.what() << "\n";
    return 2;
  }
  if (options.help) {
    std::cout << lw::server::BackupHelp();
    return 0;
  }
  try {
    const auto now = std::chrono::floor<std::chrono::seconds>(std::chrono::system_clock::now());
    const lw::server::BackupResult r = lw::server::TakeBackup(options, now);
    std::cout << "linerwatch-backup: " << r.file.string() << " (" << r.bytes << " bytes, integrity ok)";
    if (!r.removed.empty()) {
      std::cout << "; deleted " << r.removed.size() << " older:";
      for (const auto& p : r.removed) std::cout << " " << p.filename().string();
    }
    std::cout << "\n";
  } catch (const std::exception& e) {
    std::cerr << "linerwatch-backup: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
