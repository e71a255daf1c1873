// Images as COLMAP's feature extractor sees them: decoded by FreeImage (the
// library COLMAP 3.8 reads images with), converted to 8-bit grey by
// FreeImage's own conversion, rows top to bottom.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace linecloud {

struct GreyImage {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> pixels;  // row-major, the top row first

  uint8_t at(int x, int y) const { return pixels[static_cast<size_t>(y) * width + x]; }
};

// Throws Error naming `path` when the file is missing, not an image FreeImage
// can read, corrupt, or empty.
GreyImage ReadGreyImage(const std::string& path);

// Bilinear downscaling as COLMAP does before extraction when the larger side
// exceeds `max_size` (FreeImage_Rescale); returns the image unchanged otherwise.
GreyImage DownscaleToMaxSize(const GreyImage& image, int max_size);

}  // namespace linecloud
