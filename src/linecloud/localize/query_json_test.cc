#include "linecloud/localize/query_json.h"

#include <fstream>

#include <gtest/gtest.h>

#include "linecloud/io/json_util.h"
#include "linecloud/testing/test_util.h"

namespace linecloud {
namespace {

nlohmann::json ValidQuery() {
  return nlohmann::json::parse(R"({
    "cameras": [{"model": "PINHOLE", "width": 640, "height": 480, "params": [500, 500, 320, 240]},
                {"model": "SIMPLE_RADIAL", "width": 640, "height": 480, "params": [500, 320, 240, 0.01]}],
    "cam_from_rig": [{"q": [1, 0, 0, 0], "t": [0, 0, 0]}, {"q": [0, 0, 1, 0], "t": [0.1, 0, 0]}],
    "observations": [{"camera": 0, "xy": [10.5, 20.5], "id": 7, "ratio": 0.25},
                     {"camera": 1, "xy": [1, 2], "id": 8, "ratio": 0.75}],
    "points_local": [[1, 2, 3], [4, 5, 6]],
    "gravity_query": [0, 1, 0], "gravity_map": [0, -1, 0], "ground_truth": {}})");
}

TEST(QueryJson, RoundTripsEveryField) {
  const Query q = ParseQueryJson(ValidQuery(), "q.json");
  ASSERT_EQ(q.cameras.size(), 2u);
  EXPECT_EQ(q.cameras[1].model_id, CameraModelId::kSimpleRadial);
  ASSERT_EQ(q.cam_from_rig.size(), 2u);
  EXPECT_NEAR(q.cam_from_rig[1].rotation.y(), 1.0, 1e-15);
  ASSERT_EQ(q.observations.size(), 2u);
  EXPECT_EQ(q.observations[1].camera, 1);
  EXPECT_EQ(q.observations[0].id, 7u);
  EXPECT_EQ(q.observations[0].xy, Eigen::Vector2d(10.5, 20.5));
  EXPECT_EQ(q.observations[1].match_ratio, 0.75);
  EXPECT_EQ(q.points_local[1], Eigen::Vector3d(4, 5, 6));
  EXPECT_EQ(*q.gravity_map, Eigen::Vector3d(0, -1, 0));
  const Query again = ParseQueryJson(QueryToJson(q), "again");
  EXPECT_EQ(QueryToJson(again), QueryToJson(q));
}

TEST(QueryJson, ErrorsNameTheField) {
  const auto error = [](const std::function<void(nlohmann::json&)>& edit) {
    nlohmann::json j = ValidQuery();
    edit(j);
    return testing::ErrorOf([&] { ParseQueryJson(j, "q.json"); });
  };
  EXPECT_NE(error([](auto& j) { j.erase("cameras"); }).find("q.json: field 'cameras' is missing"),
            std::string::npos);
  EXPECT_NE(error([](auto& j) {
              j["cameras"][1]["model"] = "FISHEYE_42";
            }).find("q.json: cameras[1].model"),
            std::string::npos);
  EXPECT_NE(error([](auto& j) {
              j["cameras"][0]["params"] = {500, 320};
            }).find("cameras[0]"),
            std::string::npos);
  // A field the camera does not have is refused (it would be ignored); COLMAP's and pycolmap's
  // identity fields are not.
  EXPECT_EQ(error([](auto& j) { j["cameras"][0]["focal_length"] = 600; }),
            "q.json: cameras[0]: unknown field \"focal_length\" (model, width, height, params)");
  // A field spelt with another case is named as it was sent, not as a missing field.
  EXPECT_EQ(error([](auto& j) {
              j["cameras"][0]["Model"] = j["cameras"][0]["model"];
              j["cameras"][0].erase("model");
            }),
            "q.json: cameras[0]: unknown field \"Model\" (model, width, height, params)");
  EXPECT_EQ(error([](auto& j) {
              j["cameras"][0]["camera_id"] = 3;
              j["cameras"][0]["has_prior_focal_length"] = true;
            }),
            "");
  EXPECT_NE(error([](auto& j) { j["observations"][1].erase("xy"); }).find("observations[1]"),
            std::string::npos);
  EXPECT_NE(error([](auto& j) {
              j["observations"][0]["id"] = -3;
            }).find("observations[0].id: expected a non-negative integer"),
            std::string::npos);
  EXPECT_NE(error([](auto& j) {
              j["observations"][0]["xy"] = {1};
            }).find("observations[0].xy: expected [u, v]"),
            std::string::npos);
  EXPECT_NE(error([](auto& j) {
              j["points_local"][1] = {1, "a", 3};
            }).find("points_local[1]"),
            std::string::npos);
  EXPECT_NE(error([](auto& j) {
              j["cam_from_rig"][0]["q"] = {0, 0, 0, 0};
            }).find("cam_from_rig[0].q: zero quaternion"),
            std::string::npos);
  EXPECT_NE(error([](auto& j) {
              j["gravity_map"] = {0, 1};
            }).find("gravity_map"),
            std::string::npos);
  EXPECT_NE(error([](auto& j) { j = nlohmann::json::array(); }).find("expected a JSON object"),
            std::string::npos);
  // [harden] 5: 4294967296 used to wrap to camera 0.
  EXPECT_NE(error([](auto& j) {
              j["observations"][0]["camera"] = 4294967296ll;
            }).find("observations[0].camera: expected a camera index"),
            std::string::npos);
  EXPECT_NE(
      error([](auto& j) { j["observations"][0]["camera"] = -1; }).find("observations[0].camera"),
      std::string::npos);
  EXPECT_NE(error([](auto& j) {
              j["observations"][1]["ratio"] = -0.5;
            }).find("observations[1].ratio: expected a match's Lowe ratio"),
            std::string::npos);
  EXPECT_NE(
      error([](auto& j) { j["observations"][1]["ratio"] = "good"; }).find("observations[1].ratio"),
      std::string::npos);
}

TEST(Json, AKeyTwiceInOneObjectIsRefusedNamingItAndTheSource) {
  EXPECT_EQ(
      testing::ErrorOf([] { ParseJsonUniqueKeys(R"({"a": 1, "b": {"a": 2}, "a": 3})", "body"); }),
      "body: the key \"a\" appears twice in one object");
  EXPECT_EQ(testing::ErrorOf([] {
              ParseJsonUniqueKeys(R"({"frames": [{"camera": {}, "camera": {}}]})", "body");
            }),
            "body: the key \"camera\" appears twice in one object");
  // The same key in sibling or nested objects is fine, and the value is what the parser gives.
  const nlohmann::json j =
      ParseJsonUniqueKeys(R"([{"a": 1}, {"a": 2, "b": {"a": [{"a": 3}]}}])", "x");
  EXPECT_EQ(j, nlohmann::json::parse(R"([{"a": 1}, {"a": 2, "b": {"a": [{"a": 3}]}}])"));
  EXPECT_THROW(ParseJsonUniqueKeys(R"({"a": )", "x"), nlohmann::json::parse_error);
  testing::TempDir tmp;
  std::ofstream(tmp.Path("q.json")) << R"({"cameras": [], "cameras": []})";
  EXPECT_EQ(testing::ErrorOf([&] { ReadJsonFile(tmp.Path("q.json")); }),
            tmp.Path("q.json") + ": the key \"cameras\" appears twice in one object");
}

}  // namespace
}  // namespace linecloud
