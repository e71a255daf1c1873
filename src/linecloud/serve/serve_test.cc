// `linecloud serve` through a real HTTP client on 127.0.0.1 (random ports):
// poses, every documented status, limits, signals. The fountain-P11 test
// needs CI's `eval prepare` work (LINECLOUD_FOUNTAIN_WORK).
#include <netinet/in.h>
#include <signal.h>
#include <sodium.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <random>
#include <set>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "linecloud/features/image.h"
#include "linecloud/features/sift.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/io/geo.h"
#include "linecloud/localize/overlay_marks.h"
#include "linecloud/serve/server.h"
#include "linecloud/serve/serve_testing.h"
#include "linecloud/serve/tokens.h"
#include "linecloud/testing/test_util.h"
#include "linecloud/util/base64.h"
#include "linecloud/util/file.h"
#include "linecloud/io/ply.h"

#include <cstring>

#include <fmt/format.h>

#include <httplib.h>
#undef _res

namespace linecloud {
namespace {

using json = nlohmann::json;
using testing::TempDir;

// A seeded scene: 400 points seen by a 640 x 480 pinhole camera, each lifted
// to a line with a random direction and a random descriptor; the client's
// features are 300 of the points' exact projections with their descriptors
// and 60 unrelated features.
struct Scene {
  LineCloud cloud;
  json camera = {{"model", "PINHOLE"},
                 {"width", 640},
                 {"height", 480},
                 {"params", {500.0, 500.0, 320.0, 240.0}}};
  Rigid3d cam_from_world;
  std::vector<std::array<float, 2>> keypoints;
  std::vector<uint8_t> descriptors;
};

// A SIFT-like descriptor: positive, on the 512 sphere (COLMAP's normalisation).
std::vector<uint8_t> Descriptor(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<double> v(128);
  double norm = 0;
  for (double& x : v) {
    x = u(rng) * u(rng);
    norm += x * x;
  }
  std::vector<uint8_t> out(128);
  for (int k = 0; k < 128; ++k) {
    out[k] = static_cast<uint8_t>(std::min(255.0, std::round(512 * v[k] / std::sqrt(norm))));
  }
  return out;
}

Scene MakeScene() {
  Scene s;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  s.cam_from_world =
      Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized())),
              Eigen::Vector3d(0.5, -0.2, 1.0));
  const Rigid3d world_from_cam = s.cam_from_world.Inverse();
  s.cloud.descriptor_dim = 128;
  s.cloud.descriptor_type = "colmap-sift-uint8";
  s.cloud.descriptor_aggregation = "medoid";
  for (int i = 0; i < 400; ++i) {
    const Eigen::Vector3d xc(3 * u(rng), 2 * u(rng), 6 + 2 * u(rng));
    const Eigen::Vector3d xw = world_from_cam.rotation * xc + world_from_cam.translation;
    s.cloud.ids.push_back(1000 + i);
    s.cloud.lines.push_back(
        PluckerLine::FromPointAndDirection(xw, Eigen::Vector3d(u(rng), u(rng), u(rng))));
    const std::vector<uint8_t> d = Descriptor(rng);
    s.cloud.descriptors.insert(s.cloud.descriptors.end(), d.begin(), d.end());
    const double px = 500 * xc.x() / xc.z() + 320, py = 500 * xc.y() / xc.z() + 240;
    if (i < 300 && px > 0 && px < 640 && py > 0 && py < 480) {
      s.keypoints.push_back({float(px), float(py)});
      s.descriptors.insert(s.descriptors.end(), d.begin(), d.end());
    }
  }
  for (int i = 0; i < 60; ++i) {
    s.keypoints.push_back({float(320 + 300 * u(rng)), float(240 + 220 * u(rng))});
    const std::vector<uint8_t> d = Descriptor(rng);
    s.descriptors.insert(s.descriptors.end(), d.begin(), d.end());
  }
  return s;
}

json FeaturesBody(const Scene& s) {
  json kp = json::array();
  for (const auto& k : s.keypoints) kp.push_back({k[0], k[1]});
  return {{"camera", s.camera}, {"keypoints", kp}, {"descriptors", Base64Encode(s.descriptors)}};
}

// A server on 127.0.0.1 with a random port, run on its own thread.
class Running {
 public:
  explicit Running(ServeOptions o) {
    o.listen = "127.0.0.1:0";
    if (!o.log)
      o.log = [this](const std::string& line) {
        std::lock_guard<std::mutex> lock(mutex_);
        log_.push_back(line);
      };
    server_ = std::make_unique<Server>(o);
    port_ = server_->Bind();
    thread_ = std::thread([this] { server_->Run(); });
  }
  ~Running() {
    server_->Stop();
    thread_.join();
  }
  httplib::Client Client() const {
    httplib::Client c("127.0.0.1", port_);
    c.set_read_timeout(30, 0);
    return c;
  }
  Server& server() { return *server_; }
  std::vector<std::string> log() {
    std::lock_guard<std::mutex> lock(mutex_);
    return log_;
  }
  bool LogContains(const std::string& text) {
    const std::vector<std::string> lines = log();
    return std::any_of(lines.begin(), lines.end(),
                       [&](const std::string& l) { return l.find(text) != std::string::npos; });
  }

 private:
  std::unique_ptr<Server> server_;
  int port_ = 0;
  std::thread thread_;
  std::mutex mutex_;
  std::vector<std::string> log_;
};

struct Fixture {
  TempDir tmp;
  Scene scene = MakeScene();
  Fixture() {
    std::filesystem::create_directories(tmp.Path("maps"));
    WriteLineCloud(scene.cloud, tmp.Path("maps/synth.lcm"));
    WriteLineCloud(scene.cloud, tmp.Path("maps/other.lcm"));
    WriteTestTokens(tmp.Path("tokens.json"));
  }
  ServeOptions Options(bool with_tokens = true) const {
    ServeOptions o;
    o.maps_dir = tmp.Path("maps");
    if (with_tokens) o.tokens_path = tmp.Path("tokens.json");
    return o;
  }
};

httplib::Headers Bearer(const std::string& token) { return {{"Authorization", "Bearer " + token}}; }

TEST(Serve, ClientFeaturesGiveTheTruePoseAndOnlyThePose) {
  Fixture f;
  Running server(f.Options());
  httplib::Client c = server.Client();
  const auto r = c.Post("/v1/maps/synth/localize", Bearer("alice-secret"),
                        FeaturesBody(f.scene).dump(), "application/json");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  const json j = json::parse(r->body);
  ASSERT_TRUE(j["success"].get<bool>()) << r->body;
  const Eigen::Quaterniond q(j["q"][0], j["q"][1], j["q"][2], j["q"][3]);
  const Eigen::Vector3d t(j["t"][0], j["t"][1], j["t"][2]);
  // Exact data up to the float32 keypoints (SiftKeypoint): ~1e-5 px.
  EXPECT_LT(q.angularDistance(f.scene.cam_from_world.rotation), 1e-6);
  EXPECT_LT((t - f.scene.cam_from_world.translation).norm(), 1e-6);
  EXPECT_GE(j["num_inliers"].get<int>(), 250);
  // What leaves the server: the pose and summary figures, nothing per point.
  std::set<std::string> keys;
  for (const auto& [k, v] : j.items()) keys.insert(k);
  EXPECT_EQ(keys,
            (std::set<std::string>{"success", "method", "pose", "q", "t", "center", "num_matches",
                                   "num_inliers", "inlier_ratio", "uncertainty", "times_ms"}));
  EXPECT_EQ(j["method"], "p6L");
  EXPECT_EQ(j["pose"], "cam_from_world");
  // The access log: one JSON line, with the token's id, never the token.
  bool logged = false;
  for (const std::string& line : server.log()) {
    EXPECT_EQ(line.find("alice-secret"), std::string::npos) << line;
    const json l = json::parse(line);
    if (l["route"] == "/v1/maps/{id}/localize") {
      logged = true;
      EXPECT_EQ(l["token"], "alice");
      EXPECT_EQ(l["map"], "synth");
      EXPECT_EQ(l["status"], 200);
    }
  }
  EXPECT_TRUE(logged);
  // The same frame twice in a rig would count its matches twice: 400, naming it.
  json frame = FeaturesBody(f.scene);
  frame["cam_from_rig"] = {{"q", {1, 0, 0, 0}}, {"t", {0, 0, 0}}};
  json twice = {{"frames", {frame, frame}}};
  twice["frames"][1]["cam_from_rig"]["t"] = {0.1, 0, 0};
  const auto dup =
      c.Post("/v1/maps/synth/localize", Bearer("alice-secret"), twice.dump(), "application/json");
  ASSERT_TRUE(dup);
  EXPECT_EQ(dup->status, 400) << dup->body;
  EXPECT_NE(dup->body.find("frames[1] is frames[0] again (the same descriptors)"),
            std::string::npos)
      << dup->body;
}

// The console's routes: a map's info, its segments (on the lines, inside the
// anchors' box, a prefix of one fixed order), the owner's audit and the
// inlier keypoints for admin tokens only.
TEST(Serve, ConsoleRoutesRevealNothingTheMapDoesNot) {
  Fixture f;
  const json audit = {{"density_attack", {{"recovery", {{"points", 400}}}}}};
  WriteFileAtomically(f.tmp.Path("maps/synth.audit.json"),
                      [&](std::ostream& os) { os << audit.dump(); });
  Running server(f.Options());
  httplib::Client c = server.Client();
  auto r = c.Get("/v1/maps/synth", Bearer("alice-secret"));
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  const json info = json::parse(r->body);
  EXPECT_EQ(info["id"], "synth");
  EXPECT_EQ(info["num_lines"], 400);
  EXPECT_EQ(info["descriptors"]["dim"], 128);
  EXPECT_EQ(c.Get("/v1/maps/other", Bearer("alice-secret"))->status, 404);
  // [shield] A reader gets poses, not the map: no geometry, no segments
  // (a line cloud downloaded whole gives most of its points back).
  EXPECT_FALSE(info.contains("anchor_bbox")) << info.dump();
  EXPECT_EQ(info["publish_lines"], false);
  // What the token may fetch, said up front (the console asks for nothing else).
  EXPECT_EQ(
      info["for_this_token"],
      json({{"admin", false}, {"segments", false}, {"audit", false}, {"audit_points", false}}))
      << info.dump();
  EXPECT_EQ(json::parse(c.Get("/v1/maps/synth", Bearer("root-secret"))->body)["for_this_token"],
            json({{"admin", true}, {"segments", true}, {"audit", true}, {"audit_points", false}}));
  EXPECT_TRUE(
      json::parse(c.Get("/v1/maps/synth", Bearer("root-secret"))->body).contains("anchor_bbox"));
  r = c.Get("/v1/maps/synth/segments?limit=999999999", Bearer("alice-secret"));
  ASSERT_EQ(r->status, 403);
  EXPECT_NE(json::parse(r->body)["error"].get<std::string>().find("has not published"),
            std::string::npos)
      << r->body;

  r = c.Get("/v1/maps/synth/segments?limit=150", Bearer("root-secret"));
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(r->get_header_value("X-Linecloud-Lines"), "400");
  EXPECT_EQ(r->get_header_value("X-Linecloud-Segments"), "150");
  ASSERT_EQ(r->body.size(), 150 * 6 * sizeof(float));
  std::vector<float> seg(150 * 6);
  std::memcpy(seg.data(), r->body.data(), r->body.size());
  Eigen::Vector3d min, max;
  AnchorBoundingBox(f.scene.cloud, &min, &max);
  for (size_t k = 0; k < 150; ++k) {
    const Eigen::Vector3d a(seg[6 * k], seg[6 * k + 1], seg[6 * k + 2]);
    const Eigen::Vector3d b(seg[6 * k + 3], seg[6 * k + 4], seg[6 * k + 5]);
    // Each segment lies on one of the map's lines, inside the box.
    double best = 1e9;
    for (const PluckerLine& line : f.scene.cloud.lines) {
      best = std::min(best, line.DistanceTo(a) + line.DistanceTo(b));
    }
    EXPECT_LT(best, 1e-4) << k;
    for (const Eigen::Vector3d& p : {a, b}) {
      EXPECT_TRUE((p.array() >= min.array() - 1e-4).all() &&
                  (p.array() <= max.array() + 1e-4).all());
    }
  }
  // The whole map by default here (fewer than 20 000 lines); a prefix of the same order.
  r = c.Get("/v1/maps/synth/segments", Bearer("root-secret"));
  ASSERT_EQ(r->body.size(), 400 * 6 * sizeof(float));
  EXPECT_EQ(std::memcmp(r->body.data(), seg.data(), seg.size() * sizeof(float)), 0);
  EXPECT_EQ(c.Get("/v1/maps/synth/segments?limit=abc", Bearer("root-secret"))->status, 400);
  EXPECT_EQ(c.Get("/v1/maps/other/segments", Bearer("alice-secret"))->status, 404);
  // The owner publishes the lines (ID.json): readers get them, and the map's
  // details say what that costs by the owner's audit.
  WriteFileAtomically(f.tmp.Path("maps/synth.json"),
                      [&](std::ostream& os) { os << R"({"publish_lines": true})"; });
  const json published_audit = {
      {"density_attack", {{"recovery", {{"within_diagonal_percent", {{"1", 0.6325}}}}}}}};
  WriteFileAtomically(f.tmp.Path("maps/synth.audit.json"),
                      [&](std::ostream& os) { os << published_audit.dump(); });
  server.server().Reload();  // the map file unchanged: its ID.json and audit are read anew
  r = c.Get("/v1/maps/synth/segments?limit=10", Bearer("alice-secret"));
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(r->body.size(), 10 * 6 * sizeof(float));
  const json published = json::parse(c.Get("/v1/maps/synth", Bearer("alice-secret"))->body);
  EXPECT_EQ(published["publish_lines"], true);
  EXPECT_EQ(published["audit_recovered_share"], 0.6325);
  EXPECT_EQ(
      published["for_this_token"],
      json({{"admin", false}, {"segments", true}, {"audit", false}, {"audit_points", false}}));
  EXPECT_EQ(json::parse(c.Get("/v1/maps/synth", Bearer("root-secret"))->body)["for_this_token"],
            json({{"admin", true}, {"segments", true}, {"audit", true}, {"audit_points", false}}));
  // A share no audit gives (7.5) is not shown to readers.
  WriteFileAtomically(f.tmp.Path("maps/synth.audit.json"), [&](std::ostream& os) {
    os << json{{"density_attack", {{"recovery", {{"within_diagonal_percent", {{"1", 7.5}}}}}}}}
              .dump();
  });
  server.server().Reload();
  const json implausible = json::parse(c.Get("/v1/maps/synth", Bearer("alice-secret"))->body);
  EXPECT_FALSE(implausible.contains("audit_recovered_share")) << implausible.dump();
  WriteFileAtomically(f.tmp.Path("maps/synth.audit.json"),
                      [&](std::ostream& os) { os << audit.dump(); });

  // The audit: the owner's only.
  EXPECT_EQ(c.Get("/v1/maps/synth/audit", Bearer("alice-secret"))->status, 404);
  r = c.Get("/v1/maps/synth/audit", Bearer("root-secret"));
  ASSERT_EQ(r->status, 200);
  EXPECT_EQ(json::parse(r->body), audit);
  EXPECT_EQ(c.Get("/v1/maps/other/audit", Bearer("root-secret"))->status, 404);  // none there
  // The recovered points (the audit's recovered.ply), coloured: read back exactly.
  const std::vector<Eigen::Vector3d> points = {{1, 2, 3}, {-4.5, 0.25, 8}};
  WritePointsPly(f.tmp.Path("maps/synth.audit.ply"), points, {{{0, 255, 0}}, {{255, 0, 0}}},
                 "test");
  EXPECT_EQ(c.Get("/v1/maps/synth/audit/points", Bearer("alice-secret"))->status, 404);
  r = c.Get("/v1/maps/synth/audit/points", Bearer("root-secret"));
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(r->get_header_value("X-Linecloud-Points"), "2");
  ASSERT_EQ(r->body.size(), 2 * 12 + 2 * 3);
  float xyz[6];
  std::memcpy(xyz, r->body.data(), sizeof(xyz));
  EXPECT_EQ(std::vector<float>(xyz, xyz + 6), (std::vector<float>{1, 2, 3, -4.5f, 0.25f, 8}));
  EXPECT_EQ(r->body.substr(24), std::string("\x00\xff\x00\xff\x00\x00", 6));
  // A truncated file is an error naming it, not a crash.
  const std::string ply = ReadFileToString(f.tmp.Path("maps/synth.audit.ply"));
  WriteFileAtomically(f.tmp.Path("maps/synth.audit.ply"),
                      [&](std::ostream& os) { os << ply.substr(0, ply.size() - 1); });
  r = c.Get("/v1/maps/synth/audit/points", Bearer("root-secret"));
  EXPECT_EQ(r->status, 500);
  EXPECT_NE(r->body.find("synth.audit.ply"), std::string::npos) << r->body;

  // Inlier keypoints: the owner's answer has one per inlier, at the client's pixels.
  const std::string body = FeaturesBody(f.scene).dump();
  r = c.Post("/v1/maps/synth/localize", Bearer("root-secret"), body, "application/json");
  ASSERT_EQ(r->status, 200);
  const json owner = json::parse(r->body);
  ASSERT_EQ(owner["inlier_keypoints"].size(), owner["num_inliers"].get<size_t>());
  for (const json& k : owner["inlier_keypoints"]) {
    bool found = false;
    for (const auto& kp : f.scene.keypoints) found = found || (kp[0] == k[0] && kp[1] == k[1]);
    EXPECT_TRUE(found) << k;
  }
  // What the CLI's --overlay draws, for the owner: the outliers, and per inlier the projected
  // map line, a segment through (near) its keypoint.
  EXPECT_EQ(owner["outlier_keypoints"].size() + owner["num_inliers"].get<size_t>(),
            owner["num_matches"].get<size_t>());
  ASSERT_EQ(owner["inlier_segments"].size(), owner["inlier_keypoints"].size());
  size_t drawn = 0;
  for (size_t i = 0; i < owner["inlier_segments"].size(); ++i) {
    const json& s = owner["inlier_segments"][i];
    if (s.is_null()) continue;
    ++drawn;
    const Eigen::Vector2d a(s[0], s[1]), b(s[2], s[3]);
    const Eigen::Vector2d k(owner["inlier_keypoints"][i][0], owner["inlier_keypoints"][i][1]);
    const Eigen::Vector2d d = (b - a).normalized();
    EXPECT_NEAR((b - a).norm(), 2 * OverlaySegmentHalfLength(640), 1e-6);
    const Eigen::Vector2d off = k - a - d * d.dot(k - a);
    EXPECT_LT(off.norm(), 0.01) << "segment " << s << " misses keypoint " << k;
  }
  EXPECT_GT(drawn, owner["inlier_segments"].size() * 9 / 10);
  r = c.Post("/v1/maps/synth/localize", Bearer("alice-secret"), body, "application/json");
  for (const char* key : {"inlier_keypoints", "inlier_segments", "outlier_keypoints"}) {
    EXPECT_FALSE(json::parse(r->body).contains(key)) << key;
  }
}

TEST(Serve, EveryDocumentedErrorStatus) {
  Fixture f;
  ServeOptions o = f.Options();
  o.max_body_mb = 1;
  Running server(o);
  httplib::Client c = server.Client();
  const std::string body = FeaturesBody(f.scene).dump();
  const auto post = [&](const std::string& path, const std::string& token, const std::string& b,
                        const std::string& type) {
    auto r = token.empty() ? c.Post(path.c_str(), b, type.c_str())
                           : c.Post(path.c_str(), Bearer(token), b, type.c_str());
    EXPECT_TRUE(r) << path;
    return r;
  };
  const auto error_of = [](const httplib::Result& r) {
    return json::parse(r->body)["error"].get<std::string>();
  };
  // 401: no token, a wrong one.
  auto r = post("/v1/maps/synth/localize", "", body, "application/json");
  EXPECT_EQ(r->status, 401);
  EXPECT_NE(error_of(r).find("Bearer"), std::string::npos);
  EXPECT_EQ(post("/v1/maps/synth/localize", "guess", body, "application/json")->status, 401);
  // 404 alike for a forbidden map, an unknown one and a path in the id.
  const auto forbidden = post("/v1/maps/synth/localize", "bob-secret", body, "application/json");
  const auto unknown = post("/v1/maps/nope/localize", "bob-secret", body, "application/json");
  EXPECT_EQ(forbidden->status, 404);
  EXPECT_EQ(unknown->status, 404);
  EXPECT_EQ(forbidden->body, unknown->body);  // existence not revealed
  EXPECT_EQ(
      post("/v1/maps/..%2Fmaps%2Fsynth/localize", "alice-secret", body, "application/json")->status,
      404);
  // 415, 400s naming the part.
  EXPECT_EQ(post("/v1/maps/synth/localize", "alice-secret", body, "text/plain")->status, 415);
  r = post("/v1/maps/synth/localize", "alice-secret", "{not json", "application/json");
  EXPECT_EQ(r->status, 400);
  EXPECT_NE(error_of(r).find("not JSON"), std::string::npos);
  json bad = FeaturesBody(f.scene);
  bad["descriptors"] = "***";
  r = post("/v1/maps/synth/localize", "alice-secret", bad.dump(), "application/json");
  EXPECT_EQ(r->status, 400);
  EXPECT_NE(error_of(r).find("descriptors"), std::string::npos);
  bad = FeaturesBody(f.scene);
  bad["camera"]["model"] = "FISHEYE_X";
  r = post("/v1/maps/synth/localize", "alice-secret", bad.dump(), "application/json");
  EXPECT_EQ(r->status, 400);
  EXPECT_NE(error_of(r).find("camera.model"), std::string::npos);
  bad = FeaturesBody(f.scene);
  bad["keypoints"][0] = {1e9, 5};
  r = post("/v1/maps/synth/localize", "alice-secret", bad.dump(), "application/json");
  EXPECT_EQ(r->status, 400);
  EXPECT_NE(error_of(r).find("keypoints[0]"), std::string::npos);
  httplib::MultipartFormDataItems no_camera = {{"image", "xx", "a.jpg", "image/jpeg"}};
  r = c.Post("/v1/maps/synth/localize", Bearer("alice-secret"), no_camera);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400);
  EXPECT_NE(error_of(r).find("'camera'"), std::string::npos);
  // 413: a body over --max-body-mb; a photo whose header announces 3.6 GP,
  // answered from its header at once.
  EXPECT_EQ(
      post("/v1/maps/synth/localize", "alice-secret", std::string(2 << 20, 'x'), "application/json")
          ->status,
      413);
  const auto start = std::chrono::steady_clock::now();
  httplib::MultipartFormDataItems bomb = {
      {"image", testing::BombPng(), "bomb.png", "image/png"},
      {"camera", "PINHOLE 60000 60000 50000 50000 30000 30000", "", ""}};
  r = c.Post("/v1/maps/synth/localize", Bearer("alice-secret"), bomb);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 413);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 0.1);
  EXPECT_NE(error_of(r).find("exceed this server's limit of"), std::string::npos) << r->body;
  // 429 with Retry-After: one request a minute.
  EXPECT_EQ(post("/v1/maps/synth/localize", "slow-secret", body, "application/json")->status, 200);
  r = post("/v1/maps/synth/localize", "slow-secret", body, "application/json");
  EXPECT_EQ(r->status, 429);
  EXPECT_GE(std::stoi(r->get_header_value("Retry-After")), 1);
  // Health, readiness, the maps a token may use, metrics for admins only.
  EXPECT_EQ(c.Get("/healthz")->status, 200);
  EXPECT_EQ(c.Get("/readyz")->status, 200);
  const json maps = json::parse(c.Get("/v1/maps", Bearer("alice-secret"))->body);
  ASSERT_EQ(maps["maps"].size(), 1u);
  EXPECT_EQ(maps["maps"][0]["id"], "synth");
  EXPECT_EQ(maps["maps"][0]["lines"], 400);
  EXPECT_EQ(c.Get("/metrics", Bearer("alice-secret"))->status, 404);
  const auto metrics = c.Get("/metrics", Bearer("root-secret"));
  EXPECT_EQ(metrics->status, 200);
  EXPECT_NE(metrics->body.find(
                "linecloud_requests_total{route=\"/v1/maps/{id}/localize\",status=\"429\"} 1"),
            std::string::npos)
      << metrics->body;
  EXPECT_NE(metrics->body.find("linecloud_stage_ms_bucket{stage=\"total\""), std::string::npos);
}

TEST(Serve, OptionsAndTokensAreChecked) {
  Fixture f;
  ServeOptions o = f.Options(false);
  o.listen = "0.0.0.0:8080";
  EXPECT_THROW(Server{o}, Error);  // off loopback without tokens
  o = f.Options();
  o.threads = 0;
  EXPECT_THROW(Server{o}, Error);
  WriteFileAtomically(f.tmp.Path("bad.json"), [](std::ostream& os) {
    os << R"({"tokens": [{"id": "x", "sha256": "abc", "maps": ["*"]}]})";
  });
  o = f.Options();
  o.tokens_path = f.tmp.Path("bad.json");
  try {
    Server s(o);
    ADD_FAILURE() << "a short hash was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("tokens[0].sha256"), std::string::npos) << e.what();
  }
}

// SIGHUP (Server::Reload) reads the tokens file again: a removed token stops
// working at once, a new one works, the rate spent is kept; a broken file
// keeps the previous tokens.
TEST(Serve, ReloadReadsTheTokensAgain) {
  Fixture f;
  Running server(f.Options());
  httplib::Client c = server.Client();
  ASSERT_EQ(c.Get("/v1/maps/synth", Bearer("alice-secret"))->status, 200);
  const std::string body = FeaturesBody(f.scene).dump();
  const auto slow = [&] {
    return c.Post("/v1/maps/synth/localize", Bearer("slow-secret"), body, "application/json")
        ->status;
  };
  ASSERT_EQ(slow(), 200);  // its one request a minute
  ASSERT_EQ(slow(), 429);
  nlohmann::json tokens = nlohmann::json::parse(ReadFileToString(f.tmp.Path("tokens.json")));
  tokens["tokens"].erase(0);  // alice
  tokens["tokens"].push_back(
      {{"id", "carol"}, {"sha256", TokenSha256Hex("carol-secret")}, {"maps", {"synth"}}});
  WriteFileAtomically(f.tmp.Path("tokens.json"), [&](std::ostream& os) { os << tokens.dump(); });
  EXPECT_EQ(c.Get("/v1/maps/synth", Bearer("alice-secret"))->status, 200);  // not yet reloaded
  server.server().Reload();
  EXPECT_EQ(c.Get("/v1/maps/synth", Bearer("alice-secret"))->status, 401);
  EXPECT_EQ(c.Get("/v1/maps/synth", Bearer("carol-secret"))->status, 200);
  EXPECT_EQ(slow(), 429) << "the rate survives a reload";
  WriteFileAtomically(f.tmp.Path("tokens.json"), [](std::ostream& os) { os << "{\"tokens\": 3"; });
  server.server().Reload();
  EXPECT_EQ(c.Get("/v1/maps/synth", Bearer("carol-secret"))->status, 200);
  EXPECT_TRUE(server.LogContains("tokens not reloaded")) << "a broken file is said, not obeyed";
  // A key twice (an outsider's file: "admin" false then true gave an admin) is refused, named.
  WriteFileAtomically(f.tmp.Path("tokens.json"), [](std::ostream& os) {
    os << R"({"tokens": [{"id": "mallory", "sha256": "00", "maps": ["synth"], "admin": false,
              "admin": true}]})";
  });
  EXPECT_EQ(testing::ErrorOf([&] { TokenStore::Read(f.tmp.Path("tokens.json")); }),
            f.tmp.Path("tokens.json") + ": the key \"admin\" appears twice in one object");
}

// A worker busy and no queue: 503 with Retry-After; a deadline shorter than
// the work: 504. The work is a real photo's SIFT (fountain-P11, 1.6 MP).
TEST(Serve, BusyAndLateRequests) {
  LINECLOUD_REQUIRE_DATA("strecha/fountain-P11/images/0000.jpg");
  const std::string photo =
      ReadFileToString(testing::DataPath("strecha/fountain-P11/images/0000.jpg"));
  const httplib::MultipartFormDataItems form = {
      {"image", photo, "0000.jpg", "image/jpeg"},
      {"camera", "PINHOLE 1536 1024 1379.74 1382.08 760.095 503.155", "", ""}};
  Fixture f;
  {
    ServeOptions o = f.Options(false);
    o.threads = 1;
    o.queue = 0;
    o.request_seconds = 300;  // the first request's SIFT must finish, even under the sanitizers
    Running server(o);
    std::atomic<int> first_status = 0;
    std::thread first([&] {
      httplib::Client c = server.Client();
      first_status = c.Post("/v1/maps/synth/localize", form)->status;
    });
    // The first request holds the one worker once it is in flight (a fixed sleep was not
    // always enough on a loaded machine).
    httplib::Client c = server.Client();
    for (int i = 0; i < 500; ++i) {
      const auto m = c.Get("/metrics");
      if (m && m->body.find("linecloud_in_flight 1\n") != std::string::npos) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const auto busy = c.Post("/v1/maps/synth/localize", form);
    first.join();
    ASSERT_TRUE(busy);
    EXPECT_EQ(busy->status, 503) << busy->body;
    EXPECT_EQ(busy->get_header_value("Retry-After"), "1");
    EXPECT_EQ(first_status.load(), 200);  // ran: no pose on this synthetic map, but an answer
  }
  {
    ServeOptions o = f.Options(false);
    o.request_seconds = 0.05;
    Running server(o);
    httplib::Client c = server.Client();
    const auto late = c.Post("/v1/maps/synth/localize", form);
    ASSERT_TRUE(late);
    EXPECT_EQ(late->status, 504) << late->body;
  }
}

// A client that sends half a request and stalls holds its connection for the
// read timeout only; others are served meanwhile.
TEST(Serve, ASlowClientIsCutOff) {
  Fixture f;
  ServeOptions o = f.Options(false);
  o.read_timeout_s = 1;
  Running server(o);
  const int port = std::stoi(server.server().url().substr(server.server().url().rfind(':') + 1));
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  const std::string partial =
      "POST /v1/maps/synth/localize HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\n{";
  ASSERT_EQ(::send(fd, partial.data(), partial.size(), 0), ssize_t(partial.size()));
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(server.Client().Get("/healthz")->status, 200);  // served meanwhile
  char buf[256];
  const ssize_t n = ::recv(fd, buf, sizeof(buf), 0);  // the server gives up on it
  const double waited =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ::close(fd);
  EXPECT_LT(waited, 5.0);
  EXPECT_GE(n, 0);
}

// A fountain-P11 photo against the line cloud of a map built without it
// (eval prepare's group g00), through multipart, client features and OSCP
// GeoPose: within 0.5° and 5 cm of the ground truth each way.
TEST(Serve, FountainPhotoThroughEveryRoute) {
  const char* work = std::getenv("LINECLOUD_FOUNTAIN_WORK");
  if (!work || !std::filesystem::exists(std::string(work) + "/prepared.json")) {
    LINECLOUD_ABSENT(
        "LINECLOUD_FOUNTAIN_WORK is not an `eval prepare` work of fountain-P11 "
        "(scripts/run.sh test prepares it)");
  }
  TempDir tmp;
  std::filesystem::create_directories(tmp.Path("maps"));
  const std::string lift = fmt::format(
      "LINECLOUD_KEY_STORE={} {} lift --model {}/groups/g00/map --database "
      "{}/colmap/database.db --out {} > /dev/null 2>&1",
      tmp.Path("keys"), LINECLOUD_BINARY, work, work, tmp.Path("maps/fountain.lcm"));
  ASSERT_EQ(std::system(lift.c_str()), 0) << lift;
  GeoAnchor anchor;
  anchor.lat_deg = 46.5191;
  anchor.lon_deg = 6.5668;
  anchor.h_m = 400;
  anchor.enu_from_map =
      Sim3d(1.0, Eigen::Quaterniond(Eigen::AngleAxisd(1.1, Eigen::Vector3d::UnitX())),
            Eigen::Vector3d(3, 4, 5));
  const json anchor_json = {
      {"geo_anchor",
       {{"lat", anchor.lat_deg},
        {"lon", anchor.lon_deg},
        {"h", anchor.h_m},
        {"enu_from_map",
         {{"q",
           {anchor.enu_from_map.rotation.w(), anchor.enu_from_map.rotation.x(),
            anchor.enu_from_map.rotation.y(), anchor.enu_from_map.rotation.z()}},
          {"t", {3, 4, 5}},
          {"scale", 1.0}}}}}};
  WriteFileAtomically(tmp.Path("maps/fountain.json"),
                      [&](std::ostream& os) { os << anchor_json.dump(); });
  const json prepared = json::parse(ReadFileToString(std::string(work) + "/prepared.json"));
  const json& image = prepared["groups"][0]["images"][0];
  ASSERT_EQ(image["name"], "0000.jpg");
  const json& truth_json = image["cam_from_world"];
  const Rigid3d truth(Eigen::Quaterniond(truth_json["q"][0], truth_json["q"][1], truth_json["q"][2],
                                         truth_json["q"][3]),
                      Eigen::Vector3d(truth_json["t"][0], truth_json["t"][1], truth_json["t"][2]));
  // The photo through the data locator: the work's dataset_dir is where the data was when the
  // work was prepared, and data folders move.
  const std::string photo_path = testing::DataPath("strecha/fountain-P11/images/0000.jpg");
  const std::string photo = ReadFileToString(photo_path);
  const std::string camera = "PINHOLE 1536 1024 1379.74 1382.08 760.095 503.155";
  const auto expect_near = [&](const Eigen::Quaterniond& q, const Eigen::Vector3d& centre,
                               const char* route) {
    EXPECT_LT(q.angularDistance(truth.rotation) * 180 / M_PI, 0.5) << route;
    EXPECT_LT((centre - truth.Inverse().translation).norm(), 0.05) << route;
  };
  ServeOptions o;
  o.maps_dir = tmp.Path("maps");
  Running server(o);
  httplib::Client c = server.Client();
  const auto pose_of = [](const json& j) {
    return std::pair{Eigen::Quaterniond(j["q"][0], j["q"][1], j["q"][2], j["q"][3]),
                     Eigen::Vector3d(j["center"][0], j["center"][1], j["center"][2])};
  };
  // Multipart: the photo and its camera.
  auto r = c.Post("/v1/maps/fountain/localize",
                  httplib::MultipartFormDataItems{{"image", photo, "0000.jpg", "image/jpeg"},
                                                  {"camera", camera, "", ""}});
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  json j = json::parse(r->body);
  ASSERT_TRUE(j["success"].get<bool>()) << r->body;
  auto [q1, c1] = pose_of(j);
  expect_near(q1, c1, "multipart");
  // Client features (the device's own SIFT).
  const SiftFeatures features = ExtractSift(ReadGreyImage(photo_path));
  json kp = json::array();
  for (const SiftKeypoint& k : features.keypoints) kp.push_back({k.x, k.y});
  const json body = {{"camera",
                      {{"model", "PINHOLE"},
                       {"width", 1536},
                       {"height", 1024},
                       {"params", {1379.74, 1382.08, 760.095, 503.155}}}},
                     {"keypoints", kp},
                     {"descriptors", Base64Encode(features.descriptors)}};
  r = c.Post("/v1/maps/fountain/localize", body.dump(), "application/json");
  ASSERT_EQ(r->status, 200) << r->body;
  j = json::parse(r->body);
  ASSERT_TRUE(j["success"].get<bool>()) << r->body;
  auto [q2, c2] = pose_of(j);
  expect_near(q2, c2, "features");
  // OSCP GeoPose: WGS84 back to the map frame.
  const json req = {
      {"id", "req-1"},
      {"timestamp", 0},
      {"type", "geopose"},
      {"sensorReadings",
       {{"cameraReadings",
         {{{"sensorId", "cam"},
           {"imageFormat", "RGBA32"},  // the reference client's label for JPEG bytes
           {"size", {1536, 1024}},
           {"imageOrientation", {{"mirrored", false}, {"rotation", 0}}},  // upright: accepted
           {"imageBytes", Base64Encode(std::vector<uint8_t>(photo.begin(), photo.end()))},
           {"params",
            {{"model", "PINHOLE"}, {"modelParams", {1379.74, 1382.08, 760.095, 503.155}}}}}}}}}};
  // A camera field OSCP does not have (a distortion) would be dropped: refused, named.
  json with_k1 = req;
  with_k1["sensorReadings"]["cameraReadings"][0]["params"]["k1"] = 0.5;
  r = c.Post("/geopose", with_k1.dump(), "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400) << r->body;
  EXPECT_NE(r->body.find(R"(params: unknown field \"k1\")"), std::string::npos) << r->body;
  // Fields OSCP does not have would be ignored (a client's "options"), and a turned photo would
  // be used as it stands: refused, named.
  json with_options = req;
  with_options["options"] = {{"threshold", 2}};
  r = c.Post("/geopose", with_options.dump(), "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400) << r->body;
  EXPECT_NE(r->body.find(R"(GeoPoseReq: unknown field \"options\" (id, timestamp)"),
            std::string::npos)
      << r->body;
  json turned = req;
  turned["sensorReadings"]["cameraReadings"][0]["imageOrientation"]["rotation"] = 90;
  r = c.Post("/geopose", turned.dump(), "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400) << r->body;
  EXPECT_NE(r->body.find("cameraReadings[0].imageOrientation:"), std::string::npos) << r->body;
  r = c.Post("/geopose", req.dump(), "application/json");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  j = json::parse(r->body);
  EXPECT_EQ(j["id"], "req-1");
  EXPECT_EQ(j["type"], "geopose");
  const json& g = j["geopose"];
  const Eigen::Vector3d centre =
      MapPointFromGeodetic(anchor, g["position"]["lat"], g["position"]["lon"], g["position"]["h"]);
  const Eigen::Quaterniond enu_from_cam(g["quaternion"]["w"], g["quaternion"]["x"],
                                        g["quaternion"]["y"], g["quaternion"]["z"]);
  const Eigen::Quaterniond cam_from_map =
      (anchor.enu_from_map.rotation.inverse() * enu_from_cam).inverse();
  expect_near(cam_from_map, centre, "geopose");
}

// A map's geo-anchor: a field the pose does not have is refused, naming it, as is a missing one.
TEST(Geo, AnAnchorsPoseHasQTAndScaleOnly) {
  json j = {{"geo_anchor",
             {{"lat", 48.85},
              {"lon", 2.35},
              {"h", 35},
              {"enu_from_map", {{"q", {1, 0, 0, 0}}, {"t", {0, 0, 0}}, {"scale", 1.0}}}}}};
  EXPECT_EQ(GeoAnchorFromJson(j, "m.json").enu_from_map.scale, 1.0);
  auto error = [&](const json& anchor) {
    try {
      GeoAnchorFromJson(anchor, "m.json");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  json extra = j;
  extra["geo_anchor"]["enu_from_map"]["Q"] = {1, 0, 0, 0};
  EXPECT_EQ(error(extra), "m.json: geo_anchor.enu_from_map: unknown field \"Q\" (q, t, scale)");
  json no_t = j;
  no_t["geo_anchor"]["enu_from_map"].erase("t");
  EXPECT_EQ(error(no_t), "m.json: geo_anchor.enu_from_map.t: missing");
}

TEST(Geo, GeodeticRoundTripsAndPosesComeBack) {
  for (const auto& [lat, lon, h] :
       {std::tuple{46.5191, 6.5668, 400.0}, {-33.9, 151.2, 10.0}, {78.2, -15.6, 1500.0}}) {
    const Eigen::Vector3d g = GeodeticFromEcef(EcefFromGeodetic(lat, lon, h));
    EXPECT_NEAR(g.x(), lat, 1e-10);
    EXPECT_NEAR(g.y(), lon, 1e-10);
    EXPECT_NEAR(g.z(), h, 1e-6);
  }
  GeoAnchor a;
  a.lat_deg = 46.5191;
  a.lon_deg = 6.5668;
  a.h_m = 400;
  a.enu_from_map = Sim3d(2.0, Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ())),
                         Eigen::Vector3d(10, -5, 1));
  const Rigid3d cam_from_world(
      Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, -1, 2).normalized())),
      Eigen::Vector3d(3, 1, -2));
  const GeoPose p = GeoPoseOfCamera(a, cam_from_world);
  const Eigen::Vector3d back = MapPointFromGeodetic(a, p.lat_deg, p.lon_deg, p.h_m);
  EXPECT_LT((back - cam_from_world.Inverse().translation).norm(), 1e-6);
  // The camera's optical axis in ENU is the map's, rotated by enu_from_map.
  const Eigen::Vector3d axis_map = cam_from_world.rotation.inverse() * Eigen::Vector3d::UnitZ();
  EXPECT_LT(
      (p.enu_from_camera * Eigen::Vector3d::UnitZ() - a.enu_from_map.rotation * axis_map).norm(),
      1e-12);
}

// The real binary: SIGHUP during load adds a map, SIGTERM during load lets
// every accepted request finish and exits 0.
TEST(Serve, SighupReloadsAndSigtermDrainsUnderLoad) {
  Fixture f;
  std::filesystem::remove(f.tmp.Path("maps/other.lcm"));
  ServedBinary server({"serve", "--maps", f.tmp.Path("maps"), "--listen", "127.0.0.1:0",
                       "--threads", "2", "--queue", "64"},
                      f.tmp.Path("serve.err"));
  const int port = server.port();
  const pid_t pid = server.pid();
  ASSERT_GT(port, 0) << server.err();
  const std::string body = FeaturesBody(f.scene).dump();
  std::atomic<int> ok = 0, failed = 0;
  const auto load = [&](int n) {
    std::vector<std::thread> clients;
    for (int k = 0; k < 4; ++k) {
      clients.emplace_back([&, n] {  // n by value: load() returns before they end
        httplib::Client c("127.0.0.1", port);
        for (int i = 0; i < n; ++i) {
          const auto r = c.Post("/v1/maps/synth/localize", body, "application/json");
          if (r && r->status == 200 && json::parse(r->body)["success"].get<bool>()) {
            ++ok;
          } else if (r) {
            ++failed;
          }
        }
      });
    }
    return clients;
  };
  auto first = load(10);
  std::filesystem::copy_file(f.tmp.Path("maps/synth.lcm"), f.tmp.Path("maps/late.lcm"));
  ::kill(pid, SIGHUP);
  for (auto& t : first) t.join();
  EXPECT_EQ(ok.load(), 40);
  EXPECT_EQ(failed.load(), 0);
  httplib::Client c("127.0.0.1", port);
  EXPECT_EQ(json::parse(c.Get("/v1/maps")->body)["maps"].size(), 2u);
  ok = 0;
  auto second = load(10);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ::kill(pid, SIGTERM);
  for (auto& t : second) t.join();
  const int status = server.Wait();
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << server.err();
  EXPECT_EQ(failed.load(), 0);  // no request cut: answered, or never accepted
  EXPECT_GT(ok.load(), 0);
}

}  // namespace
}  // namespace linecloud
