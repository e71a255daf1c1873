// `linecloud map` end to end through the real binary: photos of a real scene
// to a served map that localizes a photo left out; bad input refused before
// any work, naming the file; a run interrupted in each stage (SIGINT as a
// terminal's Ctrl-C sends it, to the process group; SIGKILL) finished by the
// same command with the same lines as an uninterrupted run; an update that
// keeps every released line.
#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <set>
#include <thread>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "linecloud/io/colmap_model.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/testing/test_util.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

namespace fs = std::filesystem;
using testing::DataPath;
using testing::TempDir;

const std::string kFountain = "strecha/fountain-P11";
const std::string kCamera = "PINHOLE 1536 1024 1379.74 1382.08 760.095 503.155";

struct Child {
  pid_t pid = -1;
  std::string err_path, out_path;
};

// The tool in its own process group (a terminal's Ctrl-C reaches the whole group).
Child Start(const std::vector<std::string>& args, const std::string& tag, const TempDir& tmp) {
  Child r;
  r.out_path = tmp.Path(tag + ".out");
  r.err_path = tmp.Path(tag + ".err");
  std::vector<char*> argv;
  static const std::string tool = LINECLOUD_BINARY;
  argv.push_back(const_cast<char*>(tool.c_str()));
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  r.pid = ::fork();
  if (r.pid == 0) {
    ::setpgid(0, 0);
    const int out = ::open(r.out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    const int err = ::open(r.err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    ::dup2(out, 1);
    ::dup2(err, 2);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  ::setpgid(r.pid, r.pid);
  return r;
}

int Wait(const Child& r) {
  int status = 0;
  ::waitpid(r.pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

// Waits until the run's log shows `marker`, then sends `sig` (to its group
// for SIGINT: the tool and the COLMAP it runs, as Ctrl-C does). False when
// the run ended first.
bool InterruptAt(const Child& r, const std::string& marker, int sig) {
  for (int k = 0; k < 6000; ++k) {
    if (FileExists(r.err_path) && ReadFileToString(r.err_path).find(marker) != std::string::npos) {
      std::this_thread::sleep_for(std::chrono::milliseconds(300));
      ::kill(sig == SIGINT ? -r.pid : r.pid, sig);
      return true;
    }
    int status = 0;
    if (::waitpid(r.pid, &status, WNOHANG) == r.pid) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return false;
}

int RunToEnd(const std::vector<std::string>& args, const std::string& tag, const TempDir& tmp,
             std::string* err = nullptr) {
  const Child r = Start(args, tag, tmp);
  const int code = Wait(r);
  if (err) *err = ReadFileToString(r.err_path);
  return code;
}

std::vector<std::string> Photos(int first, int last) {
  std::vector<std::string> out;
  for (int k = first; k <= last; ++k) {
    out.push_back(DataPath(fmt::format("{}/images/{:04d}.jpg", kFountain, k)));
  }
  return out;
}

// Each project its own key store; one key file (equal models give equal lines).
std::vector<std::string> MapArgs(const std::vector<std::string>& photos, const std::string& project,
                                 const std::string& out, const TempDir& tmp) {
  std::vector<std::string> a = {"map"};
  a.insert(a.end(), photos.begin(), photos.end());
  for (const std::string& s : std::vector<std::string>{
           "--project", project, "--out", out, "--camera", kCamera, "--key-file",
           tmp.Path("map.key"), "--key-store", project + ".keys", "--threads", "2"}) {
    a.push_back(s);
  }
  return a;
}

TEST(Map, BadInputIsRefusedBeforeAnyWorkNamingTheFile) {
  LINECLOUD_REQUIRE_DATA(kFountain);
  TempDir tmp;
  const std::string photo = DataPath(kFountain + "/images/0000.jpg");
  auto refused = [&](std::vector<std::string> args, const std::string& expected) {
    std::string err;
    const int code = RunToEnd(args, "bad", tmp, &err);
    EXPECT_NE(code, 0) << fmt::format("{}", fmt::join(args, " "));
    EXPECT_NE(err.find(expected), std::string::npos) << err;
    EXPECT_EQ(err.find("[map] features"), std::string::npos) << "work started: " << err;
  };
  const std::string project = tmp.Path("p");
  // One photo.
  refused({"map", photo, "--project", project}, "one photo; a map needs at least two");
  // A folder without photos.
  fs::create_directories(tmp.Path("empty"));
  refused({"map", tmp.Path("empty"), "--project", project}, "a folder without photos");
  // A truncated photo (the first half of a JPEG).
  const std::string bytes = ReadFileToString(photo);
  { std::ofstream(tmp.Path("cut.jpg"), std::ios::binary) << bytes.substr(0, bytes.size() / 2); }
  refused({"map", photo, tmp.Path("cut.jpg"), "--project", project},
          tmp.Path("cut.jpg") + ": the JPEG file is truncated");
  // Not an image.
  { std::ofstream(tmp.Path("notes.jpg")) << "not a photo\n"; }
  refused({"map", photo, tmp.Path("notes.jpg"), "--project", project}, tmp.Path("notes.jpg"));
  // A missing photo.
  refused({"map", photo, tmp.Path("gone.jpg"), "--project", project},
          tmp.Path("gone.jpg") + ": no such photo");
  // Two photos of one name.
  fs::create_directories(tmp.Path("b"));
  fs::copy_file(DataPath(kFountain + "/images/0001.jpg"), tmp.Path("b/0000.jpg"));
  refused({"map", photo, tmp.Path("b/0000.jpg"), "--project", project},
          "a second photo named 0000.jpg");
  // Photos of two sizes and no camera for them (EuRoC's frames are 752 x 480).
  LINECLOUD_REQUIRE_DATA("euroc-v101-micro/images");
  std::string frame;
  for (const auto& e : fs::directory_iterator(DataPath("euroc-v101-micro/images"))) {
    frame = e.path().string();
    break;
  }
  refused({"map", photo, frame, "--project", project},
          "no EXIF focal length, among photos of 2 sizes");
  // A project folder holding something else, and another project.
  fs::create_directories(tmp.Path("busy"));
  { std::ofstream(tmp.Path("busy/thesis.tex")) << "\\documentclass{article}\n"; }
  refused({"map", photo, DataPath(kFountain + "/images/0001.jpg"), "--project", tmp.Path("busy")},
          "a folder with other files and no project.json");
  fs::create_directories(tmp.Path("other"));
  {
    std::ofstream(tmp.Path("other/project.json"))
        << R"({"format": "linecloud map project", "version": 1, "id": "00ff", "photos": [{"name": "a.jpg", "blake2b": "x"}]})";
  }
  refused({"map", photo, DataPath(kFountain + "/images/0001.jpg"), "--project", tmp.Path("other")},
          "the project of other photos");
  // The served folder inside the project.
  refused({"map", photo, DataPath(kFountain + "/images/0001.jpg"), "--project", project, "--out",
           project + "/maps/m"},
          "must be apart");
  // A file name COLMAP's match lists cannot hold.
  fs::copy_file(photo, tmp.Path("with space.jpg"));
  refused({"map", photo, tmp.Path("with space.jpg"), "--project", project},
          tmp.Path("with space.jpg") + ": a file name with a space");
  // A symbolic link where a served file goes: its target must never be written.
  fs::create_directories(tmp.Path("served"));
  { std::ofstream(tmp.Path("precious.cfg")) << "precious\n"; }
  fs::create_symlink(tmp.Path("precious.cfg"), tmp.Path("served/m.json"));
  refused({"map", photo, DataPath(kFountain + "/images/0001.jpg"), "--project", project, "--out",
           tmp.Path("served/m")},
          tmp.Path("served/m.json") + ": a symbolic link");
  EXPECT_EQ(ReadFileToString(tmp.Path("precious.cfg")), "precious\n");
  fs::create_directories(tmp.Path("served2/m.json"));
  refused({"map", photo, DataPath(kFountain + "/images/0001.jpg"), "--project", project, "--out",
           tmp.Path("served2/m")},
          tmp.Path("served2/m.json") + ": not a file");
  EXPECT_FALSE(fs::exists(tmp.Path("served2/m.lcm")));
  // A camera no photo takes; a stereo rig no photos pair; a project that is a file.
  const std::string second = DataPath(kFountain + "/images/0001.jpg");
  refused({"map", photo, second, "--project", project, "--camera",
           "PINHOLE 1024 1536 1381 1381 512 768"},
          "--camera: no photo takes this camera (1024x1536; the photos are 1536x1024)");
  refused({"map", photo, second, "--project", project, "--stereo", "_c0,_c1,0.11"},
          "--stereo _c0,_c1,0.11: 0 pairs of photos");
  refused({"map", photo, second, "--project", tmp.Path("precious.cfg")}, "not a folder");
  // A project another run is working on (its lock held).
  fs::create_directories(tmp.Path("locked"));
  const int lock = ::open(tmp.Path("locked/.lock").c_str(), O_RDWR | O_CREAT, 0600);
  ASSERT_EQ(::flock(lock, LOCK_EX), 0);
  refused({"map", photo, DataPath(kFountain + "/images/0001.jpg"), "--project", tmp.Path("locked")},
          "another `linecloud map` is working on this project");
  ::close(lock);
  EXPECT_FALSE(fs::exists(tmp.Path("locked/project.json")));
  EXPECT_EQ(ReadFileToString(tmp.Path("busy/thesis.tex")), "\\documentclass{article}\n");
  EXPECT_FALSE(fs::exists(project + "/database.db"));
}

// Photos of fountain-P11 in, a served folder out that localizes a photo left
// out; nothing of the project in the served folder.
TEST(Map, PhotosInAServedMapOut) {
  LINECLOUD_REQUIRE_DATA(kFountain);
  TempDir tmp;
  const std::string out = tmp.Path("maps/fountain");
  std::string err;
  ASSERT_EQ(RunToEnd(MapArgs(Photos(0, 5), tmp.Path("project"), out, tmp), "map", tmp, &err), 0)
      << err;
  const auto report = nlohmann::json::parse(ReadFileToString(tmp.Path("project/report.json")));
  EXPECT_EQ(report["registered"], 6);
  EXPECT_GT(report["points"].get<size_t>(), 3000u);
  EXPECT_EQ(report["lines"], report["points"]);
  EXPECT_LT(report["mean_reprojection_error_px"].get<double>(), 1.0);
  std::set<std::string> served;
  for (const auto& e : fs::directory_iterator(tmp.Path("maps"))) served.insert(e.path().filename());
  EXPECT_EQ(served,
            (std::set<std::string>{"fountain.lcm", "fountain.json", "fountain.audit.json"}));
  EXPECT_EQ(nlohmann::json::parse(ReadFileToString(out + ".json")), nlohmann::json::object())
      << "no GPS: no geo_anchor";
  const std::string audit = ReadFileToString(out + ".audit.json");
  EXPECT_EQ(audit.find(tmp.Path("project")), std::string::npos) << "a private path served";
  EXPECT_EQ(ReadLineCloud(out + ".lcm").size(), report["lines"].get<size_t>());
  // The served map localizes a photo it was not built from.
  const Child loc = Start({"localize", "--map", out + ".lcm", "--image",
                           DataPath(kFountain + "/images/0006.jpg"), "--camera", kCamera},
                          "localize", tmp);
  ASSERT_EQ(Wait(loc), 0) << ReadFileToString(loc.err_path);
  const auto pose = nlohmann::json::parse(ReadFileToString(loc.out_path));
  EXPECT_TRUE(pose["success"].get<bool>()) << pose.dump();
  // The same command again: every stage kept, the same map.
  const std::string before = ReadFileToString(out + ".lcm");
  ASSERT_EQ(RunToEnd(MapArgs(Photos(0, 5), tmp.Path("project"), out, tmp), "again", tmp, &err), 0)
      << err;
  for (const char* stage : {"features", "matches", "mapper", "lift", "audit"}) {
    EXPECT_NE(err.find(fmt::format("[map] {}: finished by an earlier run", stage)),
              std::string::npos)
        << err;
  }
  EXPECT_EQ(ReadFileToString(out + ".lcm"), before);
}

// Half of fountain's photos mapped and served, then --update with all but the
// last: every released point keeps its line (the audit's pairing of the two
// versions recovers at most 1 % of the points beyond the map's own
// crossings), and the updated map localizes the photo left out.
TEST(Map, AnUpdateKeepsEveryReleasedLine) {
  LINECLOUD_REQUIRE_DATA(kFountain);
  TempDir tmp;
  const std::string project = tmp.Path("project"), out = tmp.Path("maps/f");
  std::string err;
  ASSERT_EQ(RunToEnd(MapArgs(Photos(0, 4), project, out, tmp), "first", tmp, &err), 0) << err;
  fs::copy_file(out + ".lcm", tmp.Path("v1.lcm"));
  const size_t v1_lines = ReadLineCloud(tmp.Path("v1.lcm")).size();
  std::vector<std::string> update = MapArgs(Photos(0, 9), project, out, tmp);
  update.push_back("--update");
  ASSERT_EQ(RunToEnd(update, "update", tmp, &err), 0) << err;
  const auto report = nlohmann::json::parse(ReadFileToString(project + "/report.json"));
  EXPECT_EQ(report["registered"], 10) << report.dump();
  EXPECT_GE(report["lines_kept"].get<size_t>(), v1_lines * 95 / 100) << report.dump();
  EXPECT_EQ(report["lines"].get<size_t>(),
            report["lines_kept"].get<size_t>() + report["lines_new"].get<size_t>())
      << report.dump();
  EXPECT_GT(report["lines_new"].get<size_t>(), 1000u) << report.dump();
  EXPECT_LE(report["lines_withdrawn"].get<size_t>(), v1_lines / 20) << report.dump();
  // The attacker's pairing of the two served versions.
  const auto manifest = nlohmann::json::parse(ReadFileToString(project + "/project.json"));
  const std::string model = project + "/" + manifest["model"].get<std::string>();
  ASSERT_EQ(RunToEnd({"audit", "--map", out + ".lcm", "--model", model, "--other",
                      tmp.Path("v1.lcm"), "--key-file", tmp.Path("map.key"), "--no-density-attack",
                      "--out", tmp.Path("audit")},
                     "audit", tmp, &err),
            0)
      << err;
  const auto audit = nlohmann::json::parse(ReadFileToString(tmp.Path("audit/report.json")));
  const auto& pairing = audit["pairing_attacks"];
  ASSERT_TRUE(pairing.contains("share_most_recovered_beyond_own")) << pairing.dump();
  EXPECT_LE(pairing["share_most_recovered_beyond_own"].get<double>(), 0.01) << pairing.dump();
  const Child loc = Start({"localize", "--map", out + ".lcm", "--image",
                           DataPath(kFountain + "/images/0010.jpg"), "--camera", kCamera},
                          "localize", tmp);
  ASSERT_EQ(Wait(loc), 0) << ReadFileToString(loc.err_path);
  EXPECT_TRUE(nlohmann::json::parse(ReadFileToString(loc.out_path))["success"].get<bool>());
}

// One key store, three projects: another survey whose photos have the same
// default names (Herz-Jesus-P8's 0000.jpg...) gets its own key; the same
// photos mapped again in another project find the first project's key (its
// photos' features), so one place never has two keys.
TEST(Map, ProjectsShareAKeyOnlyThroughTheirPhotos) {
  LINECLOUD_REQUIRE_DATA(kFountain);
  LINECLOUD_REQUIRE_DATA("strecha/Herz-Jesus-P8");
  TempDir tmp;
  auto map = [&](const std::string& scene, const std::string& name) {
    std::vector<std::string> args = {"map"};
    for (int k = 0; k <= 2; ++k)
      args.push_back(DataPath(fmt::format("{}/images/{:04d}.jpg", scene, k)));
    for (const std::string& a : std::vector<std::string>{
             "--project", tmp.Path(name), "--out", tmp.Path("maps/" + name), "--camera", kCamera,
             "--key-store", tmp.Path("keys"), "--no-audit", "--threads", "2"}) {
      args.push_back(a);
    }
    std::string err;
    EXPECT_EQ(RunToEnd(args, name, tmp, &err), 0) << err;
    return ReadLineCloud(tmp.Path("maps/" + name + ".lcm")).key_fingerprint;
  };
  const auto fountain = map(kFountain, "fountain");
  const auto herz_jesus = map("strecha/Herz-Jesus-P8", "herz_jesus");
  const auto fountain_again = map(kFountain, "fountain_again");
  EXPECT_NE(herz_jesus, fountain)
      << "a survey of other photos took the released map's key by names";
  EXPECT_EQ(fountain_again, fountain) << "the same photos in a second project got a second key";
}

// Interrupted in each stage, then the same command until it finishes: the
// lines equal an uninterrupted run's (the same key file).
void ExpectResumedRunEqualsUninterrupted(int sig) {
  LINECLOUD_REQUIRE_DATA(kFountain);
  TempDir tmp;
  const std::vector<std::string> photos = Photos(0, 3);
  std::string err;
  // One key for both runs, made beforehand: a key file new to a run's store
  // is lifted the same way in both (its lines the key's directions through
  // the points), so any difference in the model shows in the lines.
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/reconstruction");
  ASSERT_EQ(RunToEnd({"lift", "--model", DataPath("colmap-maupertuis/reconstruction"), "--out",
                      tmp.Path("key_maker.lcm"), "--key-file", tmp.Path("map.key"), "--key-store",
                      tmp.Path("key_maker_store")},
                     "key", tmp, &err),
            0)
      << err;
  ASSERT_EQ(
      RunToEnd(MapArgs(photos, tmp.Path("whole"), tmp.Path("maps1/m"), tmp), "whole", tmp, &err), 0)
      << err;
  const std::string reference = ReadFileToString(tmp.Path("maps1/m.lcm"));
  const std::vector<std::string> args = MapArgs(photos, tmp.Path("cut"), tmp.Path("maps2/m"), tmp);
  int interrupted = 0;
  for (const char* stage : {"features", "matches", "mapper", "lift", "audit"}) {
    const Child r = Start(args, fmt::format("cut_{}", stage), tmp);
    const bool sent = InterruptAt(r, fmt::format("[map] {} ...", stage), sig);
    const int code = Wait(r);
    if (sent && code != 0) {
      ++interrupted;
      EXPECT_FALSE(fs::exists(tmp.Path("maps2/m.lcm"))) << "a map served before its run ended";
    }
  }
  EXPECT_GE(interrupted, 3) << "the stages ran too fast to be interrupted";
  ASSERT_EQ(RunToEnd(args, "resumed", tmp, &err), 0) << err;
  const std::string resumed = ReadFileToString(tmp.Path("maps2/m.lcm"));
  if (resumed != reference) {
    const auto [a, b] =
        std::mismatch(resumed.begin(), resumed.end(), reference.begin(), reference.end());
    ADD_FAILURE() << "the resumed run's map differs from the uninterrupted run's from byte "
                  << (a - resumed.begin()) << " (sizes " << resumed.size() << ", "
                  << reference.size() << "); lines "
                  << ReadLineCloud(tmp.Path("maps2/m.lcm")).size() << " / "
                  << ReadLineCloud(tmp.Path("maps1/m.lcm")).size() << "\n"
                  << ReadFileToString(tmp.Path("cut/report.json")).substr(0, 600) << "\n"
                  << ReadFileToString(tmp.Path("whole/report.json")).substr(0, 600);
  }
}

TEST(Map, CtrlCInEachStageThenTheSameCommandEndsWithTheSameMap) {
  ExpectResumedRunEqualsUninterrupted(SIGINT);
}

TEST(Map, KilledInEachStageThenTheSameCommandEndsWithTheSameMap) {
  ExpectResumedRunEqualsUninterrupted(SIGKILL);
}

}  // namespace
}  // namespace linecloud
