#pragma once
// The one scratch-directory helper of the tests: a fresh directory under $TMPDIR (or /tmp), removed
// with everything in it when the test ends.
//
//   lw::test::TempDirectory dir("lw-spool");
//   Spool spool(dir.File("spool.sqlite"));            // a path inside it, as a string
//   const auto map = dir.Write("maps/m.csv", text);   // a file written there (folders made)
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace lw::test {

class TempDirectory {
 public:
  explicit TempDirectory(const std::string& prefix = "lw-test") {
    const char* tmp = std::getenv("TMPDIR");
    const std::string tmpl = std::string(tmp && *tmp ? tmp : "/tmp") + "/" + prefix + "-XXXXXX";
    std::vector<char> buf(tmpl.begin(), tmpl.end());
    buf.push_back('\0');
    if (!::mkdtemp(buf.data())) throw std::runtime_error("mkdtemp " + tmpl + " failed");
    path_ = buf.data();
  }
  ~TempDirectory() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDirectory(const TempDirectory&) = delete;
  TempDirectory& operator=(const TempDirectory&) = delete;

  const std::filesystem::path& path() const { return path_; }
  /// The path of `name` inside the directory (not created).
  std::string File(const std::string& name) const { return (path_ / name).string(); }
  /// Writes `text` to `name` inside the directory (making folders) and returns its path.
  std::filesystem::path Write(const std::string& name, const std::string& text) const {
    const auto p = path_ / name;
    std::filesystem::create_directories(p.parent_path());
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }

 private:
  std::filesystem::path path_;
};

}  // namespace lw::test
