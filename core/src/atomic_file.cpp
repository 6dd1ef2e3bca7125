#include "core/atomic_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <string>

namespace lw::core {
namespace fs = std::filesystem;

namespace {

/// The temporary beside `path`: same folder (so the rename stays on one filesystem), unique per process.
fs::path TempFor(const fs::path& path) {
  fs::path tmp = path;
  tmp += ".tmp-" + std::to_string(::getpid());
  return tmp;
}

[[noreturn]] void Fail(const fs::path& path, const std::string& why, const fs::path& tmp) {
  std::error_code ec;
  fs::remove(tmp, ec);
  throw std::runtime_error("cannot write '" + path.string() + "': " + why);
}

void Sync(const fs::path& p, int flags) {
  const int fd = ::open(p.c_str(), flags | O_CLOEXEC);
  if (fd < 0) return;  // a folder that cannot be opened (permissions): the rename is still atomic
  ::fsync(fd);
  ::close(fd);
}

/// Renames the finished temporary over `path`, syncing first when asked.
void Commit(const fs::path& tmp, const fs::path& path, Durability durability) {
  if (durability == Durability::kSynced) Sync(tmp, O_RDONLY);
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) Fail(path, ec.message(), tmp);
  if (durability == Durability::kSynced) {
    const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
    Sync(dir, O_RDONLY | O_DIRECTORY);
  }
}

}  // namespace

void WriteFileAtomically(const fs::path& path, const std::function<void(std::ostream&)>& write, Durability durability) {
  const fs::path tmp = TempFor(path);
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) Fail(path, std::strerror(errno), tmp);
    try {
      write(out);
    } catch (...) {
      out.close();
      std::error_code ec;
      fs::remove(tmp, ec);
      throw;
    }
    out.flush();
    if (!out) Fail(path, "write failed (disk full?)", tmp);
  }
  Commit(tmp, path, durability);
}

void WriteFileAtomically(const fs::path& path, std::string_view text, Durability durability) {
  WriteFileAtomically(
      path, [text](std::ostream& out) { out.write(text.data(), static_cast<std::streamsize>(text.size())); }, durability);
}

void CopyFileAtomically(const fs::path& from, const fs::path& to, Durability durability) {
  const fs::path tmp = TempFor(to);
  std::error_code ec;
  fs::copy_file(from, tmp, fs::copy_options::overwrite_existing, ec);
  if (ec) Fail(to, "copy from '" + from.string() + "': " + ec.message(), tmp);
  Commit(tmp, to, durability);
}

void MakeFileAtomically(const fs::path& path, const std::function<void(const fs::path& tmp)>& fill, Durability durability) {
  const fs::path tmp = TempFor(path);
  try {
    fill(tmp);
  } catch (...) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw;
  }
  Commit(tmp, path, durability);
}

void WriteFolderAtomically(const fs::path& dir, const std::function<void(const fs::path& tmp)>& fill, const std::string& what) {
  if (fs::exists(dir) && !(fs::is_directory(dir) && fs::is_empty(dir))) {
    throw std::runtime_error(what + ": '" + dir.string() + "' exists and is not an empty directory");
  }
  const fs::path tmp = dir.string() + ".partial-" + std::to_string(::getpid());
  fs::remove_all(tmp);
  fs::create_directories(tmp);
  try {
    fill(tmp);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(tmp, ec);
    throw;
  }
  if (fs::exists(dir)) fs::remove(dir);
  fs::rename(tmp, dir);
}

}  // namespace lw::core
