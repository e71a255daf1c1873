// The service's test fixtures, shared by its tests and the HTTP fuzzer: the
// tokens every test server reads and a small map with descriptors.
#pragma once

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "linecloud/geometry/plucker.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/serve/tokens.h"
#include "linecloud/util/file.h"

namespace linecloud {

// alice reads map "synth", bob "other", slow may use every map once a
// minute, root is an admin.
inline void WriteTestTokens(const std::string& path) {
  const nlohmann::json tokens = {
      {"tokens",
       {{{"id", "alice"}, {"sha256", TokenSha256Hex("alice-secret")}, {"maps", {"synth"}}},
        {{"id", "bob"}, {"sha256", TokenSha256Hex("bob-secret")}, {"maps", {"other"}}},
        {{"id", "slow"},
         {"sha256", TokenSha256Hex("slow-secret")},
         {"maps", {"*"}},
         {"requests_per_minute", 1}},
        {{"id", "root"},
         {"sha256", TokenSha256Hex("root-secret")},
         {"maps", {"*"}},
         {"admin", true}}}}};
  WriteFileAtomically(path, [&](std::ostream& os) { os << tokens.dump(); });
}

// A small line cloud with descriptors (what the routes need to run).
inline LineCloud SmallCloud() {
  LineCloud cloud;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  cloud.descriptor_dim = 128;
  cloud.descriptor_type = "colmap-sift-uint8";
  cloud.descriptor_aggregation = "medoid";
  for (int i = 0; i < 200; ++i) {
    cloud.ids.push_back(10 + i);
    cloud.lines.push_back(PluckerLine::FromPointAndDirection(
        Eigen::Vector3d(u(rng), u(rng), 5 + u(rng)), Eigen::Vector3d(u(rng), u(rng), u(rng))));
    // SIFT-like: on the sphere of radius 512 (COLMAP's normalisation).
    std::vector<double> v(128);
    double norm = 0;
    for (double& x : v) {
      x = static_cast<double>(rng() % 1000);
      norm += x * x;
    }
    for (const double x : v) {
      cloud.descriptors.push_back(static_cast<uint8_t>(std::lround(512 * x / std::sqrt(norm))));
    }
  }
  return cloud;
}

}  // namespace linecloud
