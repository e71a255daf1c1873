#include "linecloud/features/image.h"

#include <FreeImage.h>

#include <algorithm>
#include <limits>
#include <memory>
#include <mutex>

#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

using BitmapPtr = std::unique_ptr<FIBITMAP, void (*)(FIBITMAP*)>;

// FreeImage reports decoding problems through one global callback, set once;
// each thread collects the messages of its own decoding.
thread_local std::vector<std::string> freeimage_messages;
void FreeImageMessage(FREE_IMAGE_FORMAT, const char* message) {
  if (freeimage_messages.size() < 16) freeimage_messages.emplace_back(message ? message : "");
}

void EnsureFreeImage() {
  static std::once_flag once;
  std::call_once(once, [] { FreeImage_SetOutputMessage(FreeImageMessage); });
}

std::string Messages() {
  std::string out;
  for (const std::string& m : freeimage_messages) out += (out.empty() ? "" : "; ") + m;
  return out;
}

// A read-only FreeImage memory stream over `data`.
struct MemoryStream {
  explicit MemoryStream(std::span<const uint8_t> data)
      : stream(FreeImage_OpenMemory(const_cast<BYTE*>(data.data()),
                                    static_cast<DWORD>(data.size()))) {}
  ~MemoryStream() {
    if (stream) FreeImage_CloseMemory(stream);
  }
  FIMEMORY* stream;
};

FREE_IMAGE_FORMAT DetectFormat(std::span<const uint8_t> data, const std::string& source) {
  if (data.empty()) Fail("{}: empty file, not an image", source);
  if (data.size() > std::numeric_limits<DWORD>::max()) Fail("{}: too large for an image", source);
  MemoryStream memory(data);
  const FREE_IMAGE_FORMAT format = FreeImage_GetFileTypeFromMemory(memory.stream, 0);
  if (format == FIF_UNKNOWN || !FreeImage_FIFSupportsReading(format)) {
    Fail("{}: not an image (FreeImage does not recognise its format)", source);
  }
  // Photos come from strangers: only the two formats cameras write, whose
  // decoders (libjpeg, libpng) are hardened; FreeImage's other plugins are not.
  if (format != FIF_JPEG && format != FIF_PNG) {
    Fail("{}: {} images are not read; convert it to JPEG or PNG", source,
         FreeImage_GetFormatFromFIF(format));
  }
  return format;
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

ImageHeader ReadImageHeader(std::span<const uint8_t> data, const std::string& source,
                            const ImageLimits& limits) {
  EnsureFreeImage();
  const FREE_IMAGE_FORMAT format = DetectFormat(data, source);
  MemoryStream memory(data);
  freeimage_messages.clear();
  BitmapPtr header(FreeImage_LoadFromMemory(format, memory.stream, FIF_LOAD_NOPIXELS),
                   FreeImage_Unload);
  if (!header) Fail("{}: cannot read the image header ({})", source, Messages());
  if (FreeImage_HasPixels(header.get())) {
    // The plugin decoded everything: nothing was checked before it did.
    Fail("{}: {} images cannot be checked before decoding; convert it to PNG or JPEG", source,
         FreeImage_GetFormatFromFIF(format));
  }
  ImageHeader h{FreeImage_GetFormatFromFIF(format), FreeImage_GetWidth(header.get()),
                FreeImage_GetHeight(header.get())};
  if (h.width == 0 || h.height == 0) Fail("{}: the image header says it is empty", source);
  if (h.width * h.height > limits.max_pixels) {
    Fail("{}: the image header says {}x{} pixels, more than the limit of {}", source, h.width,
         h.height, limits.max_pixels);
  }
  if ((limits.expected_width && h.width != limits.expected_width) ||
      (limits.expected_height && h.height != limits.expected_height)) {
    Fail("{}: the image is {}x{} pixels but the camera is {}x{}", source, h.width, h.height,
         limits.expected_width, limits.expected_height);
  }
  return h;
}

GreyImage DecodeGreyImage(std::span<const uint8_t> data, const std::string& source,
                          const ImageLimits& limits) {
  const ImageHeader header = ReadImageHeader(data, source, limits);
  const FREE_IMAGE_FORMAT format = FreeImage_GetFIFFromFormat(header.format.c_str());
  MemoryStream memory(data);
  freeimage_messages.clear();
  BitmapPtr bitmap(FreeImage_LoadFromMemory(format, memory.stream, 0), FreeImage_Unload);
  if (!bitmap || FreeImage_GetWidth(bitmap.get()) == 0 || FreeImage_GetHeight(bitmap.get()) == 0) {
    Fail("{}: cannot decode the image{}", source,
         freeimage_messages.empty() ? "" : " (" + Messages() + ")");
  }
  if (FreeImage_GetWidth(bitmap.get()) != header.width ||
      FreeImage_GetHeight(bitmap.get()) != header.height) {
    Fail("{}: decoded {}x{} pixels, the header said {}x{}", source,
         FreeImage_GetWidth(bitmap.get()), FreeImage_GetHeight(bitmap.get()), header.width,
         header.height);
  }
  // libjpeg fills what is missing of a truncated file with grey and warns.
  for (const std::string& m : freeimage_messages) {
    if (m.find("Premature end") != std::string::npos) {
      Fail("{}: the image is truncated ({})", source, m);
    }
  }
  if (FreeImage_GetImageType(bitmap.get()) != FIT_BITMAP) {
    Fail("{}: unsupported pixel type (only 8-bit grey and colour images)", source);
  }
  const bool grey =
      FreeImage_GetBPP(bitmap.get()) == 8 && FreeImage_GetColorType(bitmap.get()) == FIC_MINISBLACK;
  if (grey) return FromBitmap(bitmap.get());
  // As COLMAP's Bitmap::Read: 32-bit images go through 24 bits first, then
  // FreeImage's greyscale conversion.
  if (FreeImage_GetBPP(bitmap.get()) == 32) {
    BitmapPtr rgb(FreeImage_ConvertTo24Bits(bitmap.get()), FreeImage_Unload);
    if (!rgb) Fail("{}: cannot convert the image to RGB", source);
    bitmap = std::move(rgb);
  }
  BitmapPtr converted(FreeImage_ConvertToGreyscale(bitmap.get()), FreeImage_Unload);
  if (!converted) Fail("{}: cannot convert the image to grey", source);
  return FromBitmap(converted.get());
}

GreyImage ReadGreyImage(const std::string& path, const ImageLimits& limits) {
  if (!FileExists(path)) Fail("{}: no such file", path);
  if (IsDirectory(path)) Fail("{}: is a directory, not an image", path);
  const std::string data = ReadFileToString(path);
  return DecodeGreyImage(std::span(reinterpret_cast<const uint8_t*>(data.data()), data.size()),
                         path, limits);
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
