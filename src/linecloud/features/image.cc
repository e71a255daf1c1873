#include "linecloud/features/image.h"

#include <FreeImage.h>

#include <algorithm>
#include <memory>
#include <mutex>

#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

using BitmapPtr = std::unique_ptr<FIBITMAP, void (*)(FIBITMAP*)>;

// FreeImage reports decoding problems through one global callback.
thread_local std::string last_freeimage_message;
void FreeImageMessage(FREE_IMAGE_FORMAT, const char* message) {
  last_freeimage_message = message ? message : "";
}

void EnsureFreeImage() {
  static std::once_flag once;
  std::call_once(once, [] { FreeImage_SetOutputMessage(FreeImageMessage); });
}

GreyImage FromBitmap(FIBITMAP* grey) {
  GreyImage image;
  image.width = static_cast<int>(FreeImage_GetWidth(grey));
  image.height = static_cast<int>(FreeImage_GetHeight(grey));
  image.pixels.resize(static_cast<size_t>(image.width) * image.height);
  for (int y = 0; y < image.height; ++y) {
    // FreeImage stores scan lines bottom-up.
    const uint8_t* line = FreeImage_GetScanLine(grey, image.height - 1 - y);
    std::copy_n(line, image.width, image.pixels.data() + static_cast<size_t>(y) * image.width);
  }
  return image;
}

}  // namespace

GreyImage ReadGreyImage(const std::string& path) {
  EnsureFreeImage();
  if (!FileExists(path)) Fail("{}: no such file", path);
  if (IsDirectory(path)) Fail("{}: is a directory, not an image", path);
  FREE_IMAGE_FORMAT format = FreeImage_GetFileType(path.c_str(), 0);
  if (format == FIF_UNKNOWN) format = FreeImage_GetFIFFromFilename(path.c_str());
  if (format == FIF_UNKNOWN || !FreeImage_FIFSupportsReading(format)) {
    Fail("{}: not an image (FreeImage does not recognise its format)", path);
  }
  last_freeimage_message.clear();
  BitmapPtr bitmap(FreeImage_Load(format, path.c_str(), 0), FreeImage_Unload);
  if (!bitmap || FreeImage_GetWidth(bitmap.get()) == 0 || FreeImage_GetHeight(bitmap.get()) == 0) {
    Fail("{}: cannot decode the image{}", path,
         last_freeimage_message.empty() ? "" : " (" + last_freeimage_message + ")");
  }
  if (FreeImage_GetImageType(bitmap.get()) != FIT_BITMAP) {
    Fail("{}: unsupported pixel type (only 8-bit grey and colour images)", path);
  }
  const bool grey =
      FreeImage_GetBPP(bitmap.get()) == 8 && FreeImage_GetColorType(bitmap.get()) == FIC_MINISBLACK;
  if (grey) return FromBitmap(bitmap.get());
  // As COLMAP's Bitmap::Read: 32-bit images go through 24 bits first, then
  // FreeImage's greyscale conversion.
  if (FreeImage_GetBPP(bitmap.get()) == 32) {
    BitmapPtr rgb(FreeImage_ConvertTo24Bits(bitmap.get()), FreeImage_Unload);
    if (!rgb) Fail("{}: cannot convert the image to RGB", path);
    bitmap = std::move(rgb);
  }
  BitmapPtr converted(FreeImage_ConvertToGreyscale(bitmap.get()), FreeImage_Unload);
  if (!converted) Fail("{}: cannot convert the image to grey", path);
  return FromBitmap(converted.get());
}

GreyImage DownscaleToMaxSize(const GreyImage& image, int max_size) {
  if (std::max(image.width, image.height) <= max_size) return image;
  EnsureFreeImage();
  const double scale = static_cast<double>(max_size) / std::max(image.width, image.height);
  const int width = std::max(1, static_cast<int>(image.width * scale));
  const int height = std::max(1, static_cast<int>(image.height * scale));
  BitmapPtr source(FreeImage_Allocate(image.width, image.height, 8), FreeImage_Unload);
  if (!source) Fail("out of memory for a {}x{} image", image.width, image.height);
  for (int y = 0; y < image.height; ++y) {
    std::copy_n(image.pixels.data() + static_cast<size_t>(y) * image.width, image.width,
                FreeImage_GetScanLine(source.get(), image.height - 1 - y));
  }
  BitmapPtr scaled(FreeImage_Rescale(source.get(), width, height, FILTER_BILINEAR),
                   FreeImage_Unload);
  if (!scaled) Fail("cannot rescale a {}x{} image", image.width, image.height);
  return FromBitmap(scaled.get());
}

}  // namespace linecloud
