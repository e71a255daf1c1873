// Fuzzes the descriptor-index cache reader (MAP.lcm.index, a file anyone who
// can write beside a map can plant): any content must be refused (nullptr)
// or load an index that searches without crashing. Only a cache that this
// user's secret authenticated reaches the index readers (FLANN's and FAISS's
// trust their input; ours checks its offsets and ids as well).
#include <unistd.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "linecloud/features/descriptor_index.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::vector<uint8_t> descriptors = [] {
    std::vector<uint8_t> d(64 * 128);
    for (size_t i = 0; i < d.size(); ++i) d[i] = static_cast<uint8_t>((i * 2654435761u) >> 24);
    return d;
  }();
  static const std::string path = "/tmp/linecloud-index-cache-fuzz-" + std::to_string(::getpid());
  const std::array<uint8_t, 32> key{42};
  try {
    linecloud::WriteFileAtomically(path, [&](std::ostream& os) {
      os.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    });
    const auto index = linecloud::DescriptorIndex::Load(path, descriptors, {}, key);
    if (index) index->Match(std::span(descriptors.data(), 128 * 4), {});
  } catch (const linecloud::Error&) {
  }
  std::remove(path.c_str());
  return 0;
}
