#include "linecloud/io/lcm_format.h"

#include <random>

#include <gtest/gtest.h>

#include "linecloud/lifting/lifting.h"
#include "linecloud/testing/test_util.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

LineCloud MakeCloud(LineEncoding encoding, bool descriptors) {
  std::mt19937_64 rng(9);
  std::normal_distribution<double> g(0.0, 5.0);
  std::vector<uint64_t> ids;
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 300; ++i) {
    ids.push_back(10 + 3 * i);
    points.emplace_back(g(rng), g(rng), g(rng));
  }
  LineCloud cloud = LiftPoints(ids, points, DemoLiftingKey(), {encoding});
  if (descriptors) {
    cloud.descriptor_dim = 128;
    cloud.descriptor_type = "colmap-sift-uint8";
    cloud.descriptor_aggregation = "medoid";
    cloud.descriptors.resize(ids.size() * 128);
    for (uint8_t& b : cloud.descriptors) b = static_cast<uint8_t>(rng());
  }
  return cloud;
}

TEST(LcmFormat, RoundTripsEveryEncoding) {
  for (const LineEncoding encoding : {LineEncoding::kPlucker, LineEncoding::kCompact}) {
    for (const bool descriptors : {false, true}) {
      const LineCloud cloud = MakeCloud(encoding, descriptors);
      const std::string bytes = SerializeLineCloud(cloud);
      const LineCloud back = ParseLineCloud(bytes, "mem.lcm");
      EXPECT_EQ(back.encoding, encoding);
      EXPECT_EQ(back.ids, cloud.ids);
      ASSERT_EQ(back.lines.size(), cloud.lines.size());
      for (size_t i = 0; i < cloud.size(); ++i) {
        ASSERT_EQ(back.lines[i].v, cloud.lines[i].v);
        ASSERT_EQ(back.lines[i].w, cloud.lines[i].w);
      }
      EXPECT_EQ(back.descriptors, cloud.descriptors);
      EXPECT_EQ(back.descriptor_aggregation, cloud.descriptor_aggregation);
      EXPECT_EQ(back.key_fingerprint, cloud.key_fingerprint);
      // Writing what was read reproduces the bytes exactly.
      EXPECT_EQ(SerializeLineCloud(back), bytes);
      // Sizes: 48 (or 9) bytes per line + 8 per id + descriptors + header.
      const size_t per_line =
          (encoding == LineEncoding::kPlucker ? 48 : 9) + 8 + (descriptors ? 128 : 0);
      EXPECT_GE(bytes.size(), per_line * cloud.size());
      EXPECT_LT(bytes.size(), per_line * cloud.size() + 2048);
    }
  }
}

std::string ErrorOf(const std::string& bytes) {
  try {
    ParseLineCloud(bytes, "map.lcm");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(LcmFormat, TruncatedOrCorruptFilesAreRejected) {
  const std::string bytes = SerializeLineCloud(MakeCloud(LineEncoding::kPlucker, true));
  for (size_t keep = 0; keep < bytes.size(); keep += 97) {
    const std::string message = ErrorOf(bytes.substr(0, keep));
    ASSERT_NE(message.find("map.lcm"), std::string::npos) << "cut at " << keep;
  }
  EXPECT_NE(ErrorOf(bytes.substr(0, bytes.size() - 1)).find("checksum"), std::string::npos);
  std::mt19937_64 rng(10);
  for (int trial = 0; trial < 200; ++trial) {
    std::string corrupt = bytes;
    const size_t pos = rng() % corrupt.size();
    corrupt[pos] = static_cast<char>(corrupt[pos] ^ (1 + rng() % 255));
    EXPECT_FALSE(ErrorOf(corrupt).empty()) << "flip at " << pos;
  }
  std::string bad_magic = bytes;
  bad_magic[0] = 'X';
  EXPECT_NE(ErrorOf(bad_magic).find("bad magic"), std::string::npos);
  std::string version = bytes;
  version[8] = 9;
  EXPECT_NE(ErrorOf(version).find("unsupported .lcm format version 9"), std::string::npos);
}

TEST(LcmFormat, WriterRefusesInvalidClouds) {
  LineCloud cloud = MakeCloud(LineEncoding::kPlucker, false);
  cloud.lines[3].v *= 2.0;  // not a unit direction
  EXPECT_THROW(SerializeLineCloud(cloud), Error);
  cloud = MakeCloud(LineEncoding::kPlucker, false);
  cloud.lines[5].w += cloud.lines[5].v;  // moment not orthogonal
  EXPECT_THROW(SerializeLineCloud(cloud), Error);
  cloud = MakeCloud(LineEncoding::kPlucker, false);
  cloud.ids[1] = cloud.ids[0];
  EXPECT_THROW(SerializeLineCloud(cloud), Error);
  testing::TempDir tmp;
  EXPECT_THROW(WriteLineCloud(cloud, tmp.Path("x.lcm")), Error);
  EXPECT_FALSE(FileExists(tmp.Path("x.lcm")));
  // The writer holds to the reader's limits ([harden] 4).
  cloud = MakeCloud(LineEncoding::kPlucker, false);
  cloud.descriptor_dim = kLcmMaxDescriptorDim + 1;
  cloud.descriptors.assign(cloud.size() * cloud.descriptor_dim, 1);
  cloud.descriptor_type = "x";
  EXPECT_THROW(SerializeLineCloud(cloud), Error);
}

// A map with no line is written and read back (no memcpy from a null pointer:
// UBSan checks this in scripts/sanitize.sh).
TEST(LcmFormat, AnEmptyMapRoundTrips) {
  LineCloud empty;
  const LineCloud back = ParseLineCloud(SerializeLineCloud(empty), "empty.lcm");
  EXPECT_EQ(back.size(), 0u);
}

}  // namespace
}  // namespace linecloud
