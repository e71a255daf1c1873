// serve/localize_body: a localize request read from the wire — one photo or a
// device's frames — with what a stranger may send instead (the service's
// tests through the real binary are in python/tests/test_rigs.py).
#include "linecloud/serve/localize_body.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "linecloud/util/base64.h"

namespace linecloud {
namespace {

using json = nlohmann::json;

const char* kCamera = "PINHOLE 640 480 500 500 320 240";

json Frame(int keypoints, double tx) {
  json kp = json::array();
  for (int i = 0; i < keypoints; ++i) kp.push_back({10.0 + i, 20.0});
  return {
      {"camera",
       {{"model", "PINHOLE"}, {"width", 640u}, {"height", 480u}, {"params", {500, 500, 320, 240}}}},
      {"keypoints", kp},
      {"descriptors", Base64Encode(std::vector<uint8_t>(128 * keypoints, 1))},
      {"cam_from_rig", {{"q", {1, 0, 0, 0}}, {"t", {tx, 0, 0}}}}};
}

std::string Error(const std::function<void()>& read) {
  try {
    read();
  } catch (const FramesOverLimit& e) {
    return std::string("413 ") + e.what();
  } catch (const linecloud::Error& e) {
    return e.what();
  }
  return "no error";
}

TEST(LocalizeBody, JsonFramesWithTheRigsFields) {
  json j = {{"frames", {Frame(3, 0), Frame(2, 0.5)}},
            {"points_local", {{{"frame", 1}, {"keypoint", 1}, {"xyz", {1, 2, 3}}}}},
            {"scale_known", true},
            {"gravity", {0, 1, 0}},
            {"threshold", 3}};
  const LocalizeBody b = ReadJsonBody(j, 8);
  ASSERT_EQ(b.frames.size(), 2u);
  EXPECT_EQ(b.frames[1].name, "frames[1]");
  EXPECT_EQ(b.frames[1].features.size(), 2u);
  EXPECT_EQ(b.frames[1].cam_from_rig.translation, Eigen::Vector3d(0.5, 0, 0));
  ASSERT_EQ(b.points_local.size(), 1u);
  EXPECT_EQ(b.points_local[0].keypoint, 1);
  EXPECT_EQ(b.points_local[0].xyz, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(b.scale_known, true);
  EXPECT_EQ(*b.gravity, Eigen::Vector3d(0, 1, 0));
  EXPECT_EQ(b.options, (json{{"threshold", 3}}));  // options as sent: the server checks them
  const std::vector<QueryPhoto> photos = b.Photos();
  ASSERT_EQ(photos.size(), 2u);
  EXPECT_EQ(photos[0].features, &b.frames[0].features);
  EXPECT_TRUE(photos[0].encoded.empty());
  // One photo as before: its fields at the top.
  json one = Frame(4, 0);
  one.erase("cam_from_rig");
  EXPECT_EQ(ReadJsonBody(one, 8).frames.size(), 1u);
}

TEST(LocalizeBody, MultipartFramesInOrderWithTheirPoses) {
  const std::string pose = R"({"q": [1, 0, 0, 0], "t": [0.25, 0, 0]})";
  const std::map<std::string, std::string> parts = {
      {"image[0]", "A"},
      {"image[1]", "B"},
      {"camera", kCamera},
      {"cam_from_rig[0]", pose},
      {"cam_from_rig[1]", pose},
      {"scale_known", "false"},
      {"points_local", R"([{"frame": 1, "keypoint": 0, "xyz": [0, 0, 2]}])"},
      {"seed", "7"}};
  const LocalizeBody b = ReadMultipartBody(parts, 8);
  ASSERT_EQ(b.frames.size(), 2u);
  EXPECT_EQ(b.frames[1].image, "B");
  EXPECT_EQ(b.frames[1].name, "image[1]");
  EXPECT_EQ(b.frames[1].cam_from_rig.translation, Eigen::Vector3d(0.25, 0, 0));
  EXPECT_EQ(b.scale_known, false);
  EXPECT_EQ(b.points_local.size(), 1u);
  EXPECT_EQ(b.options, (json{{"seed", 7}}));
}

TEST(LocalizeBody, WhatAStrangerSendsIsRefusedNamingThePart) {
  const auto multipart = [](std::map<std::string, std::string> parts, int max_frames = 8) {
    return Error([&] { ReadMultipartBody(parts, max_frames); });
  };
  const auto body = [](const json& j, int max_frames = 8) {
    return Error([&] { ReadJsonBody(j, max_frames); });
  };
  const std::string pose = R"({"q": [1, 0, 0, 0], "t": [0, 0, 0]})";
  EXPECT_EQ(multipart({{"camera", kCamera}}), "multipart: the 'image' part is missing");
  EXPECT_EQ(multipart({{"image[2]", "A"}, {"image[0]", "A"}, {"camera", kCamera}}),
            "multipart: image[2] without image[1] (frames are image[0], image[1], ... in order)");
  EXPECT_EQ(multipart({{"image[99999]", "A"}, {"camera", kCamera}}),
            "multipart: part \"image[99999]\": expected image[0], image[1], ...");
  EXPECT_EQ(multipart({{"image[-1]", "A"}, {"camera", kCamera}}),
            "multipart: part \"image[-1]\": expected image[0], image[1], ...");
  EXPECT_EQ(multipart({{"image[0]", "A"}, {"camera[0]", kCamera}, {"camera", kCamera}}),
            "multipart: give one 'camera' for every frame or camera[k] for each, not both");
  EXPECT_EQ(multipart({{"image[0]", "A"},
                       {"image[1]", "A"},
                       {"camera[0]", kCamera},
                       {"cam_from_rig[0]", pose},
                       {"cam_from_rig[1]", pose}}),
            "multipart: the 'camera[1]' part is missing");
  EXPECT_EQ(multipart({{"image[0]", "A"}, {"camera", kCamera}, {"cam_from_rig[0]", "{"}}),
            "cam_from_rig[0]: not JSON (parse error at line 1, "
            "column 2: syntax error while parsing object key - unexpected end of input; expected "
            "string literal)");
  EXPECT_EQ(
      multipart({{"image[0]", "A"}, {"image[1]", "A"}, {"image[2]", "A"}, {"camera", kCamera}}, 2),
      "413 3 frames: this server takes at most 2 in one request (serve --max-frames)");
  EXPECT_EQ(multipart({{"image", "A"}, {"camera", kCamera}, {"points_local", "[{}]"}}),
            "points_local[0]: field 'frame' is missing");
  EXPECT_EQ(multipart({{"image", "A"}, {"camera", kCamera}, {"gravity", "0,0,0"}}).substr(0, 8),
            "gravity ");
  json j = {{"frames", {Frame(1, 0), Frame(1, 0)}}};
  EXPECT_EQ(body(j, 1),
            "413 2 frames: this server takes at most 1 in one request (serve "
            "--max-frames)");
  j["frames"][1].erase("cam_from_rig");
  EXPECT_EQ(body(j), "frames[1]: field 'cam_from_rig' is missing (the frame's pose in the rig)");
  // A rigid pose is q and t: a "scale" (a Sim3 pose's) or a misspelt field would be ignored.
  j = {{"frames", {Frame(1, 0), Frame(1, 0)}}};
  j["frames"][1]["cam_from_rig"]["scale"] = 2;
  EXPECT_EQ(body(j),
            "frames[1].cam_from_rig: unknown field \"scale\" (a rigid pose has q and t only)");
  EXPECT_EQ(multipart({{"image[0]", "A"},
                       {"camera", kCamera},
                       {"cam_from_rig[0]", R"({"q": [1, 0, 0, 0], "t": [0, 0, 0], "T": 1})"}}),
            "cam_from_rig[0]: unknown field \"T\" (a rigid pose has q and t only)");
  // A misspelt "Q" is named (not "q is missing"); a pose without t says so.
  j = {{"frames", {Frame(1, 0), Frame(1, 0)}}};
  j["frames"][0]["cam_from_rig"] = {{"Q", {1, 0, 0, 0}}, {"t", {0, 0, 0}}};
  EXPECT_EQ(body(j), "frames[0].cam_from_rig: unknown field \"Q\" (a rigid pose has q and t only)");
  j["frames"][0]["cam_from_rig"] = {{"q", {1, 0, 0, 0}}};
  EXPECT_EQ(body(j),
            "frames[0].cam_from_rig.t: missing (expected {\"q\": [w, x, y, z], \"t\": [x, y, "
            "z]})");
  EXPECT_EQ(body({{"frames", json::array()}}),
            "frames: expected [{camera, keypoints, descriptors, cam_from_rig}, ...]");
  EXPECT_EQ(body({{"frames", {Frame(1, 0)}}, {"points_local", {{{"frame", -1}}}}}),
            "points_local[0].frame: expected an index (0, 1, ...)");
  EXPECT_EQ(body({{"frames", {Frame(1, 0)}},
                  {"points_local", {{{"frame", 0}, {"keypoint", 0}, {"xyz", {0, 0, "1"}}}}}}),
            "points_local[0].xyz: element 2 is not a number");
  EXPECT_EQ(body({{"frames", {Frame(1, 0)}}, {"scale_known", "yes"}}),
            "scale_known: expected true or false");
  // A direction of huge numbers is a direction (its norm is not finite).
  const LocalizeBody huge =
      ReadJsonBody({{"frames", {Frame(1, 0)}}, {"gravity", {1e308, 1e308, 0}}}, 8);
  EXPECT_NEAR((*huge.gravity).normalized().x(), std::sqrt(0.5), 1e-15);
  json frame = Frame(1, 0);
  frame["camera"]["params"] = {1e308, 500, 320, 240};
  EXPECT_EQ(body({{"frames", {frame}}}).substr(0, 30), "frames[0].camera: focal length");
}

}  // namespace
}  // namespace linecloud
