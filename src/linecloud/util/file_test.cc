#include "linecloud/util/file.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <utime.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "linecloud/testing/test_util.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using testing::TempDir;
namespace fs = std::filesystem;

void Write(const std::string& path, const std::string& text, unsigned mode = 0644) {
  WriteFileAtomically(
      path, [&](std::ostream& out) { out << text; }, mode);
}

TEST(File, WritesAtomicallyWithTheRequestedMode) {
  TempDir tmp;
  Write(tmp.Path("a.txt"), "one", 0600);
  EXPECT_EQ(ReadFileToString(tmp.Path("a.txt")), "one");
  struct stat st;
  ASSERT_EQ(::stat(tmp.Path("a.txt").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  // A writer that fails leaves the old file and no temporary behind.
  EXPECT_THROW(WriteFileAtomically(tmp.Path("a.txt"),
                                   [](std::ostream& out) {
                                     out << "partial";
                                     throw Error("no");
                                   }),
               Error);
  EXPECT_EQ(ReadFileToString(tmp.Path("a.txt")), "one");
  EXPECT_EQ(std::distance(fs::directory_iterator(tmp.Path()), fs::directory_iterator()), 1);
}

// A device is written through, never replaced by a regular file.
TEST(File, WritesThroughDevicesAndLinks) {
  Write("/dev/null", "discarded");
  struct stat st;
  ASSERT_EQ(::stat("/dev/null", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
  // Through a link: the file it names is replaced, the link stays a link.
  TempDir tmp;
  Write(tmp.Path("target.txt"), "old");
  fs::create_symlink(tmp.Path("target.txt"), tmp.Path("link.txt"));
  Write(tmp.Path("link.txt"), "new");
  EXPECT_TRUE(fs::is_symlink(tmp.Path("link.txt")));
  EXPECT_EQ(ReadFileToString(tmp.Path("target.txt")), "new");
}

// The old writer used OUT.tmp.<pid>: a link planted there made it overwrite
// (and re-permission) another file. The temporary name is now unpredictable
// and created exclusively.
TEST(File, APlantedLinkAtTheOldTemporaryNameIsNotFollowed) {
  TempDir tmp;
  Write(tmp.Path("victim.txt"), "precious", 0600);
  const std::string planted = tmp.Path("out.txt") + ".tmp." + std::to_string(::getpid());
  fs::create_symlink(tmp.Path("victim.txt"), planted);
  Write(tmp.Path("out.txt"), "output");
  EXPECT_EQ(ReadFileToString(tmp.Path("victim.txt")), "precious");
  struct stat st;
  ASSERT_EQ(::stat(tmp.Path("victim.txt").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  EXPECT_EQ(ReadFileToString(tmp.Path("out.txt")), "output");
}

TEST(File, RefusesNonRegularInputsAndOutputsOverInputs) {
  TempDir tmp;
  ASSERT_EQ(::mkfifo(tmp.Path("fifo").c_str(), 0600), 0);
  try {
    ReadFileToString(tmp.Path("fifo"));  // would block forever in open()
    ADD_FAILURE() << "a FIFO was read";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ReadFileToString(tmp.Path()), Error);        // a directory
  EXPECT_THROW(ReadFileToString(tmp.Path("none")), Error);  // missing
  Write(tmp.Path("in.lcm"), "map");
  fs::create_directories(tmp.Path("model"));
  Write(tmp.Path("model/points3D.bin"), "points");
  fs::create_symlink(tmp.Path("in.lcm"), tmp.Path("alias.lcm"));
  EXPECT_THROW(RefuseOutputOverInputs(tmp.Path("alias.lcm"), {tmp.Path("in.lcm")}, "--out"), Error);
  EXPECT_THROW(RefuseOutputOverInputs(tmp.Path("model/points3D.bin"), {tmp.Path("model")}, "--ply"),
               Error);
  EXPECT_NO_THROW(RefuseOutputOverInputs(tmp.Path("new.ply"), {tmp.Path("model")}, "--ply"));
  EXPECT_NO_THROW(RefuseOutputOverInputs(tmp.Path("in.lcm"), {tmp.Path("model"), ""}, "--out"));
}

// [guard]: a writer killed during a write leaves a hidden temporary; the next
// write into that folder removes it once it is a minute old and unlocked. A
// live writer's temporary (locked) and a fresh one are left alone.
TEST(File, TemporariesOfKilledWritersAreRemovedLiveOnesKept) {
  TempDir tmp;
  const auto make = [&](const std::string& name, int age_s) {
    const std::string path = tmp.Path(name);
    std::ofstream(path) << "partial";
    struct utimbuf times;
    times.actime = times.modtime = ::time(nullptr) - age_s;
    ::utime(path.c_str(), &times);
    return path;
  };
  const std::string stale = make(".linecloud-AAAAAA", 120);
  const std::string live = make(".linecloud-BBBBBB", 120);
  const std::string fresh = make(".linecloud-CCCCCC", 0);
  const std::string other = make(".linecloud-DDDDDDD", 120);  // not our naming
  const int live_fd = ::open(live.c_str(), O_RDONLY);
  ASSERT_EQ(::flock(live_fd, LOCK_EX), 0);
  Write(tmp.Path("out.txt"), "new");
  ::close(live_fd);
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_TRUE(fs::exists(live));
  EXPECT_TRUE(fs::exists(fresh));
  EXPECT_TRUE(fs::exists(other));
}

// [guard]: new files get the requested mode less the umask; a replaced file
// keeps its own mode (never widened to the requested one).
TEST(File, NewFilesFollowTheUmaskReplacedFilesKeepTheirMode) {
  TempDir tmp;
  const mode_t old = ::umask(077);
  EXPECT_EQ(CurrentUmask(), 077u);
  Write(tmp.Path("new.txt"), "x", 0644);
  ::umask(old);
  struct stat st;
  ASSERT_EQ(::stat(tmp.Path("new.txt").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  ::chmod(tmp.Path("new.txt").c_str(), 0640);
  Write(tmp.Path("new.txt"), "y", 0644);
  ASSERT_EQ(::stat(tmp.Path("new.txt").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0640u);
  Write(tmp.Path("new.txt"), "z", 0600);  // a secret narrows it
  ASSERT_EQ(::stat(tmp.Path("new.txt").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
}

}  // namespace
}  // namespace linecloud
