// Where the tests and benchmarks find the real data sets (docs/data.md): one rule, also in
// scripts/data_dir.sh, python/tests/conftest.py and web/tests/console.test.mjs.
//   1. $LINECLOUD_DATA when set;
//   2. ../shared/data beside the checkout, where it exists;
//   3. data/ inside the checkout (git-ignored: where scripts/get_data.sh puts the sets).
// LINECLOUD_REPO_DIR is the checkout, defined by the build for the targets that include this.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <string>

namespace linecloud::testing {

inline std::string DataDir() {
  if (const char* env = std::getenv("LINECLOUD_DATA"); env && *env) return env;
  const std::filesystem::path repo = LINECLOUD_REPO_DIR;
  const std::filesystem::path beside = repo.parent_path() / "shared" / "data";
  if (std::filesystem::is_directory(beside)) return beside.string();
  return (repo / "data").string();
}

inline std::string DataPath(const std::string& relative) {
  return (std::filesystem::path(DataDir()) / relative).string();
}

}  // namespace linecloud::testing
