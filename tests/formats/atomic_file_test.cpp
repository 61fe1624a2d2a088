// SPDX-License-Identifier: Apache-2.0
#include "formats/atomic_file.hpp"

#include <csignal>
#include <cstring>
#include <system_error>

#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include "tests/formats/test_support.hpp"

namespace cylscan::formats {
namespace {

namespace fs = std::filesystem;

using testing::entriesOf;
using testing::readText;
using testing::writeText;

class AtomicFileTest : public testing::TempDirTest {};

// Runs f, expecting a std::system_error whose message names `path`.
template <class F>
::testing::AssertionResult failsNaming(F&& f, const fs::path& path) {
  try {
    f();
  } catch (const std::system_error& e) {
    if (std::string(e.what()).find(path.string()) == std::string::npos) {
      return ::testing::AssertionFailure() << "message does not name " << path << ": " << e.what();
    }
    return ::testing::AssertionSuccess() << e.what();
  }
  return ::testing::AssertionFailure() << "did not throw std::system_error";
}

TEST_F(AtomicFileTest, WritesANewFile) {
  const fs::path file = dir_ / "a.txt";
  writeFileAtomically(file, std::string_view("hello\n"));
  EXPECT_EQ(readText(file), "hello\n");
  EXPECT_EQ(entriesOf(dir_), std::vector<std::string>{"a.txt"});
}

TEST_F(AtomicFileTest, WritesBytesIncludingZeros) {
  const fs::path file = dir_ / "b.bin";
  const std::vector<std::byte> data{std::byte{0}, std::byte{0xFF}, std::byte{0}, std::byte{7}};
  writeFileAtomically(file, data);
  EXPECT_EQ(readText(file), std::string("\0\xFF\0\x07", 4));
}

TEST_F(AtomicFileTest, ReplacesAnExistingFileWhole) {
  const fs::path file = dir_ / "a.txt";
  writeText(file, std::string(10000, 'x'));
  writeFileAtomically(file, std::string_view("short"));
  EXPECT_EQ(readText(file), "short");
  EXPECT_EQ(entriesOf(dir_), std::vector<std::string>{"a.txt"});
}

TEST_F(AtomicFileTest, KeepsThePermissionsOfTheReplacedFile) {
  const fs::path file = dir_ / "a.txt";
  writeText(file, "old");
  fs::permissions(file, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
  writeFileAtomically(file, std::string_view("new"));
  EXPECT_EQ(fs::status(file).permissions(),
            fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
}

TEST_F(AtomicFileTest, NewFilesAreNotPrivateTemporaries) {
  const fs::path file = dir_ / "a.txt";
  writeFileAtomically(file, std::string_view("x"));
  // mkstemp creates 0600; the written file follows the umask like any other.
  const mode_t mask = ::umask(022);
  ::umask(mask);
  EXPECT_EQ(static_cast<mode_t>(fs::status(file).permissions()), 0666 & ~mask);
}

TEST_F(AtomicFileTest, MissingDirectoryFailsNamingThePath) {
  const fs::path file = dir_ / "missing" / "a.txt";
  EXPECT_TRUE(failsNaming([&] { writeFileAtomically(file, std::string_view("x")); }, file));
  EXPECT_FALSE(fs::exists(dir_ / "missing"));
  EXPECT_TRUE(entriesOf(dir_).empty());
}

TEST_F(AtomicFileTest, TargetThatIsADirectorySurvivesAndNoTemporaryIsLeft) {
  const fs::path target = dir_ / "taken";
  fs::create_directories(target / "inside");
  EXPECT_TRUE(failsNaming([&] { writeFileAtomically(target, std::string_view("x")); }, target));
  EXPECT_TRUE(fs::is_directory(target / "inside"));
  EXPECT_EQ(entriesOf(dir_), std::vector<std::string>{"taken"});
}

TEST_F(AtomicFileTest, FailureWhileWritingKeepsTheOldFile) {
  const fs::path file = dir_ / "a.txt";
  writeText(file, "old content");
  // A file size limit makes write(2) fail part-way, as a full disk would.
  struct rlimit old_limit {};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old_limit), 0);
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  struct rlimit limit = old_limit;
  limit.rlim_cur = 1024;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &limit), 0);
  const std::string big(100000, 'n');
  const auto result = failsNaming([&] { writeFileAtomically(file, big); }, file);
  ::setrlimit(RLIMIT_FSIZE, &old_limit);
  std::signal(SIGXFSZ, old_handler);
  EXPECT_TRUE(result);
  EXPECT_EQ(readText(file), "old content");
  EXPECT_EQ(entriesOf(dir_), std::vector<std::string>{"a.txt"});
}

TEST_F(AtomicFileTest, FailedRenameKeepsTheOldTargetAndLeavesNoTemporary) {
  // The rename step fails (even for root) when the target is a non-empty
  // directory: the data was already written to the temporary by then.
  const fs::path target = dir_ / "a.txt";
  fs::create_directories(target);
  writeText(target / "inside.txt", "old content");
  const auto result =
      failsNaming([&] { writeFileAtomically(target, std::string_view("new")); }, target);
  EXPECT_TRUE(result);
  EXPECT_TRUE(fs::is_directory(target));
  EXPECT_EQ(readText(target / "inside.txt"), "old content");
  EXPECT_EQ(entriesOf(dir_), std::vector<std::string>{"a.txt"});
}

TEST_F(AtomicFileTest, RelativePathInTheCurrentDirectory) {
  const fs::path old_cwd = fs::current_path();
  fs::current_path(dir_);
  writeFileAtomically("rel.txt", std::string_view("r"));
  fs::current_path(old_cwd);
  EXPECT_EQ(readText(dir_ / "rel.txt"), "r");
}

}  // namespace
}  // namespace cylscan::formats
