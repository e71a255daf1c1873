// Fuzzes the COLMAP text readers; the first byte picks the reader.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "linecloud/io/colmap_model.h"
#include "linecloud/util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const std::string_view text(reinterpret_cast<const char*>(data) + 1, size - 1);
  linecloud::Reconstruction rec;
  try {
    switch (data[0] % 3) {
      case 0:
        linecloud::ParseCamerasText(text, "cameras.txt", &rec);
        break;
      case 1:
        linecloud::ParseImagesText(text, "images.txt", &rec);
        break;
      case 2:
        linecloud::ParsePoints3DText(text, "points3D.txt", &rec);
        break;
    }
    rec.Check("fuzz");
  } catch (const linecloud::Error&) {
  }
  return 0;
}
