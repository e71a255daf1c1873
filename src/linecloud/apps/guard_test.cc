// [guard]: the privacy promise under concurrency and tampering, and input from
// strangers (photos, caches, maps, models, databases). Each test is one row of
// the issue; the concurrency rows run real `linecloud` processes.
#include <fcntl.h>
#include <sqlite3.h>
#include <sys/file.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <utime.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <thread>

#include <gtest/gtest.h>

#include "linecloud/features/image.h"
#include "linecloud/io/colmap_database.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/lifting/key.h"
#include "linecloud/lifting/key_store.h"
#include "linecloud/lifting/line_cloud.h"
#include "linecloud/pipeline/image_query.h"
#include "linecloud/localize/localize.h"
#include "linecloud/synthetic/localization_instances.h"
#include "linecloud/testing/test_util.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

namespace fs = std::filesystem;
using testing::DataPath;
using testing::ErrorOf;
using testing::TempDir;

const std::string kMaupertuis = "colmap-maupertuis/reconstruction";

struct Process {
  pid_t pid = -1;
  std::string out_path, err_path;
};

struct Finished {
  int code = -1;
  std::string out, err;
  long max_rss_kb = 0;
};

// Starts `sh -c SCRIPT` with `env` added (KEY=VALUE); standard output and
// error go to files in `tmp`.
Process Start(const std::string& script, const std::vector<std::string>& env, const TempDir& tmp) {
  static int counter = 0;
  Process p;
  p.out_path = tmp.Path("out" + std::to_string(counter));
  p.err_path = tmp.Path("err" + std::to_string(counter++));
  p.pid = ::fork();
  if (p.pid == 0) {
    for (const std::string& e : env) ::putenv(const_cast<char*>(e.c_str()));
    const int out = ::open(p.out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    const int err = ::open(p.err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    ::dup2(out, 1);
    ::dup2(err, 2);
    ::execl("/bin/sh", "sh", "-c", script.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  return p;
}

Finished Wait(const Process& p) {
  Finished f;
  int status = 0;
  struct rusage usage {};
  ::wait4(p.pid, &status, 0, &usage);
  f.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  f.max_rss_kb = usage.ru_maxrss;
  f.out = ReadFileToString(p.out_path);
  f.err = ReadFileToString(p.err_path);
  return f;
}

Finished RunScript(const std::string& script, const std::vector<std::string>& env,
                   const TempDir& tmp) {
  return Wait(Start(script, env, tmp));
}

const std::string& Tool() {
  static const std::string tool = LINECLOUD_BINARY;
  return tool;
}

// The peak memory of a `linecloud` child that only prints its help: a child's
// ru_maxrss also counts the image of this (test) process it was forked from
// before exec, so peak-memory bounds are taken above this baseline.
long BaselineRssKb(const TempDir& tmp) {
  return RunScript(fmt::format("exec {} --help", Tool()), {}, tmp).max_rss_kb;
}

std::vector<std::string> StoreFiles(const std::string& store, const std::string& extension) {
  std::vector<std::string> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(store, ec)) {
    if (e.path().extension() == extension) out.push_back(e.path().filename().string());
  }
  return out;
}

unsigned Mode(const std::string& path) {
  struct stat st;
  EXPECT_EQ(::stat(path.c_str(), &st), 0) << path;
  return st.st_mode & 0777;
}

// Row 1: two lifts of one new model started at the same moment, one store.
// Before: 7 of 10 trials made two keys (1039 / 1039 points recovered).
TEST(Guard, ConcurrentLiftsOfANewModelMakeOneKey) {
  LINECLOUD_REQUIRE_DATA(kMaupertuis);
  TempDir tmp;
  const std::string model = DataPath(kMaupertuis);
  const int trials = testing::InstanceCount(50);
  int double_keys = 0;
  for (int trial = 0; trial < trials; ++trial) {
    const std::string store = tmp.Path("store" + std::to_string(trial));
    const std::vector<std::string> env = {"LINECLOUD_KEY_STORE=" + store};
    std::vector<Process> running;
    for (int k = 0; k < 2; ++k) {
      running.push_back(Start(fmt::format("exec {} lift --model {} --out {}", Tool(), model,
                                          tmp.Path(fmt::format("m{}_{}.lcm", trial, k))),
                              env, tmp));
    }
    std::set<std::string> fingerprints;
    for (int k = 0; k < 2; ++k) {
      const Finished f = Wait(running[k]);
      ASSERT_EQ(f.code, 0) << f.err;
      fingerprints.insert(
          ToHex(ReadLineCloud(tmp.Path(fmt::format("m{}_{}.lcm", trial, k))).key_fingerprint));
    }
    const size_t keys = StoreFiles(store, ".key").size(),
                 models = StoreFiles(store, ".model").size();
    double_keys += keys != 1 || models != 1 || fingerprints.size() != 1;
  }
  EXPECT_EQ(double_keys, 0) << "of " << trials << " concurrent lift pairs";
}

// A copy of the maupertuis model (text) with `edit` applied to images.txt.
std::string CopyModel(const TempDir& tmp, const std::string& name,
                      const std::function<std::string(std::string)>& edit = nullptr) {
  const std::string dir = tmp.Path(name);
  fs::create_directories(dir);
  for (const char* file : {"cameras.txt", "images.txt", "points3D.txt"}) {
    std::string text = ReadFileToString(DataPath(kMaupertuis) + "/" + file);
    if (edit && std::string(file) == "images.txt") text = edit(text);
    WriteFileAtomically(dir + "/" + file, [&](std::ostream& os) { os << text; });
  }
  return dir;
}

// Lifts the shared model to OUT with the key store STORE (a real process).
void LiftIntoStore(const std::string& store, const std::string& out, const TempDir& tmp) {
  const Finished f =
      RunScript(fmt::format("{} lift --model {} --out {}", Tool(), DataPath(kMaupertuis), out),
                {"LINECLOUD_KEY_STORE=" + store}, tmp);
  ASSERT_EQ(f.code, 0) << f.err;
}

// Row 2: a key file of the store edited (other hex digits), then lift again.
TEST(Guard, AKeyEditedInTheStoreIsRefused) {
  LINECLOUD_REQUIRE_DATA(kMaupertuis);
  TempDir tmp;
  const std::string store = tmp.Path("store");
  const std::vector<std::string> env = {"LINECLOUD_KEY_STORE=" + store};
  const std::string model = DataPath(kMaupertuis);
  LiftIntoStore(store, tmp.Path("a.lcm"), tmp);
  const std::vector<std::string> keys = StoreFiles(store, ".key");
  ASSERT_EQ(keys.size(), 1u);
  const std::string key_path = store + "/" + keys[0];
  std::string text = ReadFileToString(key_path);
  const size_t digit = text.rfind('\n', text.size() - 2) + 1;  // the first digit of the key line
  text[digit] = text[digit] == '0' ? '1' : '0';
  WriteFileAtomically(
      key_path, [&](std::ostream& os) { os << text; }, 0600);
  const Finished f = RunScript(
      fmt::format("{} lift --model {} --out {}", Tool(), model, tmp.Path("b.lcm")), env, tmp);
  EXPECT_EQ(f.code, 1);
  EXPECT_NE(f.err.find("the key file was changed"), std::string::npos) << f.err;
  EXPECT_FALSE(FileExists(tmp.Path("b.lcm")));
}

// Row 3: the same model with its images renamed (a folder prefix).
TEST(Guard, RenamedImagesAreStillTheSameModel) {
  LINECLOUD_REQUIRE_DATA(kMaupertuis);
  TempDir tmp;
  const std::string store = tmp.Path("store");
  const std::vector<std::string> env = {"LINECLOUD_KEY_STORE=" + store};
  const std::string plain = CopyModel(tmp, "plain");
  const std::string renamed = CopyModel(tmp, "renamed", [](std::string text) {
    // The name is the last field of each image line (the lines with 10 fields).
    std::istringstream in(text);
    std::string line, out;
    int renamed_lines = 0;
    while (std::getline(in, line)) {
      std::istringstream fields(line);
      std::vector<std::string> f;
      for (std::string w; fields >> w;) f.push_back(w);
      if (f.size() == 10 && line[0] != '#') {
        line = line.substr(0, line.rfind(' ') + 1) + "images/" + f.back();
        ++renamed_lines;
      }
      out += line + "\n";
    }
    EXPECT_GT(renamed_lines, 0);
    return out;
  });
  for (const auto& [dir, out] : {std::pair{plain, "a.lcm"}, std::pair{renamed, "b.lcm"}}) {
    const Finished f =
        RunScript(fmt::format("{} lift --model {} --out {}", Tool(), dir, tmp.Path(out)), env, tmp);
    ASSERT_EQ(f.code, 0) << f.err;
  }
  EXPECT_EQ(ReadLineCloud(tmp.Path("a.lcm")).key_fingerprint,
            ReadLineCloud(tmp.Path("b.lcm")).key_fingerprint);
  EXPECT_EQ(StoreFiles(store, ".key").size(), 1u);
}

// Row 8: the store's parents are created owner-only whatever the umask; a
// store that is a link, or another user's, is refused.
TEST(Guard, KeyStoreParentsOwnerAndLinks) {
  LINECLOUD_REQUIRE_DATA(kMaupertuis);
  TempDir tmp;
  const std::string model = DataPath(kMaupertuis);
  const std::string store = tmp.Path("home/.local/share/linecloud/keys");
  Finished f = RunScript(
      fmt::format("umask 000; {} lift --model {} --out {}", Tool(), model, tmp.Path("a.lcm")),
      {"LINECLOUD_KEY_STORE=" + store}, tmp);
  ASSERT_EQ(f.code, 0) << f.err;
  for (const char* dir : {"home", "home/.local", "home/.local/share", "home/.local/share/linecloud",
                          "home/.local/share/linecloud/keys"}) {
    EXPECT_EQ(Mode(tmp.Path(dir)), 0700u) << dir;
  }
  // A link to a store: refused.
  fs::create_symlink(store, tmp.Path("link"));
  f = RunScript(fmt::format("{} lift --model {} --out {}", Tool(), model, tmp.Path("b.lcm")),
                {"LINECLOUD_KEY_STORE=" + tmp.Path("link")}, tmp);
  EXPECT_EQ(f.code, 1);
  EXPECT_NE(f.err.find("symbolic link"), std::string::npos) << f.err;
  // Another user's store (as root, chown it to nobody).
  if (::geteuid() == 0) {
    const std::string theirs = tmp.Path("theirs");
    ASSERT_TRUE(fs::create_directory(theirs));
    ::chmod(theirs.c_str(), 0700);
    ASSERT_EQ(::chown(theirs.c_str(), 65534, 65534), 0);
    EXPECT_NE(ErrorOf([&] { KeyStore s(theirs); }).find("belongs to another user"),
              std::string::npos);
  }
}

// Row 9: an output naming the store's own key (or anything in the store).
TEST(Guard, LiftNeverWritesIntoTheKeyStore) {
  LINECLOUD_REQUIRE_DATA(kMaupertuis);
  TempDir tmp;
  const std::string store = tmp.Path("store");
  const std::vector<std::string> env = {"LINECLOUD_KEY_STORE=" + store};
  const std::string model = DataPath(kMaupertuis);
  LiftIntoStore(store, tmp.Path("a.lcm"), tmp);
  const std::string key_path = store + "/" + StoreFiles(store, ".key").at(0);
  const std::string key_text = ReadFileToString(key_path);
  for (const std::string& out : {key_path, store + "/new.lcm"}) {
    const Finished f =
        RunScript(fmt::format("{} lift --model {} --out {} --force", Tool(), model, out), env, tmp);
    EXPECT_EQ(f.code, 1) << out;
    EXPECT_NE(f.err.find("--out"), std::string::npos) << f.err;
  }
  EXPECT_EQ(ReadFileToString(key_path), key_text);
  EXPECT_FALSE(FileExists(store + "/new.lcm"));
}

// Row 10: one unreadable entry no longer stops every lift; it is named.
// [identity]: an unreadable entry may be this model's; a new key would put a
// second line through every point. No key is made, the entry is named; once
// it is moved away the lift goes on (and another model's lift only warns).
TEST(Guard, ABadStoreEntryStopsKeyCreationAndIsNamed) {
  LINECLOUD_REQUIRE_DATA(kMaupertuis);
  TempDir tmp;
  const std::string store = tmp.Path("store");
  KeyStore{store};
  {
    const ProtectedWriteScope writing_the_store;
    WriteFileAtomically(
        store + "/x.model", [](std::ostream&) {}, 0600);
  }
  const auto lift = [&](const std::string& out) {
    return RunScript(
        fmt::format("{} lift --model {} --out {}", Tool(), DataPath(kMaupertuis), tmp.Path(out)),
        {"LINECLOUD_KEY_STORE=" + store}, tmp);
  };
  Finished f = lift("a.lcm");
  EXPECT_NE(f.code, 0);
  EXPECT_NE(f.err.find("unreadable entry"), std::string::npos) << f.err;
  EXPECT_NE(f.err.find("x.model"), std::string::npos) << f.err;
  EXPECT_NE(f.err.find("no key was created"), std::string::npos) << f.err;
  EXPECT_FALSE(FileExists(tmp.Path("a.lcm")));
  size_t keys = 0;
  for (const auto& e : std::filesystem::directory_iterator(store))
    keys += e.path().extension() == ".key";
  EXPECT_EQ(keys, 0u);
  // Moved away: the lift makes the model's key.
  std::filesystem::rename(store + "/x.model", tmp.Path("x.model"));
  f = lift("a.lcm");
  ASSERT_EQ(f.code, 0) << f.err;
  // Back: the model's own entry is found, the bad one only warned about.
  std::filesystem::rename(tmp.Path("x.model"), store + "/x.model");
  f = lift("b.lcm");
  ASSERT_EQ(f.code, 0) << f.err;
  EXPECT_NE(f.err.find("warning: key store entry skipped"), std::string::npos) << f.err;
  EXPECT_EQ(ReadFileToString(tmp.Path("a.lcm")), ReadFileToString(tmp.Path("b.lcm")));
}

// [identity] The key store as a vault: no command writes a key-store file or
// into the store, directly or through a link; the key stays intact.
TEST(Guard, NoCommandWritesIntoTheKeyStore) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/colmap.db");
  TempDir tmp;
  const std::string store = tmp.Path("store");
  const std::vector<std::string> env = {"LINECLOUD_KEY_STORE=" + store,
                                        "XDG_CACHE_HOME=" + tmp.Path("cache")};
  const std::string model = DataPath(kMaupertuis);
  const std::string db = DataPath("colmap-maupertuis/colmap.db");
  const std::string photo = DataPath("colmap-maupertuis/images/02.jpg");
  const std::string camera = "'SIMPLE_PINHOLE 1919 1079 1847.53 959.5 539.5'";
  Finished f = RunScript(fmt::format("{} lift --model {} --database {} --out {}", Tool(), model, db,
                                     tmp.Path("m.lcm")),
                         env, tmp);
  ASSERT_EQ(f.code, 0) << f.err;
  const std::string key_path = store + "/" + StoreFiles(store, ".key").at(0);
  const std::string key_text = ReadFileToString(key_path);
  fs::create_symlink(key_path, tmp.Path("link-to-key"));
  for (const std::string& target : {key_path, tmp.Path("link-to-key"), store + "/new"}) {
    const std::vector<std::string> commands = {
        fmt::format("make-query --model {} --image 02.jpg --out {}", model, target),
        fmt::format("export --model {} --ply {}", model, target),
        fmt::format("localize --map {} --image {} --camera {} --out {} --quiet", tmp.Path("m.lcm"),
                    photo, camera, target),
        fmt::format("localize --map {} --image {} --camera {} --ply {} --quiet", tmp.Path("m.lcm"),
                    photo, camera, target),
        fmt::format("attack --map {} --out {} --quiet", tmp.Path("m.lcm"), target),
        fmt::format("features --image {} --camera {} --out {}", photo, camera, target),
        fmt::format("audit --map {} --model {} --out {} --quiet --no-density-attack --other {}",
                    tmp.Path("m.lcm"), model, target, tmp.Path("m.lcm"))};
    for (const std::string& command : commands) {
      f = RunScript(Tool() + " " + command, env, tmp);
      EXPECT_NE(f.code, 0) << command;
      EXPECT_NE(f.err.find("inside the key store"), std::string::npos) << command << ": " << f.err;
      EXPECT_EQ(ReadFileToString(key_path), key_text) << command;
    }
  }
  EXPECT_FALSE(FileExists(store + "/new"));
  // Nor a new key file named into the store (found by an outsider's review).
  f = RunScript(fmt::format("{} lift --model {} --out {} --key-file {}", Tool(), model,
                            tmp.Path("other.lcm"), store + "/evil.key"),
                env, tmp);
  EXPECT_NE(f.code, 0);
  EXPECT_NE(f.err.find("inside the key store"), std::string::npos) << f.err;
  EXPECT_FALSE(FileExists(store + "/evil.key"));
}

// [identity] The descriptor index is cached in the user's own cache folder:
// a link or a FIFO planted beside the map (where others may write) is never
// written through or waited on.
TEST(Guard, APlantedCacheLinkOrFifoIsNeverUsed) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/colmap.db");
  TempDir tmp;
  const std::string store = tmp.Path("store");
  const std::vector<std::string> env = {"LINECLOUD_KEY_STORE=" + store,
                                        "XDG_CACHE_HOME=" + tmp.Path("cache")};
  Finished f = RunScript(
      fmt::format("{} lift --model {} --database {} --out {}", Tool(), DataPath(kMaupertuis),
                  DataPath("colmap-maupertuis/colmap.db"), tmp.Path("m.lcm")),
      env, tmp);
  ASSERT_EQ(f.code, 0) << f.err;
  const std::string victim = tmp.Path("authorized_keys");
  std::ofstream(victim) << "ssh-ed25519 AAAA the owner's\n";
  fs::create_symlink(victim, tmp.Path("m.lcm.index"));
  ASSERT_EQ(::mkfifo(tmp.Path("fifo-map.lcm.index").c_str(), 0644), 0);
  fs::copy_file(tmp.Path("m.lcm"), tmp.Path("fifo-map.lcm"));
  for (const char* map : {"m.lcm", "fifo-map.lcm"}) {
    f = RunScript(fmt::format("timeout 60 {} localize --map {} --image {} --camera '{}' "
                              "--approximate-from 10 --max-iterations 200 --quiet",
                              Tool(), tmp.Path(map), DataPath("colmap-maupertuis/images/02.jpg"),
                              "SIMPLE_PINHOLE 1919 1079 1847.53 959.5 539.5"),
                  env, tmp);
    EXPECT_EQ(f.code, 0) << map << ": " << f.err;
  }
  EXPECT_EQ(ReadFileToString(victim), "ssh-ed25519 AAAA the owner's\n");
  EXPECT_TRUE(fs::is_symlink(tmp.Path("m.lcm.index")));
  EXPECT_TRUE(fs::is_fifo(tmp.Path("fifo-map.lcm.index")));
  size_t cached = 0;
  for (auto it = fs::directory_iterator(tmp.Path("cache/linecloud/index"));
       it != fs::directory_iterator(); ++it) {
    ++cached;
  }
  EXPECT_EQ(cached, 2u);
}

// [identity] A store lock held by another process is reported after a second
// and given up on after LINECLOUD_LOCK_TIMEOUT, with no key made.
TEST(Guard, AHeldStoreLockIsReportedAndGivenUp) {
  LINECLOUD_REQUIRE_DATA(kMaupertuis);
  TempDir tmp;
  const std::string store = tmp.Path("store");
  KeyStore{store};
  const int fd = ::open((store + "/.lock").c_str(), O_RDWR | O_CREAT, 0600);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::flock(fd, LOCK_EX), 0);
  const auto start = std::chrono::steady_clock::now();
  const Finished f = RunScript(
      fmt::format("{} lift --model {} --out {}", Tool(), DataPath(kMaupertuis), tmp.Path("a.lcm")),
      {"LINECLOUD_KEY_STORE=" + store, "LINECLOUD_LOCK_TIMEOUT=2"}, tmp);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ::close(fd);
  EXPECT_NE(f.code, 0);
  EXPECT_NE(f.err.find("waiting for the key store's lock"), std::string::npos) << f.err;
  EXPECT_NE(f.err.find("locked by another process"), std::string::npos) << f.err;
  EXPECT_GE(seconds, 2.0);
  EXPECT_LT(seconds, 30.0);
  EXPECT_TRUE(StoreFiles(store, ".key").empty());
  EXPECT_FALSE(FileExists(tmp.Path("a.lcm")));
}

// [identity] A lift refused at its output check makes and registers no key.
TEST(Guard, ALiftRefusedAtItsOutputMakesNoKey) {
  LINECLOUD_REQUIRE_DATA(kMaupertuis);
  TempDir tmp;
  const std::string store = tmp.Path("store");
  std::ofstream(tmp.Path("a.lcm")) << "not a map";
  const Finished f = RunScript(
      fmt::format("{} lift --model {} --out {}", Tool(), DataPath(kMaupertuis), tmp.Path("a.lcm")),
      {"LINECLOUD_KEY_STORE=" + store}, tmp);
  EXPECT_NE(f.code, 0);
  EXPECT_NE(f.err.find("not a readable line cloud"), std::string::npos) << f.err;
  EXPECT_TRUE(StoreFiles(store, ".key").empty());
  EXPECT_TRUE(StoreFiles(store, ".model").empty());
  EXPECT_TRUE(StoreFiles(store, ".ledger").empty());
}

// [identity] A large file with a valid magic but another version is refused
// from its header, not read whole.
TEST(Guard, AMapOfAnotherVersionIsRefusedFromItsHeader) {
  TempDir tmp;
  const std::string path = tmp.Path("big.lcm");
  {
    std::ofstream f(path, std::ios::binary);
    f << "LCMAP\r\n\x1a";
    const uint32_t version = 99, header = 2;
    f.write(reinterpret_cast<const char*>(&version), 4);
    f.write(reinterpret_cast<const char*>(&header), 4);
  }
  fs::resize_file(path, uint64_t{1} << 30);  // a sparse 1 GB file
  Finished f = RunScript(fmt::format("{} info --map {}", Tool(), path), {}, tmp);
  EXPECT_EQ(f.code, 1);
  EXPECT_NE(f.err.find("unsupported .lcm format version 99"), std::string::npos) << f.err;
  EXPECT_LT(f.max_rss_kb, BaselineRssKb(tmp) + 100 * 1024);
  // A real map grown to 1 GB: its header's sizes refuse it before the body is read.
  LINECLOUD_REQUIRE_DATA(kMaupertuis);
  f = RunScript(
      fmt::format("{} lift --model {} --out {}", Tool(), DataPath(kMaupertuis), tmp.Path("m.lcm")),
      {"LINECLOUD_KEY_STORE=" + tmp.Path("store")}, tmp);
  ASSERT_EQ(f.code, 0) << f.err;
  fs::resize_file(tmp.Path("m.lcm"), uint64_t{1} << 30);
  f = RunScript(fmt::format("{} info --map {}", Tool(), tmp.Path("m.lcm")), {}, tmp);
  EXPECT_EQ(f.code, 1);
  EXPECT_NE(f.err.find("file size does not match its header"), std::string::npos) << f.err;
  EXPECT_LT(f.max_rss_kb, BaselineRssKb(tmp) + 100 * 1024);
}

// Row 6: outputs under umask 077 (the secret points of export --model among
// them) are owner-only; a file replaced through a link keeps its mode.
TEST(Guard, OutputsRespectTheUmaskAndReplacedFilesKeepTheirMode) {
  LINECLOUD_REQUIRE_DATA(kMaupertuis);
  TempDir tmp;
  const std::string model = DataPath(kMaupertuis);
  const Finished f = RunScript(
      fmt::format("umask 077; {0} export --model {1} --ply {2} && {0} lift --model {1} --out {3} "
                  "&& {0} make-query --model {1} --image 02.jpg --out {4}",
                  Tool(), model, tmp.Path("points.ply"), tmp.Path("map.lcm"), tmp.Path("q.json")),
      {"LINECLOUD_KEY_STORE=" + tmp.Path("store")}, tmp);
  ASSERT_EQ(f.code, 0) << f.err;
  for (const char* out : {"points.ply", "map.lcm", "q.json"})
    EXPECT_EQ(Mode(tmp.Path(out)), 0600u) << out;
  // Through a link, a 0600 file stays 0600 (was replaced by a 0644 one).
  WriteFileAtomically(
      tmp.Path("secret.ply"), [](std::ostream& os) { os << "old"; }, 0600);
  fs::create_symlink(tmp.Path("secret.ply"), tmp.Path("link.ply"));
  const Finished g = RunScript(
      fmt::format("umask 022; {} export --model {} --ply {}", Tool(), model, tmp.Path("link.ply")),
      {}, tmp);
  ASSERT_EQ(g.code, 0) << g.err;
  EXPECT_EQ(Mode(tmp.Path("secret.ply")), 0600u);
  EXPECT_NE(ReadFileToString(tmp.Path("secret.ply")), "old");
}

// Row 14: a FIFO output that nothing reads is refused instead of blocking.
TEST(Guard, AFifoOutputWithoutAReaderIsRefused) {
  LINECLOUD_REQUIRE_DATA(kMaupertuis);
  TempDir tmp;
  ASSERT_EQ(::mkfifo(tmp.Path("fifo").c_str(), 0600), 0);
  // `timeout` turns a hang into exit code 124.
  const Finished f = RunScript(fmt::format("timeout 60 {} export --model {} --ply {}", Tool(),
                                           DataPath(kMaupertuis), tmp.Path("fifo")),
                               {}, tmp);
  EXPECT_EQ(f.code, 1) << f.err;
  EXPECT_NE(f.err.find("nothing reads"), std::string::npos) << f.err;
  // With a reader, it is written through. (A FIFO read before any writer
  // opened it reads as ended: keep reading until the writer has exited.)
  const int fd = ::open(tmp.Path("fifo").c_str(), O_RDONLY | O_NONBLOCK);
  ASSERT_GE(fd, 0);
  const Process p = Start(fmt::format("timeout 60 {} export --model {} --ply {}", Tool(),
                                      DataPath(kMaupertuis), tmp.Path("fifo")),
                          {}, tmp);
  std::string received;
  char buffer[4096];
  for (int idle = 0; idle < 6000;) {
    const ssize_t n = ::read(fd, buffer, sizeof(buffer));
    if (n > 0) {
      received.append(buffer, static_cast<size_t>(n));
      continue;
    }
    if (n == 0 && !received.empty()) break;  // the writer closed it
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    ++idle;
  }
  ::close(fd);
  const Finished g = Wait(p);
  EXPECT_EQ(g.code, 0) << g.err;
  EXPECT_EQ(received.rfind("ply\n", 0), 0u) << received.substr(0, 100);
}

// Row 4: a 97-byte PNG whose header says 60000 x 60000 (testing::BombPng):
// refused from its header (before: 3.5 GB and 19 s, then an error).
TEST(Guard, ADecompressionBombIsRefusedFromItsHeader) {
  const std::string png = testing::BombPng();
  ASSERT_LT(png.size(), 200u);
  const std::span<const uint8_t> bytes(reinterpret_cast<const uint8_t*>(png.data()), png.size());
  const ImageHeader header = ReadImageHeader(bytes, "bomb.png", {.max_pixels = ~uint64_t{0}});
  EXPECT_EQ(header.width, 60000u);
  EXPECT_EQ(header.height, 60000u);
  EXPECT_NE(ErrorOf([&] {
              DecodeGreyImage(bytes, "bomb.png");
            }).find("bomb.png: the image header says 60000x60000 pixels, more than the limit"),
            std::string::npos);
  // Within the pixel cap but not the camera's size: refused from the header too.
  EXPECT_NE(ErrorOf([&] {
              DecodeGreyImage(
                  bytes, "bomb.png",
                  {.max_pixels = ~uint64_t{0}, .expected_width = 640, .expected_height = 480});
            }).find("the image is 60000x60000 pixels but the camera is 640x480"),
            std::string::npos);
  // End to end: the CLI's peak memory stays small.
  LINECLOUD_REQUIRE_DATA(kMaupertuis);
  TempDir tmp;
  WriteFileAtomically(tmp.Path("bomb.png"), [&](std::ostream& os) { os << png; });
  const std::vector<std::string> env = {"LINECLOUD_KEY_STORE=" + tmp.Path("store")};
  const std::string m = DataPath("colmap-maupertuis");
  ASSERT_EQ(
      RunScript(fmt::format("{} lift --model {}/reconstruction --database {}/colmap.db --out {}",
                            Tool(), m, m, tmp.Path("m.lcm")),
                env, tmp)
          .code,
      0);
  const Finished f =
      RunScript(fmt::format("{} localize --map {} --image {} --camera 'PINHOLE 60000 60000 "
                            "50000 50000 30000 30000'",
                            Tool(), tmp.Path("m.lcm"), tmp.Path("bomb.png")),
                env, tmp);
  EXPECT_EQ(f.code, 1);
  EXPECT_NE(f.err.find("more than the limit"), std::string::npos) << f.err;
  EXPECT_LT(f.max_rss_kb, BaselineRssKb(tmp) + 100 * 1024) << "peak memory of the refused photo";
}

// Row 13: the first 8 000 bytes of a JPEG are an error, not half a photo.
TEST(Guard, ATruncatedJpegIsAnError) {
  LINECLOUD_REQUIRE_DATA("strecha/fountain-P11/images/0000.jpg");
  const std::string jpeg = ReadFileToString(DataPath("strecha/fountain-P11/images/0000.jpg"));
  const std::string head = jpeg.substr(0, 8000);
  const auto decode = [](const std::string& data) {
    return DecodeGreyImage(std::span(reinterpret_cast<const uint8_t*>(data.data()), data.size()),
                           "photo.jpg");
  };
  EXPECT_NE(ErrorOf([&] { decode(head); }).find("photo.jpg: the image is truncated"),
            std::string::npos);
  // The whole file decodes, from bytes exactly as from the path.
  const GreyImage whole = decode(jpeg);
  EXPECT_EQ(whole.pixels, ReadGreyImage(DataPath("strecha/fountain-P11/images/0000.jpg")).pixels);
}

// Row 11: NaN 2D points in a binary model are refused (as in text models).
TEST(Guard, NonFinite2DPointsInABinaryModelAreRefused) {
  LINECLOUD_REQUIRE_DATA(kMaupertuis);
  TempDir tmp;
  Reconstruction rec = ReadColmapModel(DataPath(kMaupertuis));
  rec.images.begin()->second.points2D.at(3).xy.x() = std::nan("");
  WriteColmapModel(rec, tmp.Path("model"), ModelFormat::kBinary);
  EXPECT_NE(ErrorOf([&] { ReadColmapModel(tmp.Path("model")); }).find("field 'points2D.x' at byte"),
            std::string::npos);
}

// Row 12: a large file with bad magic is refused from its first bytes (the
// CLI's peak memory stays small; before, the whole file was read first).
TEST(Guard, InfoRefusesALargeNonMapFromItsMagic) {
  TempDir tmp;
  const std::string path = tmp.Path("big.lcm");
  {
    std::ofstream f(path, std::ios::binary);
    f << "NOTAMAP!";
  }
  fs::resize_file(path, uint64_t{3} << 30);  // a sparse 3 GB file
  const Finished f = RunScript(fmt::format("{} info --map {}", Tool(), path), {}, tmp);
  EXPECT_EQ(f.code, 1);
  EXPECT_NE(f.err.find("bad magic"), std::string::npos) << f.err;
  EXPECT_LT(f.max_rss_kb, BaselineRssKb(tmp) + 100 * 1024);
}

// Row 15: moments of 1e300 (a valid Plücker line) are refused, not attacked into inf.
TEST(Guard, LinesFarBeyondAnyMapAreRefused) {
  LineCloud cloud;
  cloud.ids = {1, 2};
  cloud.lines = {PluckerLine(Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 2, 0)),
                 PluckerLine(Eigen::Vector3d(0, 1, 0), Eigen::Vector3d(0, 0, 3e300))};
  EXPECT_TRUE(cloud.lines[1].IsValid(1e-6));
  EXPECT_NE(ErrorOf([&] { cloud.Check("map.lcm"); }).find("map.lcm: line 1 (id 2) passes 3e+300"),
            std::string::npos);
  cloud.lines[1].w *= 1e-290;  // 3e10: a far but real place
  EXPECT_EQ(ErrorOf([&] { cloud.Check("map.lcm"); }), "");
}

// Row 16: a descriptor row count of 2^62 + 1 is a shape error, not a 2^69-byte allocation.
TEST(Guard, AnOverflowingDatabaseShapeIsAClearError) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/colmap.db");
  TempDir tmp;
  const std::string db = tmp.Path("colmap.db");
  fs::copy_file(DataPath("colmap-maupertuis/colmap.db"), db);
  sqlite3* handle = nullptr;
  ASSERT_EQ(sqlite3_open(db.c_str(), &handle), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(handle,
                         "UPDATE descriptors SET rows = 4611686018427387905, data = zeroblob(128) "
                         "WHERE image_id = 1",
                         nullptr, nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(handle);
  const ColmapDatabase database(db);
  EXPECT_NE(ErrorOf([&] { database.ReadDescriptors(1); }).find("is too large for any blob"),
            std::string::npos);
}

// Row 17: one camera with local points and unknown scale (m-P3P+l): rotation
// and centre are determined although the scale gauge is not.
TEST(Guard, OneCameraWithLocalPointsReportsWhatIsDetermined) {
  const MethodInfo& method = FindMethod("m-P3P+l");
  ASSERT_TRUE(method.similarity());
  LocalizationInstanceOptions o;
  o.num_rig_cameras = 1;
  int localized = 0;
  const int queries = 10;
  for (int k = 0; k < queries; ++k) {
    std::mt19937_64 rng(100 + k);
    const LocalizationInstance inst = RandomLocalizationInstance(method, o, rng);
    ASSERT_EQ(inst.query.cameras.size(), 1u);
    LocalizeOptions options;
    options.ransac.seed = k;
    const LocalizeResult r = Localize(method, inst.query, LocalizationMap(inst.point_map), options);
    ASSERT_TRUE(r.success) << r.failure;
    // The matches' share; with the calibration's (a camera trusted to a third of what the
    // calibration check lets through) it stays well below the 1° of a success.
    EXPECT_LT(r.matches_uncertainty.rotation_deg, 0.1);
    EXPECT_LT(r.uncertainty.rotation_deg, 0.3);
    EXPECT_TRUE(std::isfinite(r.uncertainty.position)) << r.uncertainty.rotation_deg;
    const LocalizationError e = CompareLocalization(r.query_from_world, inst.truth);
    localized += e.rotation_rad < 0.5 * M_PI / 180 && e.position < 0.01 * inst.scene_size;
  }
  EXPECT_EQ(localized, queries);
}

// Row 18: the attack's time is bounded.
TEST(Guard, TheAttackStopsAtItsTimeBudget) {
  LINECLOUD_REQUIRE_DATA(kMaupertuis);
  TempDir tmp;
  const std::vector<std::string> env = {"LINECLOUD_KEY_STORE=" + tmp.Path("store")};
  ASSERT_EQ(RunScript(fmt::format("{} lift --model {} --out {}", Tool(), DataPath(kMaupertuis),
                                  tmp.Path("m.lcm")),
                      env, tmp)
                .code,
            0);
  const Finished f = RunScript(fmt::format("{} attack --map {} --out {} --max-seconds 1e-6 --quiet",
                                           Tool(), tmp.Path("m.lcm"), tmp.Path("rec.ply")),
                               env, tmp);
  EXPECT_EQ(f.code, 1);
  EXPECT_NE(f.err.find("stopped at --max-seconds 1e-06"), std::string::npos) << f.err;
  EXPECT_NE(f.err.find("the whole attack would take about"), std::string::npos) << f.err;
  EXPECT_FALSE(FileExists(tmp.Path("rec.ply")));
}

}  // namespace
}  // namespace linecloud
