// Helpers shared by the tests: where the real data lives, temporary folders.
#pragma once

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include <gtest/gtest.h>

#include "linecloud/solvers/minimal_problem.h"
#include "linecloud/util/error.h"

namespace linecloud::testing {

// Names of the methods with a minimal solver, for value-parameterised tests,
// and a gtest-safe test name for each ("m-P3P+l" → "m_P3P_l").
inline std::vector<std::string_view> ImplementedMethodNames() {
  std::vector<std::string_view> names;
  for (const MethodInfo& m : AllMethods()) {
    if (m.implemented) names.push_back(m.name);
  }
  return names;
}
inline std::string MethodTestName(const ::testing::TestParamInfo<std::string_view>& info) {
  std::string name(info.param);
  for (char& c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return name;
}

// Instance counts of the statistical tests: `full` normally; a tenth when
// LINECLOUD_QUICK_TESTS is set (the sanitizer job, which looks for memory and
// UB errors, not statistics; the release run asserts on the full counts).
inline int InstanceCount(int full) {
  return std::getenv("LINECLOUD_QUICK_TESTS") ? std::max(full / 10, 1) : full;
}

// ../shared next to the checkout, or $LINECLOUD_SHARED.
inline std::string SharedDir() {
  if (const char* env = std::getenv("LINECLOUD_SHARED")) return env;
  return LINECLOUD_SHARED_DIR;
}

inline std::string SharedDataPath(const std::string& relative) {
  return (std::filesystem::path(SharedDir()) / "data" / relative).string();
}

// Skips the test, saying why, when a real data set is not present.
#define LINECLOUD_REQUIRE_DATA(relative)                                                     \
  do {                                                                                       \
    if (!std::filesystem::exists(::linecloud::testing::SharedDataPath(relative))) {          \
      GTEST_SKIP() << "real data absent: " << ::linecloud::testing::SharedDataPath(relative) \
                   << " (set LINECLOUD_SHARED to the shared/ folder)";                       \
    }                                                                                        \
  } while (0)

// The message of the linecloud::Error that `f` throws ("" when none).
template <typename F>
std::string ErrorOf(const F& f) {
  try {
    f();
  } catch (const ::linecloud::Error& e) {
    return e.what();
  }
  return "";
}

// A fresh empty folder under the system temp dir, removed at destruction.
class TempDir {
 public:
  TempDir() {
    std::random_device rd;
    path_ = std::filesystem::temp_directory_path() /
            ("linecloud_test_" + std::to_string(rd()) + std::to_string(rd()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  std::string Path(const std::string& name = "") const {
    return name.empty() ? path_.string() : (path_ / name).string();
  }

 private:
  std::filesystem::path path_;
};

// Asserts that no coordinate of `points` appears in `bytes`: each coordinate
// as a float64, and each adjacent pair (x, y), (y, z) as two float32 (single
// float32 values are too short: 4 random bytes match somewhere in a large
// file by chance).
template <typename Points>
void ExpectNoCoordinates(const std::string& bytes, const Points& points) {
  const auto contains = [&](const void* p, size_t n) {
    return bytes.find(std::string(static_cast<const char*>(p), n)) != std::string::npos;
  };
  for (const auto& x : points) {
    for (int k = 0; k < 3; ++k) {
      const double d = x[k];
      ASSERT_FALSE(contains(&d, 8)) << "coordinate " << d << " found as float64";
    }
    for (int k = 0; k < 2; ++k) {
      const float pair[2] = {static_cast<float>(x[k]), static_cast<float>(x[k + 1])};
      ASSERT_FALSE(contains(pair, 8)) << "coordinates found as float32";
    }
  }
}

}  // namespace linecloud::testing
