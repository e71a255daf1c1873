#include "linecloud/io/colmap_model.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "linecloud/synthetic/scene.h"
#include "linecloud/testing/test_util.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

using testing::DataPath;
using testing::ErrorOf;
using testing::TempDir;

void ExpectSameModel(const Reconstruction& a, const Reconstruction& b) {
  ASSERT_EQ(a.cameras.size(), b.cameras.size());
  for (const auto& [id, ca] : a.cameras) {
    const Camera& cb = b.cameras.at(id);
    EXPECT_EQ(ca.model_id, cb.model_id);
    EXPECT_EQ(ca.width, cb.width);
    EXPECT_EQ(ca.height, cb.height);
    EXPECT_EQ(ca.params, cb.params);
  }
  ASSERT_EQ(a.images.size(), b.images.size());
  for (const auto& [id, ia] : a.images) {
    const Image& ib = b.images.at(id);
    EXPECT_EQ(ia.name, ib.name);
    EXPECT_EQ(ia.camera_id, ib.camera_id);
    EXPECT_EQ(ia.cam_from_world.rotation.coeffs(), ib.cam_from_world.rotation.coeffs());
    EXPECT_EQ(ia.cam_from_world.translation, ib.cam_from_world.translation);
    ASSERT_EQ(ia.points2D.size(), ib.points2D.size());
    for (size_t k = 0; k < ia.points2D.size(); ++k) {
      ASSERT_EQ(ia.points2D[k].xy, ib.points2D[k].xy);
      ASSERT_EQ(ia.points2D[k].point3D_id, ib.points2D[k].point3D_id);
    }
  }
  ASSERT_EQ(a.points3D.size(), b.points3D.size());
  for (const auto& [id, pa] : a.points3D) {
    const Point3D& pb = b.points3D.at(id);
    ASSERT_EQ(pa.xyz, pb.xyz);
    ASSERT_EQ(pa.color, pb.color);
    ASSERT_EQ(pa.error, pb.error);
    ASSERT_EQ(pa.track.size(), pb.track.size());
    for (size_t k = 0; k < pa.track.size(); ++k) {
      ASSERT_EQ(pa.track[k].image_id, pb.track[k].image_id);
      ASSERT_EQ(pa.track[k].point2D_idx, pb.track[k].point2D_idx);
    }
  }
}

TEST(ColmapModel, ReadsMaupertuisText) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/reconstruction");
  const Reconstruction rec = ReadColmapModel(DataPath("colmap-maupertuis/reconstruction"));
  ASSERT_EQ(rec.cameras.size(), 1u);
  const Camera& camera = rec.cameras.at(1);
  EXPECT_EQ(camera.model_id, CameraModelId::kSimplePinhole);
  EXPECT_EQ(camera.width, 1919u);
  EXPECT_EQ(camera.params, (std::vector<double>{1847.53, 959.5, 539.5}));
  ASSERT_EQ(rec.images.size(), 4u);
  EXPECT_EQ(rec.images.at(4).name, "03.jpg");
  EXPECT_NEAR(rec.images.at(4).cam_from_world.translation.x(), -7.96417, 1e-12);
  EXPECT_EQ(rec.images.at(1).points2D.size(), 6424u);
  EXPECT_EQ(rec.points3D.size(), 1039u);
  const Point3D& p = rec.points3D.at(708);
  EXPECT_EQ(p.xyz, Eigen::Vector3d(-2.39675, 4.62278, 13.2759));
  EXPECT_EQ(p.track.size(), 4u);
  EXPECT_NEAR(rec.MeanTrackLength(), 3.22907, 1e-5);
  // Every track element points back at its 3D point.
  for (const auto& [id, point] : rec.points3D) {
    for (const TrackElement& el : point.track) {
      ASSERT_EQ(rec.images.at(el.image_id).points2D.at(el.point2D_idx).point3D_id, id);
    }
  }
}

TEST(ColmapModel, TextBinaryRoundTripOnRealModel) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/reconstruction");
  const Reconstruction rec = ReadColmapModel(DataPath("colmap-maupertuis/reconstruction"));
  TempDir tmp;
  WriteColmapModel(rec, tmp.Path("bin"), ModelFormat::kBinary);
  const Reconstruction from_bin = ReadColmapModel(tmp.Path("bin"));
  ExpectSameModel(rec, from_bin);
  WriteColmapModel(from_bin, tmp.Path("txt"), ModelFormat::kText);
  const Reconstruction from_txt = ReadColmapModel(tmp.Path("txt"));
  ExpectSameModel(rec, from_txt);
  // Binary written again from the text copy is byte-identical.
  WriteColmapModel(from_txt, tmp.Path("bin2"), ModelFormat::kBinary);
  for (const char* f : {"cameras.bin", "images.bin", "points3D.bin"}) {
    EXPECT_EQ(ReadFileToString(tmp.Path(std::string("bin/") + f)),
              ReadFileToString(tmp.Path(std::string("bin2/") + f)));
  }
}

TEST(ColmapModel, SyntheticRoundTripWithRigsAndFrames) {
  SyntheticSceneOptions options;
  options.num_points = 500;
  options.num_map_images = 8;
  options.num_queries = 0;
  Reconstruction rec = GenerateSyntheticScene(options).model;
  Rig rig;
  rig.rig_id = 1;
  rig.ref_sensor = SensorId{0, 1};
  rig.sensors.push_back(
      {SensorId{0, 2}, Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.11, 0, 0))});
  rig.sensors.push_back({SensorId{1, 1}, std::nullopt});
  rec.rigs[1] = rig;
  Frame frame;
  frame.frame_id = 7;
  frame.rig_id = 1;
  frame.rig_from_world.translation = Eigen::Vector3d(1, 2, 3);
  frame.data = {{SensorId{0, 1}, 1}, {SensorId{0, 2}, 2}};
  rec.frames[7] = frame;
  TempDir tmp;
  WriteColmapModel(rec, tmp.Path(), ModelFormat::kBinary);
  const Reconstruction back = ReadColmapModel(tmp.Path());
  ExpectSameModel(rec, back);
  ASSERT_EQ(back.rigs.size(), 1u);
  ASSERT_EQ(back.rigs.at(1).sensors.size(), 2u);
  EXPECT_EQ(back.rigs.at(1).sensors[0].sensor_from_rig->translation.x(), 0.11);
  EXPECT_FALSE(back.rigs.at(1).sensors[1].sensor_from_rig.has_value());
  ASSERT_EQ(back.frames.at(7).data.size(), 2u);
  EXPECT_EQ(back.frames.at(7).rig_from_world.translation, Eigen::Vector3d(1, 2, 3));
}

TEST(ColmapModel, TruncatedBinaryFilesGiveErrorsNamingTheFile) {
  SyntheticSceneOptions options;
  options.num_points = 200;
  options.num_map_images = 4;
  options.num_queries = 0;
  const Reconstruction rec = GenerateSyntheticScene(options).model;
  TempDir tmp;
  WriteColmapModel(rec, tmp.Path(), ModelFormat::kBinary);
  for (const char* name : {"cameras.bin", "images.bin", "points3D.bin"}) {
    const std::string path = tmp.Path(name);
    const std::string full = ReadFileToString(path);
    for (const size_t keep : {size_t{0}, size_t{5}, full.size() / 2, full.size() - 1}) {
      std::ofstream(path, std::ios::binary | std::ios::trunc).write(full.data(), keep);
      const std::string message = ErrorOf([&] { ReadColmapModel(tmp.Path()); });
      EXPECT_NE(message.find(name), std::string::npos)
          << name << " cut at " << keep << ": '" << message << "'";
    }
    std::ofstream(path, std::ios::binary | std::ios::trunc).write(full.data(), full.size());
  }
  // A corrupt count cannot cause a huge allocation.
  std::string data = ReadFileToString(tmp.Path("points3D.bin"));
  data[7] = '\x7f';
  EXPECT_NE(ErrorOf([&] {
              Reconstruction r;
              ParsePoints3DBinary(data, "points3D.bin", &r);
            }).find("corrupt or truncated"),
            std::string::npos);
}

void WriteText(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

TEST(ColmapModel, BadTextModelsGiveClearErrors) {
  TempDir tmp;
  const std::string cams = "1 PINHOLE 640 480 500 500 320 240\n";
  const std::string images =
      "1 1 0 0 0 0 0 0 1 a.png\n10 20 1 30 40 -1\n2 1 0 0 0 1 0 0 1 b.png\n11 21 1\n";
  const std::string points = "1 0.5 0.25 4 255 0 0 0.3 1 0 2 0\n";
  const auto write_model = [&](const std::string& c, const std::string& i, const std::string& p) {
    WriteText(tmp.Path("cameras.txt"), c);
    WriteText(tmp.Path("images.txt"), i);
    WriteText(tmp.Path("points3D.txt"), p);
  };
  write_model(cams, images, points);
  EXPECT_EQ(ReadColmapModel(tmp.Path()).points3D.size(), 1u);

  write_model("1 FOV 640 480 500 320 240 0.1\n", images, points);
  EXPECT_NE(ErrorOf([&] { ReadColmapModel(tmp.Path()); }).find("unsupported camera model 'FOV'"),
            std::string::npos);
  write_model("1 PINHOLE 640 480 500 320 240\n", images, points);
  EXPECT_NE(ErrorOf([&] { ReadColmapModel(tmp.Path()); }).find("takes 4 parameters"),
            std::string::npos);
  write_model(cams, images, "1 nan 0.25 4 255 0 0 0.3 1 0 2 0\n");
  const std::string nan_error = ErrorOf([&] { ReadColmapModel(tmp.Path()); });
  EXPECT_NE(nan_error.find("points3D.txt:1"), std::string::npos) << nan_error;
  EXPECT_NE(nan_error.find("not finite"), std::string::npos) << nan_error;
  write_model(cams, images, "1 0.5 0.25 4 255 0 0 0.3 1 0 9 0\n");
  EXPECT_NE(ErrorOf([&] { ReadColmapModel(tmp.Path()); }).find("refers to image 9"),
            std::string::npos);
  write_model(cams, "1 1 0 0 0 0 0 0 1 a.png\n", points);
  EXPECT_NE(ErrorOf([&] { ReadColmapModel(tmp.Path()); }).find("missing POINTS2D"),
            std::string::npos);
  write_model(cams, images, "1 0.5 0.25 4 255 0 0 0.3 1\n");
  EXPECT_NE(ErrorOf([&] { ReadColmapModel(tmp.Path()); }).find("points3D.txt:1"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { ReadColmapModel(tmp.Path("nope")); }).find("not a directory"),
            std::string::npos);
  std::filesystem::create_directories(tmp.Path("empty"));
  EXPECT_NE(ErrorOf([&] { ReadColmapModel(tmp.Path("empty")); }).find("no COLMAP model"),
            std::string::npos);
}

}  // namespace
}  // namespace linecloud
