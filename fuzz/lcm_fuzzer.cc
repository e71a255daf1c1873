// Fuzzes the .lcm reader: any input must either parse into a valid line
// cloud or throw linecloud::Error — never crash, hang or over-allocate.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "linecloud/io/lcm_format.h"
#include "linecloud/util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const linecloud::LineCloud cloud = linecloud::ParseLineCloud(
        std::string_view(reinterpret_cast<const char*>(data), size), "fuzz.lcm");
    // A parsed cloud must serialise back to the same bytes.
    if (linecloud::SerializeLineCloud(cloud).size() != size) __builtin_trap();
  } catch (const linecloud::Error&) {
  }
  return 0;
}
