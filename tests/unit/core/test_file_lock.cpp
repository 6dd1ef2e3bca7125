#include "core/file_lock.hpp"

#include <optional>
#include <stdexcept>
#include <string>

#include "support/temp_directory.hpp"

#include <CppUTest/TestHarness.h>  // last

using lw::core::ExclusiveFileLock;

TEST_GROUP(FileLock) {
  lw::test::TempDirectory dir{"lw-lock"};
};

TEST(FileLock, OneHolderAtATimeAndFreedWhenDestroyed) {
  const std::string path = dir.File("db");
  std::optional<ExclusiveFileLock> first;
  first.emplace(path, true, "test program");
  try {
    ExclusiveFileLock second(path, false, "test program");
    FAIL("a second lock on the same file was granted");
  } catch (const std::runtime_error& e) {
    STRCMP_EQUAL((path + " is in use by another test program").c_str(), e.what());
  }
  first.reset();
  ExclusiveFileLock again(path, false, "test program");  // free again
  CHECK_THROWS(std::runtime_error, ExclusiveFileLock(dir.File("missing"), false, "test program"));
}
