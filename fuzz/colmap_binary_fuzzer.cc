// Fuzzes the COLMAP binary readers (cameras, images, points3D, rigs, frames);
// the first byte picks the reader.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "linecloud/io/colmap_model.h"
#include "linecloud/util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const std::string_view bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  linecloud::Reconstruction rec;
  try {
    switch (data[0] % 5) {
      case 0:
        linecloud::ParseCamerasBinary(bytes, "cameras.bin", &rec);
        break;
      case 1:
        linecloud::ParseImagesBinary(bytes, "images.bin", &rec);
        break;
      case 2:
        linecloud::ParsePoints3DBinary(bytes, "points3D.bin", &rec);
        break;
      case 3:
        linecloud::ParseRigsBinary(bytes, "rigs.bin", &rec);
        break;
      case 4:
        linecloud::ParseFramesBinary(bytes, "frames.bin", &rec);
        break;
    }
    rec.Check("fuzz");
  } catch (const linecloud::Error&) {
  }
  return 0;
}
