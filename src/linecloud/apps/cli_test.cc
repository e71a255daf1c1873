// End-to-end tests of the `linecloud` command line, run in-process.
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include <gtest/gtest.h>

#include "linecloud/apps/commands.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/lifting/key.h"
#include "linecloud/io/json_util.h"
#include "linecloud/io/track_descriptors.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/privacy/audit_report.h"
#include "linecloud/privacy/two_key_attack.h"
#include "linecloud/synthetic/minimal_instances.h"
#include <nlohmann/json.hpp>
#include "linecloud/testing/test_util.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

using testing::DataPath;
using testing::TempDir;

// The pose of a result (its "q" and "t" among its other fields).
Rigid3d PoseIn(const nlohmann::json& result, const std::string& where) {
  return JsonPose({{"q", result.at("q")}, {"t", result.at("t")}}, where);
}

struct CliResult {
  int code;
  std::string out, err;
};

CliResult RunCli(std::vector<std::string> args) {
  args.insert(args.begin(), "linecloud");
  std::vector<const char*> argv;
  for (const std::string& a : args) argv.push_back(a.c_str());
  ::testing::internal::CaptureStdout();
  ::testing::internal::CaptureStderr();
  const int code = RunLinecloud(static_cast<int>(argv.size()), argv.data());
  CliResult r{code, ::testing::internal::GetCapturedStdout(),
              ::testing::internal::GetCapturedStderr()};
  return r;
}

// A failing command: non-zero, exactly one `error: ...` line mentioning `needle`.
void ExpectError(const CliResult& r, const std::string& needle) {
  EXPECT_NE(r.code, 0);
  EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
}

const std::string kMaupertuis = "colmap-maupertuis/reconstruction";

// No test touches the user's key store: LINECLOUD_KEY_STORE points into a
// temporary folder for the whole test binary (tests that check the store pass
// --key-store explicitly).
class KeyStoreEnvironment : public ::testing::Environment {
 public:
  void SetUp() override { ::setenv("LINECLOUD_KEY_STORE", dir_.Path("keys").c_str(), 1); }

 private:
  TempDir dir_;
};
[[maybe_unused]] ::testing::Environment* const kKeyStoreEnvironment =
    ::testing::AddGlobalTestEnvironment(new KeyStoreEnvironment);

// A key file with fixed bytes (tests never depend on a fresh random key).
std::string FixedKeyFile(const TempDir& tmp, const std::string& name, uint8_t seed,
                         DirectionSet directions = DirectionSet::kSphere) {
  LiftingKey::Bytes bytes;
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<uint8_t>(seed * 37 + i * 11);
  const std::string path = tmp.Path(name);
  WriteKeyFile(path, LiftingKey(bytes, directions));
  return path;
}

// The secret points of a line cloud's lines, in file order, through the key.
std::vector<Eigen::Vector3d> SecretPointsInFileOrder(const LineCloud& cloud, const LiftingKey& key,
                                                     const Reconstruction& rec) {
  std::vector<Eigen::Vector3d> out;
  for (const uint64_t line_id : cloud.ids)
    out.push_back(rec.points3D.at(PointIdOfLine(key, line_id)).xyz);
  return out;
}

// Every file the tool writes from one model, whatever the output path, run,
// options or encoding: intersecting any two recovers no point.
// [newcomer] The console's sources are not a console: `serve --web web/src`
// is refused at start, naming the folder to serve.
TEST(Cli, ServeRefusesTheConsolesSources) {
  TempDir tmp;
  std::filesystem::create_directories(tmp.Path("maps"));
  const CliResult r = RunCli({"serve", "--maps", tmp.Path("maps"), "--listen", "127.0.0.1:0",
                              "--web", std::string(LINECLOUD_REPO_DIR) + "/web/src"});
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("not a built console"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("build/web"), std::string::npos) << r.err;
}

// [newcomer] The help sends users to the repository's own docs (no SPEC.md in
// a clone) and names the overlay's colours as the picture draws them.
TEST(Cli, HelpPointsToTheRepositorysOwnDocs) {
  for (const char* command : {"localize", "solve"}) {
    const CliResult r = RunCli({command, "--help"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(r.out.find("SPEC.md"), std::string::npos) << command;
    EXPECT_NE(r.out.find("docs/formats.md"), std::string::npos) << command;
  }
  const CliResult localize = RunCli({"localize", "--help"});
  EXPECT_NE(localize.out.find("(sky blue)"), std::string::npos);
  EXPECT_EQ(localize.out.find("(green)"), std::string::npos);
}

TEST(Cli, EveryFileLiftedFromOneModelGivesOneLinePerPoint) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/colmap.db");
  TempDir tmp;
  const std::string model = DataPath(kMaupertuis);
  const std::string store = tmp.Path("keys");
  const auto lift = [&](std::vector<std::string> extra) {
    std::vector<std::string> args = {"lift", "--model", model, "--key-store", store};
    args.insert(args.end(), extra.begin(), extra.end());
    return RunCli(args);
  };
  // The model's key: a fixed key file, registered in the store by the first lift.
  CliResult r = lift({"--out", tmp.Path("a.lcm"), "--key-file", FixedKeyFile(tmp, "model.key", 1)});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_FALSE(FileExists(tmp.Path("a.lcm.key")));  // the key belongs to the model
  // Another path, another run, descriptors: the model's key again.
  r = lift({"--out", tmp.Path("b.lcm")});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("(key store)"), std::string::npos) << r.out;
  EXPECT_EQ(ReadFileToString(tmp.Path("a.lcm")), ReadFileToString(tmp.Path("b.lcm")));
  ASSERT_EQ(lift({"--out", tmp.Path("d.lcm"), "--database", DataPath("colmap-maupertuis/colmap.db"),
                  "--descriptor", "mean"})
                .code,
            0);
  // The compact encoding would need other directions: refused, nothing written.
  ExpectError(lift({"--out", tmp.Path("c.lcm"), "--compact"}), "second line through every point");
  EXPECT_FALSE(FileExists(tmp.Path("c.lcm")));
  // A new key file for a known model: refused, and not left behind.
  ExpectError(lift({"--out", tmp.Path("e.lcm"), "--key-file", tmp.Path("new.key")}),
              "was lifted before with the key");
  EXPECT_FALSE(FileExists(tmp.Path("new.key")));
  EXPECT_FALSE(FileExists(tmp.Path("e.lcm")));
  // The store's subset test: a copy of the model without a quarter of its
  // points (a map for evaluation) is the same model.
  Reconstruction rec = ReadColmapModel(model);
  Reconstruction subset = rec;
  for (const uint64_t id : rec.SortedPoint3DIds()) {
    if (id % 4 == 0) subset.points3D.erase(id);
  }
  for (auto& [image_id, image] : subset.images) {
    for (Point2D& p : image.points2D) {
      if (p.point3D_id != kInvalidPoint3DId && !subset.points3D.count(p.point3D_id)) {
        p.point3D_id = kInvalidPoint3DId;
      }
    }
  }
  WriteColmapModel(subset, tmp.Path("subset"), ModelFormat::kBinary);
  r = RunCli(
      {"lift", "--model", tmp.Path("subset"), "--key-store", store, "--out", tmp.Path("s.lcm")});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("(key store)"), std::string::npos) << r.out;

  const std::vector<std::string> files = {"a.lcm", "b.lcm", "d.lcm", "s.lcm"};
  for (size_t i = 0; i < files.size(); ++i) {
    for (size_t j = i + 1; j < files.size(); ++j) {
      const TwoLiftingsAttack attack = IntersectLinesOfEqualId(ReadLineCloud(tmp.Path(files[i])),
                                                               ReadLineCloud(tmp.Path(files[j])));
      EXPECT_GT(attack.shared_ids, 700u) << files[i] << " x " << files[j];
      EXPECT_EQ(attack.points.size(), 0u) << files[i] << " x " << files[j];
    }
  }

  // Forced past every guard, a second key gives the points back: the attack
  // above could have found them.
  ASSERT_EQ(lift({"--out", tmp.Path("forced.lcm"), "--key-file", FixedKeyFile(tmp, "other.key", 2),
                  "--force"})
                .code,
            0);
  const LiftingKey first = ReadKeyFile(tmp.Path("model.key"));
  const LiftingKey other = ReadKeyFile(tmp.Path("other.key"));
  // The attacker needs equal ids: relabel the forced file's lines with the
  // first key's line ids (what an insider with both keys could publish).
  LineCloud forced = ReadLineCloud(tmp.Path("forced.lcm"));
  for (uint64_t& id : forced.ids) id = LineIdOfPoint(first, PointIdOfLine(other, id));
  const LineCloud a = ReadLineCloud(tmp.Path("a.lcm"));
  const TwoLiftingsAttack attack = IntersectLinesOfEqualId(a, forced);
  ASSERT_EQ(attack.shared_ids, 1039u);
  size_t exact = 0;
  for (size_t k = 0; k < attack.ids.size(); ++k) {
    const Eigen::Vector3d& x = rec.points3D.at(PointIdOfLine(first, attack.ids[k])).xyz;
    exact += (attack.points[k] - x).norm() <= 1e-6 * std::max(1.0, x.norm());
  }
  EXPECT_GE(exact, 1038u);  // ≥ 99.9 %
  // No coordinate of the model in the file's bytes, as float64 or float32.
  std::vector<Eigen::Vector3d> xyz;
  for (const auto& [id, p] : rec.points3D) xyz.push_back(p.xyz);
  testing::ExpectNoCoordinates(ReadFileToString(tmp.Path("a.lcm")), xyz);
}

// A model first lifted --compact has a compact256 key: its full and compact
// files hold the same lines, bit for bit.
TEST(Cli, ACompactKeyGivesTheSameLinesInBothEncodings) {
  LINECLOUD_REQUIRE_DATA(kMaupertuis);
  TempDir tmp;
  const std::string model = DataPath(kMaupertuis);
  // A --key-file that does not exist yet is created there (0600) with the
  // direction set the first lift asks for (structure only: any key's lines agree).
  CliResult r = RunCli({"lift", "--model", model, "--key-store", tmp.Path("keys0"), "--key-file",
                        tmp.Path("created.key"), "--out", tmp.Path("c0.lcm"), "--compact"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("(new key file)"), std::string::npos) << r.out;
  EXPECT_EQ(
      std::filesystem::status(tmp.Path("created.key")).permissions() & std::filesystem::perms::all,
      std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  EXPECT_EQ(ReadKeyFile(tmp.Path("created.key")).directions(), DirectionSet::kCompact256);

  const std::string key_file = FixedKeyFile(tmp, "model.key", 3, DirectionSet::kCompact256);
  r = RunCli({"lift", "--model", model, "--key-store", tmp.Path("keys"), "--key-file", key_file,
              "--out", tmp.Path("c.lcm"), "--compact"});
  ASSERT_EQ(r.code, 0) << r.err;
  // Without --key-file, the store knows the model's key file.
  r = RunCli(
      {"lift", "--model", model, "--key-store", tmp.Path("keys"), "--out", tmp.Path("f.lcm")});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find(key_file), std::string::npos) << r.out;
  const LineCloud c = ReadLineCloud(tmp.Path("c.lcm"));
  const LineCloud f = ReadLineCloud(tmp.Path("f.lcm"));
  EXPECT_EQ(c.encoding, LineEncoding::kCompact);
  EXPECT_EQ(f.encoding, LineEncoding::kPlucker);
  ASSERT_EQ(c.ids, f.ids);
  for (size_t i = 0; i < c.size(); ++i) {
    ASSERT_EQ(c.lines[i].v, f.lines[i].v);
    ASSERT_EQ(c.lines[i].w, f.lines[i].w);
  }
  EXPECT_TRUE(IntersectLinesOfEqualId(c, f).points.empty());
  const Reconstruction rec = ReadColmapModel(model);
  const std::vector<Eigen::Vector3d> x = SecretPointsInFileOrder(c, ReadKeyFile(key_file), rec);
  for (size_t i = 0; i < c.size(); ++i) ASSERT_LT(c.lines[i].DistanceTo(x[i]) / x[i].norm(), 1e-6);
}

// COLMAP numbers points in triangulation order, so consecutive point ids are
// often neighbours in space; line ids and file order must not be.
TEST(Cli, LineOrderCarriesNoNeighbourhoodSignal) {
  LINECLOUD_REQUIRE_DATA(kMaupertuis);
  TempDir tmp;
  const std::string model = DataPath(kMaupertuis);
  ASSERT_EQ(RunCli({"lift", "--model", model, "--key-store", tmp.Path("keys"), "--key-file",
                    FixedKeyFile(tmp, "k.key", 4), "--out", tmp.Path("m.lcm")})
                .code,
            0);
  const Reconstruction rec = ReadColmapModel(model);
  const LineCloud cloud = ReadLineCloud(tmp.Path("m.lcm"));
  // Rate at which item i+1 is among the 10 nearest neighbours of item i.
  const auto successor_rate = [](const std::vector<Eigen::Vector3d>& x) {
    size_t hits = 0;
    for (size_t i = 0; i + 1 < x.size(); ++i) {
      std::vector<double> d;
      for (size_t j = 0; j < x.size(); ++j) {
        if (j != i) d.push_back((x[j] - x[i]).squaredNorm());
      }
      std::nth_element(d.begin(), d.begin() + 9, d.end());
      hits += (x[i + 1] - x[i]).squaredNorm() <= d[9];
    }
    return static_cast<double>(hits) / (x.size() - 1);
  };
  std::vector<Eigen::Vector3d> by_point_id;
  for (const uint64_t id : rec.SortedPoint3DIds()) by_point_id.push_back(rec.points3D.at(id).xyz);
  const double chance = 10.0 / (rec.points3D.size() - 1);
  const double point_order = successor_rate(by_point_id);
  const double line_order =
      successor_rate(SecretPointsInFileOrder(cloud, ReadKeyFile(tmp.Path("k.key")), rec));
  std::cout << "[ neighbour successors ] point-id order " << point_order << ", line order "
            << line_order << ", chance " << chance << "\n";
  EXPECT_GT(point_order, 5 * chance);   // the side channel exists in raw ids
  EXPECT_LT(line_order, 2.5 * chance);  // ~10 expected hits of 1038; 2.5× is > 4σ
}

// The README's newcomer path on a real COLMAP project: lift with
// descriptors, a query from one of the model's images, localize it against
// the line cloud (p6L) and the point model (p3P).
TEST(Cli, NewcomerPathOnARealModel) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/colmap.db");
  TempDir tmp;
  const std::string model = DataPath(kMaupertuis);
  const std::string store = tmp.Path("keys");
  ASSERT_EQ(RunCli({"lift", "--model", model, "--database", DataPath("colmap-maupertuis/colmap.db"),
                    "--out", tmp.Path("m.lcm"), "--key-store", store, "--key-file",
                    FixedKeyFile(tmp, "m.key", 8)})
                .code,
            0);
  // [newcomer] --quiet: one line, and a second only for a new key (keep it secret).
  CliResult quiet = RunCli({"lift", "--model", model, "--out", tmp.Path("quiet.lcm"), "--key-store",
                            tmp.Path("quiet-keys"), "--quiet"});
  ASSERT_EQ(quiet.code, 0) << quiet.err;
  EXPECT_EQ(std::count(quiet.out.begin(), quiet.out.end(), '\n'), 2) << quiet.out;
  EXPECT_NE(quiet.out.find("new key"), std::string::npos) << quiet.out;
  // A second key store gives the model a second key: the line says what to do instead.
  EXPECT_NE(quiet.out.find("lifted before with another key store, use that key instead"),
            std::string::npos)
      << quiet.out;
  quiet = RunCli({"lift", "--model", model, "--out", tmp.Path("quiet.lcm"), "--key-store",
                  tmp.Path("quiet-keys"), "--quiet"});
  EXPECT_EQ(std::count(quiet.out.begin(), quiet.out.end(), '\n'), 1) << quiet.out;
  EXPECT_TRUE(quiet.err.empty()) << quiet.err;
  // Before the model is lifted, no key: a clear error.
  ExpectError(RunCli({"make-query", "--model", model, "--image", "02.jpg", "--out",
                      tmp.Path("q.json"), "--key-store", tmp.Path("empty")}),
              "has no key for this model");
  ExpectError(RunCli({"make-query", "--model", model, "--image", "nope.jpg", "--out",
                      tmp.Path("q.json"), "--key-store", store}),
              "no image named 'nope.jpg'");
  CliResult r = RunCli({"make-query", "--model", model, "--image", "02.jpg", "--out",
                        tmp.Path("q.json"), "--key-store", store});
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json q = ReadJsonFile(tmp.Path("q.json"));
  const Rigid3d reference = JsonPose(q["reference"]["cam_from_world"], "reference");
  for (const auto& [method, flag, map] :
       {std::tuple{"p6L", "--map", tmp.Path("m.lcm")}, std::tuple{"p3P", "--model", model}}) {
    r = RunCli({"localize", flag, map, "--query", tmp.Path("q.json"), "--method", method});
    ASSERT_EQ(r.code, 0) << r.err;
    const nlohmann::json result = nlohmann::json::parse(r.out);
    ASSERT_TRUE(result["success"].get<bool>()) << method << r.out;
    const Rigid3d estimate = PoseIn(result, "result");
    std::cout << "[ " << method << " on maupertuis 02.jpg ] "
              << RotationDistance(estimate.rotation, reference.rotation) * 180 / 3.14159
              << " deg from COLMAP's pose\n";
    EXPECT_LT(RotationDistance(estimate.rotation, reference.rotation), 0.1 * 3.14159 / 180)
        << method;
    EXPECT_GT(result["num_inliers"].get<int>(), 900) << method;
  }
  // Without --method: p6L on a line cloud, p3P on a point model.
  for (const auto& [flag, map, expected] :
       {std::tuple{"--map", tmp.Path("m.lcm"), "p6L"}, std::tuple{"--model", model, "p3P"}}) {
    r = RunCli({"localize", flag, map, "--query", tmp.Path("q.json")});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(nlohmann::json::parse(r.out)["method"].get<std::string>(), expected);
  }
}

// localize --image on bad input: one clear error line each; a photo that
// gives too few matches is "success": false, not an error.
TEST(Cli, LocalizeImageRejectsBadInput) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/images/02.jpg");
  TempDir tmp;
  const std::string model = DataPath(kMaupertuis);
  const std::string photo = DataPath("colmap-maupertuis/images/02.jpg");
  ASSERT_EQ(RunCli({"lift", "--model", model, "--database", DataPath("colmap-maupertuis/colmap.db"),
                    "--out", tmp.Path("m.lcm"), "--key-store", tmp.Path("keys"), "--key-file",
                    FixedKeyFile(tmp, "m.key", 9)})
                .code,
            0);
  ASSERT_EQ(RunCli({"lift", "--model", model, "--out", tmp.Path("bare.lcm"), "--key-store",
                    tmp.Path("keys")})
                .code,
            0);
  const std::string camera = "SIMPLE_PINHOLE 1919 1079 1847.53 959.5 539.5";
  const auto localize = [&](const std::string& map, const std::string& image,
                            const std::string& cam, std::vector<std::string> extra = {}) {
    std::vector<std::string> args = {"localize",         "--map", map,        "--image", image,
                                     "--camera",         cam,     "--method", "p6L",     "--quiet",
                                     "--max-image-size", "480"};
    args.insert(args.end(), extra.begin(), extra.end());
    return RunCli(args);
  };
  ExpectError(localize(tmp.Path("m.lcm"), tmp.Path("missing.jpg"), camera), "missing.jpg");
  std::ofstream(tmp.Path("text.jpg")) << "not an image at all\n";
  ExpectError(localize(tmp.Path("m.lcm"), tmp.Path("text.jpg"), camera), "text.jpg");
  const std::string bytes = ReadFileToString(photo);
  std::ofstream(tmp.Path("cut.jpg"), std::ios::binary).write(bytes.data(), 300);
  const CliResult cut = localize(tmp.Path("m.lcm"), tmp.Path("cut.jpg"), camera);
  EXPECT_TRUE(cut.code != 0 || cut.out.find("\"success\": false") != std::string::npos) << cut.err;
  ExpectError(localize(tmp.Path("m.lcm"), photo, "PINHOLE 1919 1079 1 2 3"),
              "PINHOLE takes 4 parameters, got 3");
  ExpectError(localize(tmp.Path("m.lcm"), photo, "FISHEYE_X 1919 1079 1 2 3"),
              "unknown camera model 'FISHEYE_X'");
  // [newcomer] A line pasted from cameras.txt, its id first.
  ExpectError(localize(tmp.Path("m.lcm"), photo, "1 PINHOLE 1919 1079 1000 1000 959 539"),
              "drop the id ('PINHOLE ...')");
  ExpectError(localize(tmp.Path("m.lcm"), photo, "SIMPLE_PINHOLE 640 480 500 320 240"),
              "the image is 1919x1079 pixels but the camera is 640x480");
  ExpectError(localize(tmp.Path("bare.lcm"), photo, camera),
              "lift it with the model's COLMAP database");
  ExpectError(RunCli({"localize", "--map", tmp.Path("m.lcm"), "--image", photo, "--method", "p6L"}),
              "--image needs --camera");
  ExpectError(RunCli({"localize", "--map", tmp.Path("m.lcm"), "--image", photo, "--query",
                      tmp.Path("q.json"), "--camera", camera, "--method", "p6L"}),
              "exactly one of --query");
  // Several photos: a rig file and an m- method are needed, with as many poses.
  const std::string photo2 = DataPath("colmap-maupertuis/images/03.jpg");
  ExpectError(RunCli({"localize", "--map", tmp.Path("m.lcm"), "--image", photo, "--image", photo2,
                      "--camera", camera, "--method", "m-p6L"}),
              "need --rig RIG.json");
  std::ofstream(tmp.Path("rig1.json"))
      << R"({"cam_from_rig": [{"q": [1, 0, 0, 0], "t": [0, 0, 0]}]})";
  ExpectError(RunCli({"localize", "--map", tmp.Path("m.lcm"), "--image", photo, "--image", photo2,
                      "--camera", camera, "--rig", tmp.Path("rig1.json"), "--method", "p6L"}),
              "use an m- method");
  ExpectError(RunCli({"localize", "--map", tmp.Path("m.lcm"), "--image", photo, "--image", photo2,
                      "--camera", camera, "--rig", tmp.Path("rig1.json"), "--quiet",
                      "--max-image-size", "480"}),
              "2 photos but 1 cam_from_rig poses");
  ExpectError(RunCli({"localize", "--map", tmp.Path("m.lcm"), "--image", photo, "--image", photo2,
                      "--camera", camera, "--camera", camera, "--camera", camera, "--rig",
                      tmp.Path("rig1.json")}),
              "2 photos but 3 --camera strings");
  // A ratio test no match passes: ran fine, no pose.
  const CliResult none = localize(tmp.Path("m.lcm"), photo, camera,
                                  {"--max-ratio", "0.05", "--overlay", tmp.Path("o.png")});
  ASSERT_EQ(none.code, 0) << none.err;
  const nlohmann::json j = nlohmann::json::parse(none.out);
  EXPECT_FALSE(j["success"].get<bool>());
  EXPECT_NE(j["reason"].get<std::string>().find("matches"), std::string::npos) << none.out;
  EXPECT_GT(j["num_features"].get<int>(), 100);
  EXPECT_TRUE(j["times_ms"].contains("extract"));
  // The approximate index (forced on this small map): same kind of result,
  // and the index cached for the next photo in the user's cache folder (never
  // beside the map, where others may plant a link or a FIFO).
  ::setenv("XDG_CACHE_HOME", tmp.Path("cache").c_str(), 1);
  const std::string cache_dir = tmp.Path("cache/linecloud/index");
  int first_matches = -1;
  for (int run = 0; run < 2; ++run) {
    const CliResult ann = localize(tmp.Path("m.lcm"), photo, camera, {"--approximate-from", "10"});
    ASSERT_EQ(ann.code, 0) << ann.err;
    const int matches = nlohmann::json::parse(ann.out)["num_matches"].get<int>();
    EXPECT_GT(matches, 0);
    if (run == 1) {
      EXPECT_EQ(matches, first_matches);  // the cached index: the same matches
    }
    first_matches = matches;
    EXPECT_FALSE(FileExists(tmp.Path("m.lcm.index")));
    size_t cached = 0;
    for (const auto& e : std::filesystem::directory_iterator(cache_dir)) {
      cached += e.path().extension() == ".index";
    }
    EXPECT_EQ(cached, 1u);
    EXPECT_EQ(std::filesystem::status(cache_dir).permissions() & std::filesystem::perms::all,
              std::filesystem::perms::owner_all);
  }
  ::unsetenv("XDG_CACHE_HOME");
  ExpectError(localize(tmp.Path("m.lcm"), photo, camera, {"--features", "vlfeat"}),
              "--features: features must be one of colmap, opencv, got \"vlfeat\"");
  ExpectError(
      localize(tmp.Path("m.lcm"), photo, camera, {"--index", "annoy"}),
      "--index: index must be one of ivf, faiss-ivf, faiss-hnsw, hnswlib, flann, got \"annoy\"");
  // The overlay is the photo's size (PNG header: width and height, big-endian).
  const std::string png = ReadFileToString(tmp.Path("o.png"));
  ASSERT_GT(png.size(), 24u);
  EXPECT_EQ(png.substr(1, 3), "PNG");
  const auto be32 = [&](size_t at) {
    return (uint32_t(uint8_t(png[at])) << 24) | (uint32_t(uint8_t(png[at + 1])) << 16) |
           (uint32_t(uint8_t(png[at + 2])) << 8) | uint32_t(uint8_t(png[at + 3]));
  };
  EXPECT_EQ(be32(16), 1919u);
  EXPECT_EQ(be32(20), 1079u);
  ASSERT_EQ(RunCli({"make-query", "--model", model, "--image", "02.jpg", "--out",
                    tmp.Path("q.json"), "--key-file", tmp.Path("m.key")})
                .code,
            0);
  ExpectError(RunCli({"localize", "--map", tmp.Path("m.lcm"), "--query", tmp.Path("q.json"),
                      "--method", "p6L", "--overlay", tmp.Path("o2.png")}),
              "--overlay draws on one photo: it needs exactly one --image");
  EXPECT_FALSE(FileExists(tmp.Path("o2.png")));
}

// lift --gravity stores the map's gravity; info shows it; a +u query
// without gravity_map takes it from the map, with the query's from --gravity.
TEST(Cli, MapGravityFromLiftToLocalize) {
  TempDir tmp;
  const std::string demo = tmp.Path("demo");
  ASSERT_EQ(RunCli({"demo", "--out", demo, "--points", "1500", "--queries", "2"}).code, 0);
  nlohmann::json q = ReadJsonFile(demo + "/queries/query_000.json");
  const Eigen::Vector3d g_map = JsonVector3(q["gravity_map"], "gravity_map");
  const Eigen::Vector3d g_query = JsonVector3(q["gravity_query"], "gravity_query");
  q.erase("gravity_map");
  q.erase("gravity_query");
  std::ofstream(tmp.Path("q.json")) << q.dump();
  const auto csv = [](const Eigen::Vector3d& v) {
    return fmt::format("{:.17g},{:.17g},{:.17g}", v.x(), v.y(), v.z());
  };
  ExpectError(RunCli({"lift", "--model", demo + "/model", "--out", tmp.Path("m.lcm"), "--key-store",
                      tmp.Path("keys"), "--gravity", "1,2"}),
              "--gravity: gravity must be a finite non-zero direction [x, y, z] (\"x,y,z\" as "
              "text) or null, got \"1,2\"");
  ASSERT_EQ(RunCli({"lift", "--model", demo + "/model", "--out", tmp.Path("m.lcm"), "--key-store",
                    tmp.Path("keys"), "--key-file", FixedKeyFile(tmp, "g.key", 10), "--gravity",
                    csv(3 * g_map)})
                .code,
            0);
  const LineCloud cloud = ReadLineCloud(tmp.Path("m.lcm"));
  ASSERT_TRUE(cloud.gravity.has_value());
  EXPECT_LT((*cloud.gravity - g_map.normalized()).norm(), 1e-12);
  EXPECT_NE(RunCli({"info", "--map", tmp.Path("m.lcm")}).out.find("gravity           ("),
            std::string::npos);
  // The demo's file carries the demo key's line ids: the ones of this map's key instead.
  nlohmann::json with_lines = q;
  const LiftingKey key = ReadKeyFile(tmp.Path("g.key"));
  for (auto& o : with_lines["observations"])
    o["line_id"] = LineIdOfPoint(key, o["id"].get<uint64_t>());
  std::ofstream(tmp.Path("q.json")) << with_lines.dump();
  ExpectError(RunCli({"localize", "--map", tmp.Path("m.lcm"), "--query", tmp.Path("q.json"),
                      "--method", "p4L+u"}),
              "gravity");
  const CliResult r = RunCli({"localize", "--map", tmp.Path("m.lcm"), "--query", tmp.Path("q.json"),
                              "--method", "p4L+u", "--gravity", csv(g_query)});
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json result = nlohmann::json::parse(r.out);
  ASSERT_TRUE(result["success"].get<bool>()) << r.out;
  const Rigid3d truth = JsonPose(q["ground_truth"]["cam_from_world"], "truth");
  EXPECT_LT(RotationDistance(PoseIn(result, "result").rotation, truth.rotation),
            0.2 * 3.14159 / 180);
}

TEST(Cli, LiftRefusesToReplaceAMapWithOtherLines) {
  LINECLOUD_REQUIRE_DATA(kMaupertuis);
  TempDir tmp;
  const std::string model = DataPath(kMaupertuis);
  const std::string store = tmp.Path("keys");
  ASSERT_EQ(
      RunCli({"lift", "--model", model, "--key-store", store, "--out", tmp.Path("m.lcm")}).code, 0);
  const std::string before = ReadFileToString(tmp.Path("m.lcm"));
  // Another key over the map: refused (the store knows the model too: --force
  // passes that guard, not the map's).
  ExpectError(RunCli({"lift", "--model", model, "--key-store", tmp.Path("keys2"), "--out",
                      tmp.Path("m.lcm"), "--key-file", FixedKeyFile(tmp, "other.key", 5)}),
              "another key");
  EXPECT_EQ(ReadFileToString(tmp.Path("m.lcm")), before);
  // Re-lifting without --key-file reuses the model's key: the same bytes.
  ASSERT_EQ(
      RunCli({"lift", "--model", model, "--key-store", store, "--out", tmp.Path("m.lcm")}).code, 0);
  EXPECT_EQ(ReadFileToString(tmp.Path("m.lcm")), before);

  // A version-1 compact map lifted (before direction sets) under a sphere key:
  // its lines differ from the key's full lines, so it is not replaced.
  const Reconstruction rec = ReadColmapModel(model);
  std::vector<uint64_t> ids = rec.SortedPoint3DIds();
  std::vector<Eigen::Vector3d> xyz;
  for (const uint64_t id : ids) xyz.push_back(rec.points3D.at(id).xyz);
  const LiftingKey sphere = ReadKeyFile(FixedKeyFile(tmp, "sphere.key", 6));
  LiftingKey as_compact(sphere.bytes(), DirectionSet::kCompact256);
  LineCloud old = LiftPoints(ids, xyz, as_compact, {LineEncoding::kCompact});
  old.key_fingerprint = sphere.Fingerprint();
  old.keyed_line_ids = false;
  for (uint64_t& id : old.ids) id = PointIdOfLine(as_compact, id);
  WriteLineCloud(old, tmp.Path("old.lcm"));
  const std::string old_bytes = ReadFileToString(tmp.Path("old.lcm"));
  ExpectError(RunCli({"lift", "--model", model, "--key-store", tmp.Path("keys3"), "--out",
                      tmp.Path("old.lcm"), "--key-file", tmp.Path("sphere.key")}),
              "other lines through the same points");
  EXPECT_EQ(ReadFileToString(tmp.Path("old.lcm")), old_bytes);
  EXPECT_EQ(ReadLineCloud(tmp.Path("old.lcm")).keyed_line_ids, false);  // version 1 still read
}

TEST(Cli, LiftWithDescriptorsCompactInfoAndExport) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/colmap.db");
  TempDir tmp;
  const std::string model = DataPath(kMaupertuis);
  CliResult r =
      RunCli({"lift", "--model", model, "--out", tmp.Path("d.lcm"), "--database",
              DataPath("colmap-maupertuis/colmap.db"), "--compact", "--key-store", tmp.Path("keys"),
              "--key-file", FixedKeyFile(tmp, "d.key", 7, DirectionSet::kCompact256)});
  ASSERT_EQ(r.code, 0) << r.err;
  const LineCloud cloud = ReadLineCloud(tmp.Path("d.lcm"));
  EXPECT_EQ(cloud.encoding, LineEncoding::kCompact);
  EXPECT_EQ(cloud.descriptor_dim, 128);
  EXPECT_EQ(cloud.descriptor_aggregation, "medoid");
  const Reconstruction rec = ReadColmapModel(model);
  const LiftingKey key = ReadKeyFile(tmp.Path("d.key"));
  const std::vector<Eigen::Vector3d> x = SecretPointsInFileOrder(cloud, key, rec);
  for (size_t i = 0; i < cloud.size(); ++i) {
    ASSERT_LT(cloud.lines[i].DistanceTo(x[i]) / x[i].norm(), 1e-6);
  }
  // Descriptors follow their lines into line-id order.
  const ColmapDatabase db(DataPath("colmap-maupertuis/colmap.db"));
  const std::vector<uint64_t> ids = rec.SortedPoint3DIds();
  const PointDescriptors d = ComputePointDescriptors(rec, ids, db, DescriptorAggregation::kMedoid);
  for (size_t k = 0; k < cloud.size(); k += 97) {
    const uint64_t point_id = PointIdOfLine(key, cloud.ids[k]);
    const size_t row = std::lower_bound(ids.begin(), ids.end(), point_id) - ids.begin();
    ASSERT_TRUE(std::equal(cloud.descriptor(k).begin(), cloud.descriptor(k).end(),
                           d.data.begin() + row * 128));
  }
  r = RunCli({"info", tmp.Path("d.lcm")});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("1039"), std::string::npos);
  EXPECT_NE(r.out.find("compact-256-f32"), std::string::npos);
  EXPECT_NE(r.out.find("128-D"), std::string::npos);
  r = RunCli({"info", tmp.Path("d.lcm"), "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("\"num_lines\": 1039"), std::string::npos);

  r = RunCli({"export", "--map", tmp.Path("d.lcm"), "--ply", tmp.Path("lines.ply")});
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string ply = ReadFileToString(tmp.Path("lines.ply"));
  EXPECT_EQ(ply.rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u);
  EXPECT_NE(ply.find("element vertex 2078\n"), std::string::npos);
  EXPECT_NE(ply.find("element edge 1039\n"), std::string::npos);
  const size_t header_end = ply.find("end_header\n") + 11;
  EXPECT_EQ(ply.size() - header_end, 2078 * 12 + 1039 * 8);
  r = RunCli({"export", "--model", model, "--ply", tmp.Path("points.ply")});
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string pts = ReadFileToString(tmp.Path("points.ply"));
  EXPECT_EQ(pts.size() - (pts.find("end_header\n") + 11), 1039u * 15);
}

TEST(Cli, BadInputGivesOneErrorLineAndNoOutput) {
  TempDir tmp;
  ExpectError(RunCli({"lift", "--model", tmp.Path("nowhere"), "--out", tmp.Path("x.lcm")}),
              "nowhere");
  EXPECT_FALSE(FileExists(tmp.Path("x.lcm")));
  EXPECT_FALSE(FileExists(tmp.Path("x.lcm.key")));  // no key left behind

  // Unknown camera model.
  std::filesystem::create_directories(tmp.Path("m"));
  std::ofstream(tmp.Path("m/cameras.txt")) << "1 THIN_PRISM_FISHEYE 10 10 1 2 3\n";
  std::ofstream(tmp.Path("m/images.txt")) << "";
  std::ofstream(tmp.Path("m/points3D.txt")) << "";
  ExpectError(RunCli({"lift", "--model", tmp.Path("m"), "--out", tmp.Path("x.lcm")}),
              "THIN_PRISM_FISHEYE");
  // NaN coordinates.
  std::ofstream(tmp.Path("m/cameras.txt")) << "1 PINHOLE 10 10 5 5 5 5\n";
  std::ofstream(tmp.Path("m/points3D.txt")) << "1 1 nan 3 0 0 0 0\n";
  ExpectError(RunCli({"lift", "--model", tmp.Path("m"), "--out", tmp.Path("x.lcm")}),
              "points3D.txt:1");
  // Truncated binary model.
  std::ofstream(tmp.Path("m/points3D.txt")) << "1 1 2 3 0 0 0 0\n";
  ASSERT_EQ(RunCli({"lift", "--model", tmp.Path("m"), "--out", tmp.Path("ok.lcm")}).code, 0);
  const Reconstruction rec = ReadColmapModel(tmp.Path("m"));
  WriteColmapModel(rec, tmp.Path("b"), ModelFormat::kBinary);
  const std::string pts = ReadFileToString(tmp.Path("b/points3D.bin"));
  std::ofstream(tmp.Path("b/points3D.bin"), std::ios::binary).write(pts.data(), pts.size() - 3);
  ExpectError(RunCli({"lift", "--model", tmp.Path("b"), "--out", tmp.Path("x.lcm")}), "truncated");
  EXPECT_FALSE(FileExists(tmp.Path("x.lcm")));
  // Malformed key.
  std::ofstream(tmp.Path("bad.key")) << "not a key\n";
  ExpectError(RunCli({"lift", "--model", tmp.Path("m"), "--out", tmp.Path("x.lcm"), "--key-file",
                      tmp.Path("bad.key")}),
              "bad.key");
  EXPECT_FALSE(FileExists(tmp.Path("x.lcm")));
  // Corrupt and truncated maps.
  std::string map = ReadFileToString(tmp.Path("ok.lcm"));
  std::ofstream(tmp.Path("cut.lcm"), std::ios::binary).write(map.data(), map.size() - 40);
  ExpectError(RunCli({"info", tmp.Path("cut.lcm")}), "cut.lcm");
  map[map.size() / 2] ^= 0x40;
  std::ofstream(tmp.Path("flip.lcm"), std::ios::binary).write(map.data(), map.size());
  ExpectError(RunCli({"export", "--map", tmp.Path("flip.lcm"), "--ply", tmp.Path("o.ply")}),
              "checksum");
  EXPECT_FALSE(FileExists(tmp.Path("o.ply")));
  ExpectError(RunCli({"info", tmp.Path("missing.lcm")}), "missing.lcm");
  // Database that is not one.
  std::ofstream(tmp.Path("fake.db")) << "hello";
  ExpectError(RunCli({"lift", "--model", tmp.Path("m"), "--out", tmp.Path("x.lcm"), "--database",
                      tmp.Path("fake.db")}),
              "fake.db");
  // Usage errors.
  ExpectError(RunCli({"lift", "--out", tmp.Path("x.lcm")}), "--model");
  ExpectError(RunCli({"export", "--ply", tmp.Path("o.ply")}), "--map or --model");
  ExpectError(RunCli({"frobnicate"}), "frobnicate");
  EXPECT_EQ(RunCli({"lift", "--help"}).code, 0);
}

// A tiny demo scene, whose queries see fewer points than some samples need,
// still runs and says why those queries have no pose.
TEST(Cli, ATinyDemoSaysWhyQueriesHaveNoPose) {
  TempDir tmp;
  const CliResult r = RunCli(
      {"demo", "--out", tmp.Path("d"), "--points", "500", "--images", "6", "--queries", "2"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("no pose: p6L query_000: method p6L needs at least 6 observations"),
            std::string::npos)
      << r.out;
}

TEST(Cli, DemoIsReproducibleAndItsFilesDoNotIntersect) {
  TempDir tmp;
  CliResult r = RunCli(
      {"demo", "--out", tmp.Path("demo"), "--points", "800", "--images", "8", "--queries", "2"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("built-in public demo key"), std::string::npos);
  EXPECT_NE(r.out.find("lines differing between the two files: 0"), std::string::npos) << r.out;
  const std::string first = ReadFileToString(tmp.Path("demo/map.lcm"));
  r = RunCli(
      {"demo", "--out", tmp.Path("demo2"), "--points", "800", "--images", "8", "--queries", "2"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(ReadFileToString(tmp.Path("demo2/map.lcm")), first);  // same lines every run
  EXPECT_TRUE(FileExists(tmp.Path("demo/queries/query_001.json")));
  const Reconstruction rec = ReadColmapModel(tmp.Path("demo/model"));
  EXPECT_GT(rec.points3D.size(), 100u);
  // Every pair of line clouds the demo writes, across both runs.
  const std::vector<std::string> maps = {"demo/map.lcm", "demo/map_compact.lcm", "demo2/map.lcm",
                                         "demo2/map_compact.lcm"};
  for (size_t i = 0; i < maps.size(); ++i) {
    for (size_t j = i + 1; j < maps.size(); ++j) {
      const TwoLiftingsAttack attack = IntersectLinesOfEqualId(ReadLineCloud(tmp.Path(maps[i])),
                                                               ReadLineCloud(tmp.Path(maps[j])));
      EXPECT_EQ(attack.shared_ids, rec.points3D.size());
      EXPECT_EQ(attack.points.size(), 0u) << maps[i] << " x " << maps[j];
    }
  }
}

TEST(Cli, SolveReturnsTheTruePoseForEveryImplementedMethod) {
  TempDir tmp;
  std::mt19937_64 rng(77);
  for (const MethodInfo& m : AllMethods()) {
    if (!m.implemented) continue;
    const MinimalInstance inst = RandomMinimalInstance(m, rng);
    nlohmann::json j;
    j["method"] = std::string(m.name);
    const auto list = [](const std::vector<Eigen::Vector3d>& v) {
      nlohmann::json a = nlohmann::json::array();
      for (const auto& x : v) a.push_back({x.x(), x.y(), x.z()});
      return a;
    };
    if (!inst.sample.bearings.empty()) j["bearings"] = list(inst.sample.bearings);
    if (!inst.sample.points.empty()) j["points"] = list(inst.sample.points);
    if (!inst.sample.points_local.empty()) j["points_local"] = list(inst.sample.points_local);
    if (!inst.sample.lines.empty()) {
      j["lines"] = nlohmann::json::array();
      for (const auto& l : inst.sample.lines) {
        j["lines"].push_back({l.v.x(), l.v.y(), l.v.z(), l.w.x(), l.w.y(), l.w.z()});
      }
    }
    if (!inst.sample.camera_index.empty()) {
      j["camera_index"] = inst.sample.camera_index;
      j["cam_from_rig"] = nlohmann::json::array();
      for (const auto& p : inst.sample.cam_from_rig) {
        j["cam_from_rig"].push_back(PoseToJson(p.rotation, p.translation));
      }
    }
    std::ofstream(tmp.Path("p.json")) << j.dump();
    const CliResult r = RunCli({"solve", tmp.Path("p.json")});
    ASSERT_EQ(r.code, 0) << m.name << ": " << r.err;
    const nlohmann::json out = nlohmann::json::parse(r.out);
    EXPECT_EQ(out["method"], std::string(m.name));
    bool found = false;
    for (const auto& s : out["solutions"]) {
      const Rigid3d pose = PoseIn(s, "solution");
      const Sim3d sim(s["scale"].get<double>(), pose.rotation, pose.translation);
      const PoseError e = ComparePoses(sim, inst.truth);
      found |= e.rotation_rad < 1e-6 && e.translation_rel < 1e-6 && e.scale_rel < 1e-6;
    }
    EXPECT_TRUE(found) << m.name << ": " << r.out;
  }
  std::ofstream(tmp.Path("bad.json")) << R"({"method": "m-p2P+u", "bearings": [[0,0,1],[0,1,1]],
      "points": [[1,2,3],[3,2,1]], "camera_index": [0, 3], "cam_from_rig": [{"q":[1,0,0,0],"t":[0,0,0]}]})";
  ExpectError(RunCli({"solve", tmp.Path("bad.json")}), "camera_index");
  std::ofstream(tmp.Path("broken.json")) << "{\"method\": ";
  ExpectError(RunCli({"solve", tmp.Path("broken.json")}), "invalid JSON");
  std::ofstream(tmp.Path("unknown.json")) << R"({"method": "p5P"})";
  ExpectError(RunCli({"solve", tmp.Path("unknown.json")}), "unknown method 'p5P'");
}

TEST(Cli, BenchSolversReportsEveryRequestedMethod) {
  const CliResult r = RunCli({"bench", "solvers", "--json", "--min-time", "0.01", "--instances",
                              "50", "--methods", "p3P,m-P3P+l+s,m-P2L+l+u+s"});
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  std::set<std::string> ours;
  for (const auto& row : j["rows"]) {
    if (row["solver"] == "linecloud") {
      ours.insert(row["method"].get<std::string>());
      EXPECT_EQ(row["found_percent"].get<double>(), 100.0) << row.dump();
      EXPECT_GT(row["us_per_call"].get<double>(), 0.0);
      EXPECT_GT(row["api_us_per_call"].get<double>(), 0.0);
      EXPECT_LT(row["median_log10_rotation_error"].get<double>(), -10.0);
    }
  }
  EXPECT_EQ(ours, (std::set<std::string>{"p3P", "m-P3P+l+s", "m-P2L+l+u+s"}));
  for (const auto& row : j["rows"]) {
    if (row["solver"] != "linecloud") {
      EXPECT_FALSE(row.contains("api_us_per_call")) << row.dump();
    }
  }
  ExpectError(RunCli({"bench", "solvers", "--methods", "p9P"}), "unknown method 'p9P'");
}

// bench localize on a point method and its line counterpart: both localize
// every query, refine to about their Cramér–Rao bound, and the line cloud's
// bound is about √2 above the point model's on the same queries.
TEST(Cli, BenchLocalizeReportsTheRotationBound) {
  const CliResult r =
      RunCli({"bench", "localize", "--json", "--queries", "20", "--methods", "p2P+u,p4L+u"});
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["rows"].size(), 2u);
  for (const auto& row : j["rows"]) {
    EXPECT_EQ(row["localized"], 20) << row.dump();
    const double bound = row["rotation_bound_deg"].get<double>();
    const double refined = row["median_rotation_deg"]["refined"].get<double>();
    ASSERT_GT(bound, 0.0) << row.dump();
    // A median of |ω| sits ~0.9× below the RMS the bound gives; 20 queries.
    EXPECT_GT(refined / bound, 0.6) << row.dump();
    EXPECT_LT(refined / bound, 1.3) << row.dump();
    const double ratio = bound / row["counterpart_rotation_bound_deg"].get<double>();
    if (row["method"] == "p4L+u") {
      EXPECT_EQ(row["counterpart"], "p2P+u");
      EXPECT_GT(ratio, 1.25) << row.dump();
      EXPECT_LT(ratio, 1.6) << row.dump();
    }
  }
}

}  // namespace
}  // namespace linecloud

namespace linecloud {
namespace {

// The demo's query files localize against its line cloud (p4L+u) and its
// point model (p2P+u, p3P), close to the ground truth stored in each file.
TEST(Cli, LocalizeDemoQueriesAgainstTheLineCloudAndThePointModel) {
  TempDir tmp;
  const std::string demo = tmp.Path("demo");
  // The demo lifts with its fixed public key: the same lines on every run.
  ASSERT_EQ(RunCli({"demo", "--out", demo, "--points", "1500", "--queries", "3"}).code, 0);
  const std::string query = demo + "/queries/query_000.json";
  const nlohmann::json file = ReadJsonFile(query);
  const Rigid3d truth = JsonPose(file["ground_truth"]["cam_from_world"], "truth");
  for (const auto& [method, map_flag, map] : {std::tuple{"p4L+u", "--map", demo + "/map.lcm"},
                                              std::tuple{"p2P+u", "--model", demo + "/model"},
                                              std::tuple{"p3P", "--model", demo + "/model"}}) {
    const CliResult r = RunCli({"localize", map_flag, map, "--query", query, "--method", method,
                                "--out", tmp.Path("result.json"), "--inliers"});
    ASSERT_EQ(r.code, 0) << method << ": " << r.err;
    const nlohmann::json result = ReadJsonFile(tmp.Path("result.json"));
    ASSERT_TRUE(result["success"].get<bool>()) << method;
    const Rigid3d estimate = PoseIn(result, "result");
    EXPECT_LT(RotationDistance(estimate.rotation, truth.rotation), 0.2 * 3.14159 / 180) << method;
    EXPECT_LT((estimate.Center() - truth.Center()).norm(), 0.05) << method;
    EXPECT_LT((JsonVector3(result["center"], "center") - estimate.Center()).norm(), 1e-9);
    EXPECT_GT(result["stats"]["inlier_ratio"].get<double>(), 0.9) << method;
    EXPECT_EQ(result["inliers"].size(), result["num_inliers"].get<size_t>());
    EXPECT_GT(result["num_inliers"].get<int>(), 100);
    EXPECT_LT(result["uncertainty"]["rotation_deg"].get<double>(), 0.2) << method;
    // LM lowers its robust (Cauchy) cost, not necessarily the mean |residual|
    // reported here: check the refined error against the 1 px noise instead (mean |e| ≈ 0.8 px for
    // a 1D line residual, ≈ 1.25 px for a 2D point residual).
    EXPECT_LT(result["stats"]["reprojection_px"]["refined"].get<double>(), 1.6) << method;
  }
  // A rig query (3 images, local points): m-P4L+l against the line cloud,
  // m-p3P against the model.
  const std::string rig = demo + "/rig_queries/rig_000.json";
  const Rigid3d rig_truth = JsonPose(ReadJsonFile(rig)["ground_truth"]["rig_from_world"], "truth");
  for (const auto& [method, map_flag, map] : {std::tuple{"m-P4L+l", "--map", demo + "/map.lcm"},
                                              std::tuple{"m-p3P", "--model", demo + "/model"}}) {
    const CliResult r = RunCli({"localize", map_flag, map, "--query", rig, "--method", method});
    ASSERT_EQ(r.code, 0) << method << ": " << r.err;
    const nlohmann::json result = nlohmann::json::parse(r.out);
    ASSERT_TRUE(result["success"].get<bool>()) << method;
    const Rigid3d estimate = PoseIn(result, "result");
    EXPECT_LT(RotationDistance(estimate.rotation, rig_truth.rotation), 0.2 * 3.14159 / 180)
        << method;
    EXPECT_NEAR(result["scale"].get<double>(), 1.0, 0.01) << method;
  }
  // The summary comes first and the inlier list only with --inliers; COLMAP's
  // images.txt form; the frustum PLY.
  CliResult r = RunCli({"localize", "--map", demo + "/map.lcm", "--query", query, "--method",
                        "p4L+u", "--ply", tmp.Path("loc.ply")});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out.find("\"inliers\""), std::string::npos);
  EXPECT_LT(r.out.find("\"q\""), r.out.find("\"stats\""));
  EXPECT_LT(r.out.find("\"success\""), r.out.find("\"q\""));
  const LineCloud cloud = ReadLineCloud(demo + "/map.lcm");
  const std::string ply = ReadFileToString(tmp.Path("loc.ply"));
  EXPECT_NE(ply.find(fmt::format("element vertex {}\n", 2 * cloud.size() + 5)), std::string::npos);
  EXPECT_NE(ply.find(fmt::format("element edge {}\n", cloud.size() + 8)), std::string::npos);
  r = RunCli({"localize", "--map", demo + "/map.lcm", "--query", query, "--method", "p4L+u",
              "--format", "colmap"});
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string data_line = r.out.substr(r.out.rfind("#"));
  std::istringstream line(r.out.substr(r.out.find('\n', r.out.rfind("#")) + 1));
  int image_id = 0, camera_id = 0;
  double qw, qx, qy, qz, tx, ty, tz;
  std::string name;
  ASSERT_TRUE(line >> image_id >> qw >> qx >> qy >> qz >> tx >> ty >> tz >> camera_id >> name)
      << r.out;
  EXPECT_LT(RotationDistance(Eigen::Quaterniond(qw, qx, qy, qz), truth.rotation),
            0.2 * 3.14159 / 180);
  // [newcomer] The image is named after the query file, not "query".
  EXPECT_EQ(name, std::filesystem::path(query).stem().string());
  // [newcomer] A few lines for people: the pose in the same numbers, or why there is none.
  r = RunCli({"localize", "--map", demo + "/map.lcm", "--query", query, "--method", "p4L+u",
              "--format", "text"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out.rfind("pose found: ", 0), 0u) << r.out;
  EXPECT_NE(r.out.find(fmt::format("q (w, x, y, z) = {:.6f} {:.6f} {:.6f} {:.6f}", qw, qx, qy, qz)),
            std::string::npos)
      << r.out;
  EXPECT_LE(std::count(r.out.begin(), r.out.end(), '\n'), 5) << r.out;
  r = RunCli({"localize", "--map", demo + "/map.lcm", "--query", query, "--method", "p4L+u",
              "--format", "text", "--min-inliers", "100000"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out.rfind("no pose: too few inliers", 0), 0u) << r.out;
  // Bounded RANSAC, and "ran fine, no pose": exit 0, success false, a reason.
  r = RunCli({"localize", "--map", demo + "/map.lcm", "--query", query, "--method", "p4L+u",
              "--min-inliers", "100000", "--max-iterations", "50", "--max-seconds", "5"});
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json no_pose = nlohmann::json::parse(r.out);
  EXPECT_FALSE(no_pose["success"].get<bool>());
  EXPECT_NE(no_pose["reason"].get<std::string>().find("(option min_inliers)"), std::string::npos);
  EXPECT_FALSE(no_pose.contains("q"));
  EXPECT_TRUE(no_pose.contains("rejected_q"));
  EXPECT_LE(no_pose["stats"]["iterations"].get<int>(), 50);
  EXPECT_NE(r.err.find("no pose:"), std::string::npos);
  // An image where JSON belongs; a number that overflows a double.
  std::ofstream(tmp.Path("photo.jpg"), std::ios::binary) << "\xFF\xD8\xFF\xE0\x00\x10JFIF";
  ExpectError(RunCli({"localize", "--map", demo + "/map.lcm", "--query", tmp.Path("photo.jpg"),
                      "--method", "p6L"}),
              "this is an image, not a JSON file");
  std::ofstream(tmp.Path("big.json"))
      << R"({"cameras": [{"model": "PINHOLE", "width": 9, "height": 9, "params": [1e400, 1, 5, 5]}]})";
  ExpectError(RunCli({"localize", "--map", demo + "/map.lcm", "--query", tmp.Path("big.json"),
                      "--method", "p6L"}),
              "big.json");
  // info takes --map like every other command; the positional form still works.
  r = RunCli({"info", "--map", demo + "/map.lcm"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out, RunCli({"info", demo + "/map.lcm"}).out);
  EXPECT_NE(r.out.find("version 2"), std::string::npos);

  // Wrong map kind, unknown method, missing query: one clear error line.
  ExpectError(
      RunCli({"localize", "--model", demo + "/model", "--query", query, "--method", "p4L+u"}),
      "needs a line cloud");
  ExpectError(RunCli({"localize", "--map", demo + "/map.lcm", "--query", query, "--method", "p5P"}),
              "unknown method 'p5P'");
  ExpectError(RunCli({"localize", "--map", demo + "/map.lcm", "--query", tmp.Path("no.json"),
                      "--method", "p4L+u"}),
              "no.json");
  ExpectError(RunCli({"localize", "--query", query, "--method", "p3P"}), "--map");
  std::ofstream(tmp.Path("bad.json")) << R"({"cameras": [], "observations": []})";
  ExpectError(RunCli({"localize", "--model", demo + "/model", "--query", tmp.Path("bad.json"),
                      "--method", "p3P"}),
              "bad.json: 'cameras' is empty");
}

}  // namespace
}  // namespace linecloud

namespace linecloud {
namespace {

// The owner's audit of a real map: the density attack scored against the
// secret model, the two-key attack on a second lifting, every output file,
// and the inputs that do not belong together.
TEST(Cli, AuditMeasuresWhatLeaksFromARealMap) {
  TempDir tmp;
  const std::string model = DataPath(kMaupertuis);
  const std::string key = FixedKeyFile(tmp, "model.key", 3);
  ASSERT_EQ(RunCli({"lift", "--key-store", tmp.Path("store"), "--model", model, "--out",
                    tmp.Path("map.lcm"), "--key-file", key})
                .code,
            0);
  // A second lifting with another key (refused unless forced: never share it).
  ASSERT_EQ(
      RunCli({"lift", "--key-store", tmp.Path("store"), "--model", model, "--out",
              tmp.Path("other.lcm"), "--key-file", FixedKeyFile(tmp, "other.key", 4), "--force"})
          .code,
      0);
  const std::string map_before = ReadFileToString(tmp.Path("map.lcm"));
  CliResult r = RunCli({"audit", "--map", tmp.Path("map.lcm"), "--model", model, "--key-file", key,
                        "--other", tmp.Path("other.lcm"), "--out", tmp.Path("audit"), "--quiet"});
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json report = nlohmann::json::parse(r.out);
  EXPECT_EQ(report["lines"], 1039);
  // Measured on maupertuis (1 039 points): 59 % within 1 % of the diagonal.
  const double within1 = report["density_attack"]["recovery"]["within_diagonal_percent"]["1"];
  EXPECT_GT(within1, 0.45);
  EXPECT_LT(within1, 0.75);
  EXPECT_EQ(report["two_keys"]["pairing"], "crossing");
  EXPECT_GE(report["two_keys"]["share_recovered_exactly"].get<double>(), 0.999);
  for (const char* f : {"report.json", "report.md", "recovered.ply", "audit.png"}) {
    EXPECT_TRUE(FileExists(tmp.Path(std::string("audit/") + f))) << f;
  }
  // What the attack recovered is the owner's only (it was world-readable).
  for (const char* f : {"recovered.ply", "audit.png"}) {
    const auto perms = std::filesystem::status(tmp.Path(std::string("audit/") + f)).permissions();
    EXPECT_EQ(perms & (std::filesystem::perms::group_all | std::filesystem::perms::others_all),
              std::filesystem::perms::none)
        << f;
  }
  EXPECT_NE(ReadFileToString(tmp.Path("audit/report.md")).find("| 1 % of the diagonal |"),
            std::string::npos);
  // report.json is the typed report: read back, it writes the same JSON and renders the same
  // report.md.
  const nlohmann::json written = ReadJsonFile(tmp.Path("audit/report.json"));
  EXPECT_EQ(written, report);
  const AuditReport typed = AuditReportFromJson(written, "report.json");
  EXPECT_EQ(nlohmann::json(ToJson(typed)), written);
  EXPECT_EQ(AuditMarkdown(typed), ReadFileToString(tmp.Path("audit/report.md")));
  ASSERT_TRUE(typed.pairing_attacks.by_crossing.has_value());
  EXPECT_EQ(typed.two_keys->pairing, "crossing");
  EXPECT_EQ(ReadFileToString(tmp.Path("map.lcm")), map_before);
  // The attacker's own command: the same recovery, without the model.
  r = RunCli({"attack", "--map", tmp.Path("map.lcm"), "--out", tmp.Path("rec.ply"), "--quiet"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(ReadFileToString(tmp.Path("rec.ply")).substr(0, 3), "ply");

  // Inputs that do not belong together.
  ExpectError(RunCli({"audit", "--map", tmp.Path("map.lcm"), "--model", model, "--key-file",
                      tmp.Path("other.key"), "--quiet"}),
              "lifted with another key");
  RunCli({"demo", "--out", tmp.Path("demo"), "--points", "600", "--images", "6", "--queries", "1"});
  ExpectError(RunCli({"audit", "--map", tmp.Path("demo/map.lcm"), "--model", model, "--quiet"}),
              "does not pass through its model point");
  ExpectError(RunCli({"attack", "--map", tmp.Path("map.lcm"), "--out", tmp.Path("map.lcm")}),
              "is one of the command's inputs");
  EXPECT_EQ(ReadFileToString(tmp.Path("map.lcm")), map_before);
  // A map of another scene as --other: nothing comes back, and the report says why.
  r = RunCli({"audit", "--map", tmp.Path("map.lcm"), "--model", model, "--key-file", key, "--other",
              tmp.Path("demo/map.lcm"), "--no-density-attack", "--quiet"});
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json other = nlohmann::json::parse(r.out);
  EXPECT_EQ(other["two_keys"]["recovered_exactly"], 0);
  EXPECT_TRUE(other["two_keys"].contains("why_nothing"));
  // A tiny map: a clear error.
  ASSERT_EQ(RunCli({"demo", "--out", tmp.Path("tiny"), "--points", "12", "--images", "3",
                    "--queries", "0"})
                .code,
            0);
  ExpectError(RunCli({"attack", "--map", tmp.Path("tiny/map.lcm"), "--out", tmp.Path("t.ply")}),
              "needs at least 10");
  // An empty map (written directly: which demos triangulate nothing depends on the compiler's
  // order of evaluating arguments, which the demo's random draws follow).
  LineCloud empty = ReadLineCloud(tmp.Path("tiny/map.lcm"));  // its header: the demo's key
  empty.ids.clear();
  empty.lines.clear();
  empty.descriptors.clear();
  WriteLineCloud(empty, tmp.Path("empty.lcm"));
  ASSERT_EQ(ReadLineCloud(tmp.Path("empty.lcm")).size(), 0u);
  ExpectError(RunCli({"audit", "--map", tmp.Path("empty.lcm"), "--model", tmp.Path("tiny/model"),
                      "--quiet"}),
              "the map has no lines");
  ExpectError(RunCli({"attack", "--map", tmp.Path("empty.lcm"), "--out", tmp.Path("e.ply")}),
              "needs at least 10");
}

// A sparsified map is a subset of the full map's lines (one point, one line).
TEST(Cli, SparsifiedMapsHoldTheSameLines) {
  TempDir tmp;
  const std::string model = DataPath(kMaupertuis);
  const std::string key = FixedKeyFile(tmp, "model.key", 5);
  ASSERT_EQ(RunCli({"lift", "--key-store", tmp.Path("store"), "--model", model, "--out",
                    tmp.Path("full.lcm"), "--key-file", key})
                .code,
            0);
  for (const char* mode : {"uniform", "balanced"}) {
    const std::string out = tmp.Path(std::string(mode) + ".lcm");
    const CliResult r =
        RunCli({"lift", "--key-store", tmp.Path("store"), "--model", model, "--out", out,
                "--key-file", key, "--sparsify", "0.75", "--sparsify-mode", mode});
    ASSERT_EQ(r.code, 0) << r.err;
    const LineCloud full = ReadLineCloud(tmp.Path("full.lcm")), sparse = ReadLineCloud(out);
    EXPECT_NEAR(sparse.size(), 0.25 * full.size(), 40) << mode;
    const TwoLiftingsAttack attack = IntersectLinesOfEqualId(full, sparse);
    EXPECT_EQ(attack.shared_ids, sparse.size()) << mode;
    EXPECT_EQ(attack.points.size(), 0u) << mode;
  }
  // Attack-aware sparsification too: a subset of the same lines.
  const CliResult r =
      RunCli({"lift", "--key-store", tmp.Path("store"), "--model", model, "--out",
              tmp.Path("resist.lcm"), "--key-file", key, "--resist-attack", "0.2", "--quiet"});
  ASSERT_EQ(r.code, 0) << r.err;
  const LineCloud full = ReadLineCloud(tmp.Path("full.lcm"));
  const LineCloud resist = ReadLineCloud(tmp.Path("resist.lcm"));
  EXPECT_LT(resist.size(), full.size());
  const TwoLiftingsAttack attack = IntersectLinesOfEqualId(full, resist);
  EXPECT_EQ(attack.shared_ids, resist.size());
  EXPECT_EQ(attack.points.size(), 0u);
  ExpectError(RunCli({"lift", "--key-store", tmp.Path("store"), "--model", model, "--out",
                      tmp.Path("x.lcm"), "--key-file", key, "--sparsify", "1"}),
              "--sparsify");
  EXPECT_FALSE(FileExists(tmp.Path("x.lcm")));
}

}  // namespace
}  // namespace linecloud

namespace linecloud {
namespace {

// [harden] 2: outputs that are devices, links or the command's own inputs.
TEST(Cli, OutputsNeverClobberInputsOrDevices) {
  TempDir tmp;
  ASSERT_EQ(
      RunCli({"demo", "--out", tmp.Path("d"), "--points", "800", "--images", "8", "--queries", "2"})
          .code,
      0);
  const std::string map = tmp.Path("d/map.lcm"), query = tmp.Path("d/queries/query_000.json");
  const std::string map_before = ReadFileToString(map);
  const std::string points_before = ReadFileToString(tmp.Path("d/model/points3D.bin"));
  ExpectError(RunCli({"localize", "--map", map, "--query", query, "--out", map, "--quiet"}),
              "one of the command's inputs");
  ExpectError(RunCli({"localize", "--map", map, "--query", query, "--ply", query, "--quiet"}),
              "one of the command's inputs");
  ExpectError(
      RunCli({"export", "--model", tmp.Path("d/model"), "--ply", tmp.Path("d/model/points3D.bin")}),
      "one of the command's inputs");
  EXPECT_EQ(ReadFileToString(map), map_before);
  EXPECT_EQ(ReadFileToString(tmp.Path("d/model/points3D.bin")), points_before);
  // A device is written through and stays a device.
  EXPECT_EQ(RunCli({"export", "--map", map, "--ply", "/dev/null"}).code, 0);
  EXPECT_TRUE(std::filesystem::is_character_file("/dev/null"));
  // A FIFO as an input: refused at once instead of blocking.
  ASSERT_EQ(::mkfifo(tmp.Path("fifo.json").c_str(), 0600), 0);
  ExpectError(RunCli({"localize", "--map", map, "--query", tmp.Path("fifo.json"), "--quiet"}),
              "not a regular file");
}

}  // namespace
}  // namespace linecloud
