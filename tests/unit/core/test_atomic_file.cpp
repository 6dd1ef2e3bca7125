// core::WriteFileAtomically / CopyFileAtomically: the target holds the old content or the new,
// never a part; a failure names the path and leaves no temporary behind.
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "core/atomic_file.hpp"
#include "support/temp_directory.hpp"

#include <CppUTest/TestHarness.h>  // last

using lw::core::CopyFileAtomically;
using lw::core::Durability;
using lw::core::MakeFileAtomically;
using lw::core::WriteFileAtomically;
namespace fs = std::filesystem;

namespace {
std::string Read(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}
size_t Entries(const fs::path& dir) {
  return static_cast<size_t>(std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
}
}  // namespace

TEST_GROUP(AtomicFile){};

TEST(AtomicFile, WritesAndReplacesLeavingOnlyTheTarget) {
  lw::test::TempDirectory dir;
  const fs::path p = dir.path() / "out.txt";
  WriteFileAtomically(p, std::string("first\n"));
  STRCMP_EQUAL("first\n", Read(p).c_str());
  WriteFileAtomically(p, std::string("second, longer\n"), Durability::kAtomic);
  STRCMP_EQUAL("second, longer\n", Read(p).c_str());
  WriteFileAtomically(p, [](std::ostream& out) { out << "streamed " << 42 << '\n'; });
  STRCMP_EQUAL("streamed 42\n", Read(p).c_str());
  LONGS_EQUAL(1, Entries(dir.path()));
}

TEST(AtomicFile, AWriterThatThrowsLeavesTheOldContentAndNoTemporary) {
  lw::test::TempDirectory dir;
  const fs::path p = dir.path() / "out.txt";
  WriteFileAtomically(p, std::string("kept\n"));
  CHECK_THROWS(std::logic_error, WriteFileAtomically(p, [](std::ostream& out) {
                 out << "half of it";
                 throw std::logic_error("the producer failed");
               }));
  STRCMP_EQUAL("kept\n", Read(p).c_str());
  LONGS_EQUAL(1, Entries(dir.path()));
}

TEST(AtomicFile, AnUnwritablePlaceIsAnErrorNamingThePath) {
  lw::test::TempDirectory dir;
  const fs::path p = dir.path() / "no-such-folder" / "out.txt";
  try {
    WriteFileAtomically(p, std::string("x"));
    FAIL("expected an error");
  } catch (const std::runtime_error& e) {
    CHECK_TRUE(std::string(e.what()).find(p.string()) != std::string::npos);
  }
  // Renaming over a folder fails after the temporary was written: it is removed, the folder kept.
  const fs::path folder = dir.path() / "a-folder";
  fs::create_directories(folder / "inside");
  CHECK_THROWS(std::runtime_error, WriteFileAtomically(folder, std::string("x")));
  CHECK_TRUE(fs::is_directory(folder / "inside"));
  LONGS_EQUAL(1, Entries(dir.path()));
}

TEST(AtomicFile, CopyReplacesTheTargetWhole) {
  lw::test::TempDirectory dir;
  const fs::path from = dir.Write("from.txt", "new content\n");
  const fs::path to = dir.Write("to.txt", "old\n");
  CopyFileAtomically(from, to);
  STRCMP_EQUAL("new content\n", Read(to).c_str());
  CHECK_THROWS(std::runtime_error, CopyFileAtomically(dir.path() / "missing.txt", to));
  STRCMP_EQUAL("new content\n", Read(to).c_str());
  LONGS_EQUAL(2, Entries(dir.path()));
}

TEST(AtomicFile, MakeRenamesWhatTheFillerWroteAndRemovesItOnFailure) {
  lw::test::TempDirectory dir;
  const fs::path to = dir.Write("made.db", "old\n");
  fs::path seen;
  MakeFileAtomically(to, [&](const fs::path& tmp) {
    seen = tmp;
    CHECK_FALSE(fs::exists(tmp));  // the filler creates it (SQLite opens a file name)
    std::ofstream(tmp, std::ios::binary) << "made by another writer\n";
  });
  STRCMP_EQUAL("made by another writer\n", Read(to).c_str());
  CHECK_TRUE(seen.parent_path() == to.parent_path());  // beside it: the rename stays on one filesystem
  CHECK_THROWS(std::logic_error, MakeFileAtomically(to, [](const fs::path& tmp) {
                 std::ofstream(tmp, std::ios::binary) << "half";
                 throw std::logic_error("the check of the copy failed");
               }));
  STRCMP_EQUAL("made by another writer\n", Read(to).c_str());
  LONGS_EQUAL(1, Entries(dir.path()));
}
