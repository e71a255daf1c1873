// Fuzzes the photo decoder (JPEG / PNG bytes as an HTTP body brings them): the
// header is checked first (size, pixel cap), then decoded. Any input must
// decode within the limits or throw linecloud::Error — never crash, hang or
// allocate beyond the pixel cap.
#include <cstddef>
#include <cstdint>
#include <span>

#include "linecloud/features/image.h"
#include "linecloud/util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  constexpr uint64_t kMaxPixels = 4'000'000;
  try {
    const linecloud::GreyImage image =
        linecloud::DecodeGreyImage(std::span(data, size), "fuzz.image", {.max_pixels = kMaxPixels});
    if (image.width <= 0 || image.height <= 0 ||
        static_cast<uint64_t>(image.width) * static_cast<uint64_t>(image.height) > kMaxPixels ||
        image.pixels.size() != static_cast<size_t>(image.width) * image.height) {
      __builtin_trap();
    }
  } catch (const linecloud::Error&) {
  }
  return 0;
}
