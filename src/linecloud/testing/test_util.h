// Helpers shared by the tests: where the real data lives, temporary folders.
#pragma once

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include <gtest/gtest.h>

#include "linecloud/solvers/minimal_problem.h"
#include "linecloud/testing/data_dir.h"
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

// Under the test command (scripts/run.sh test sets LINECLOUD_REQUIRE_ALL=1) every part must
// run: a missing prerequisite is then a failure, not a skip.
inline bool RequireAll() {
  const char* v = std::getenv("LINECLOUD_REQUIRE_ALL");
  return v && std::string_view(v) == "1";
}

// A prerequisite (data, a prepared work, a tool) is absent: the test is skipped, saying why, or
// fails under the test command. `reason` may be a stream expression.
#define LINECLOUD_ABSENT(reason)                                       \
  do {                                                                 \
    std::ostringstream absent_reason_;                                 \
    absent_reason_ << reason;                                          \
    if (::linecloud::testing::RequireAll())                            \
      GTEST_FAIL() << "required but absent: " << absent_reason_.str(); \
    GTEST_SKIP() << absent_reason_.str();                              \
  } while (0)

// Skips (or fails, see LINECLOUD_ABSENT) when a real data set is not present.
#define LINECLOUD_REQUIRE_DATA(relative)                                                         \
  do {                                                                                           \
    if (!std::filesystem::exists(::linecloud::testing::DataPath(relative))) {                    \
      LINECLOUD_ABSENT("real data absent: " << ::linecloud::testing::DataPath(relative)          \
                                            << " (scripts/get_data.sh, or set LINECLOUD_DATA)"); \
    }                                                                                            \
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

// A 97-byte PNG whose header says 60000 x 60000 grey pixels (3.6 GB once
// decoded): a decompression bomb for the decoders' and the service's limits.
inline std::string BombPng() {
  const auto chunk = [](const std::string& type, const std::string& data) {
    std::string out;
    for (int s = 24; s >= 0; s -= 8) out += static_cast<char>((data.size() >> s) & 0xff);
    std::string body = type + data;
    uint32_t crc = 0xffffffffu;
    for (const unsigned char c : body) {
      crc ^= c;
      for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
    }
    crc ^= 0xffffffffu;
    out += body;
    for (int s = 24; s >= 0; s -= 8) out += static_cast<char>((crc >> s) & 0xff);
    return out;
  };
  std::string ihdr;
  for (const uint32_t v : {60000u, 60000u})
    for (int s = 24; s >= 0; s -= 8) ihdr += static_cast<char>((v >> s) & 0xff);
  ihdr += std::string("\x08\x00\x00\x00\x00", 5);  // 8-bit grey
  // A zlib stream of zeros (the decoder would have to inflate 3.6 GB of rows
  // to find out).
  const std::string idat("\x78\x9c\x63\x60\x18\x05\xa3\x60\x14\x0c\x77\x00\x00", 13);
  return std::string("\x89PNG\r\n\x1a\n", 8) + chunk("IHDR", ihdr) + chunk("IDAT", idat) +
         chunk("IEND", "");
}

}  // namespace linecloud::testing
