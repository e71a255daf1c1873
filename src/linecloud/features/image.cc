#include "linecloud/features/image.h"

#include <FreeImage.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
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

// The EXIF orientation tag (0x0112) of a bitmap's metadata; 1 when absent or
// not one of the eight values.
int ExifOrientation(FIBITMAP* bitmap) {
  FITAG* tag = nullptr;
  if (!FreeImage_GetMetadata(FIMD_EXIF_MAIN, bitmap, "Orientation", &tag) || !tag) return 1;
  if (FreeImage_GetTagType(tag) != FIDT_SHORT || FreeImage_GetTagCount(tag) != 1) return 1;
  const int value = *static_cast<const uint16_t*>(FreeImage_GetTagValue(tag));
  return value >= 1 && value <= 8 ? value : 1;
}

// A tag of `model` (FIMD_EXIF_*) as a number: the first value of a SHORT,
// LONG or (signed) RATIONAL; nullopt when absent, of another type or with a
// zero denominator.
std::optional<double> ExifNumber(FIBITMAP* bitmap, FREE_IMAGE_MDMODEL model, const char* key,
                                 unsigned index = 0) {
  FITAG* tag = nullptr;
  if (!FreeImage_GetMetadata(model, bitmap, key, &tag) || !tag) return std::nullopt;
  if (FreeImage_GetTagCount(tag) <= index) return std::nullopt;
  const void* v = FreeImage_GetTagValue(tag);
  switch (FreeImage_GetTagType(tag)) {
    case FIDT_SHORT:
      return static_cast<const uint16_t*>(v)[index];
    case FIDT_LONG:
      return static_cast<const uint32_t*>(v)[index];
    case FIDT_RATIONAL: {
      const uint32_t* r = static_cast<const uint32_t*>(v) + 2 * index;
      if (r[1] == 0) return std::nullopt;
      return double(r[0]) / r[1];
    }
    case FIDT_SRATIONAL: {
      const int32_t* r = static_cast<const int32_t*>(v) + 2 * index;
      if (r[1] == 0) return std::nullopt;
      return double(r[0]) / r[1];
    }
    default:
      return std::nullopt;
  }
}

std::string ExifText(FIBITMAP* bitmap, const char* key) {
  FITAG* tag = nullptr;
  if (!FreeImage_GetMetadata(FIMD_EXIF_MAIN, bitmap, key, &tag) || !tag) return "";
  if (FreeImage_GetTagType(tag) != FIDT_ASCII) return "";
  const char* text = static_cast<const char*>(FreeImage_GetTagValue(tag));
  std::string s(text, strnlen(text, FreeImage_GetTagLength(tag)));
  while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
  // Names go into reports and camera keys: printable ASCII only, bounded.
  for (char& c : s) {
    if (c < 0x20 || c > 0x7e) c = '?';
  }
  return s.substr(0, 64);
}

// Degrees from EXIF's (degrees, minutes, seconds) rationals and its N/S or E/W reference.
std::optional<double> ExifDegrees(FIBITMAP* bitmap, const char* key, const char* ref_key,
                                  char negative) {
  const auto d = ExifNumber(bitmap, FIMD_EXIF_GPS, key, 0);
  const auto m = ExifNumber(bitmap, FIMD_EXIF_GPS, key, 1);
  const auto s = ExifNumber(bitmap, FIMD_EXIF_GPS, key, 2);
  if (!d || !m || !s) return std::nullopt;
  double deg = *d + *m / 60 + *s / 3600;
  FITAG* tag = nullptr;
  if (FreeImage_GetMetadata(FIMD_EXIF_GPS, bitmap, ref_key, &tag) && tag &&
      FreeImage_GetTagType(tag) == FIDT_ASCII && FreeImage_GetTagLength(tag) >= 1 &&
      static_cast<const char*>(FreeImage_GetTagValue(tag))[0] == negative) {
    deg = -deg;
  }
  return deg;
}

ExifCamera ReadExifCamera(FIBITMAP* bitmap) {
  ExifCamera e;
  e.make = ExifText(bitmap, "Make");
  e.model = ExifText(bitmap, "Model");
  e.focal_length_35mm = ExifNumber(bitmap, FIMD_EXIF_EXIF, "FocalLengthIn35mmFilm").value_or(0);
  e.focal_length_mm = ExifNumber(bitmap, FIMD_EXIF_EXIF, "FocalLength").value_or(0);
  const double resolution = ExifNumber(bitmap, FIMD_EXIF_EXIF, "FocalPlaneXResolution").value_or(0);
  // FocalPlaneResolutionUnit: 2 inch (the default), 3 cm, 4 mm, 5 µm.
  const int unit = int(ExifNumber(bitmap, FIMD_EXIF_EXIF, "FocalPlaneResolutionUnit").value_or(2));
  const double mm_per_unit = unit == 3 ? 10 : unit == 4 ? 1 : unit == 5 ? 1e-3 : 25.4;
  if (resolution > 0) e.focal_plane_pixels_per_mm = resolution / mm_per_unit;
  const auto lat = ExifDegrees(bitmap, "GPSLatitude", "GPSLatitudeRef", 'S');
  const auto lon = ExifDegrees(bitmap, "GPSLongitude", "GPSLongitudeRef", 'W');
  if (lat && lon && std::abs(*lat) <= 90 && std::abs(*lon) <= 180) {
    double alt = ExifNumber(bitmap, FIMD_EXIF_GPS, "GPSAltitude").value_or(0);
    if (ExifNumber(bitmap, FIMD_EXIF_GPS, "GPSAltitudeRef").value_or(0) == 1) alt = -alt;
    e.gps = Eigen::Vector3d(*lat, *lon, alt);
  }
  return e;
}

// The pixels as displayed: EXIF orientation o maps displayed (x, y) to the
// stored pixel — 2: mirrored, 3: turned 180°, 4: flipped, 5: transposed,
// 6: turned 90° clockwise, 7: transverse, 8: turned 90° anticlockwise.
GreyImage Oriented(const GreyImage& stored, int o) {
  const bool turned = o >= 5;
  GreyImage out;
  out.width = turned ? stored.height : stored.width;
  out.height = turned ? stored.width : stored.height;
  out.pixels.resize(stored.pixels.size());
  const int w = stored.width - 1, h = stored.height - 1;
  for (int y = 0; y < out.height; ++y) {
    for (int x = 0; x < out.width; ++x) {
      int sx = x, sy = y;
      switch (o) {
        case 2:
          sx = w - x;
          break;
        case 3:
          sx = w - x, sy = h - y;
          break;
        case 4:
          sy = h - y;
          break;
        case 5:
          sx = y, sy = x;
          break;
        case 6:
          sx = y, sy = h - x;
          break;
        case 7:
          sx = w - y, sy = h - x;
          break;
        case 8:
          sx = w - y, sy = x;
          break;
        default:
          break;
      }
      out.pixels[static_cast<size_t>(y) * out.width + x] = stored.at(sx, sy);
    }
  }
  out.orientation = {o, true};
  return out;
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

// A decoded 8-bit grey or colour bitmap in grey, as COLMAP's Bitmap::Read:
// 32-bit images go through 24 bits first, then FreeImage's greyscale
// conversion.
GreyImage GreyFromBitmap(BitmapPtr bitmap, const std::string& source) {
  if (FreeImage_GetImageType(bitmap.get()) != FIT_BITMAP) {
    Fail("{}: unsupported pixel type (only 8-bit grey and colour images)", source);
  }
  const bool grey =
      FreeImage_GetBPP(bitmap.get()) == 8 && FreeImage_GetColorType(bitmap.get()) == FIC_MINISBLACK;
  if (grey) return FromBitmap(bitmap.get());
  if (FreeImage_GetBPP(bitmap.get()) == 32) {
    BitmapPtr rgb(FreeImage_ConvertTo24Bits(bitmap.get()), FreeImage_Unload);
    if (!rgb) Fail("{}: cannot convert the image to RGB", source);
    bitmap = std::move(rgb);
  }
  BitmapPtr converted(FreeImage_ConvertToGreyscale(bitmap.get()), FreeImage_Unload);
  if (!converted) Fail("{}: cannot convert the image to grey", source);
  return FromBitmap(converted.get());
}

// What a JPEG may cost to decode, checked before decoding (photos come from
// strangers):
// - scans: a progressive JPEG's 80 000 empty scans took 40 s to decode.
//   Entropy-coded data stuffs every 0xFF with a 0x00, so FF DA is a start of
//   scan wherever it occurs (an EXIF thumbnail's scans count too);
// - bytes: a 333-byte file declared 7000 x 7000 pixels and cost gigabytes.
//   A photo holds at least a bit per 32 pixels (real ones 20-60 times more);
//   fewer bytes than that is a truncated or crafted file.
// - scans x blocks, before the header is read: FreeImage reads a progressive
//   JPEG's header by running libjpeg over every scan; a 192 KB file of 491
//   empty-band scans declaring 35 000 x 1 400 pixels took 55 s there. The
//   size is taken from the largest start-of-frame marker (an EXIF
//   thumbnail's is smaller), the blocks of its first component counted.
constexpr size_t kMaxJpegScans = 500;
constexpr uint64_t kMaxPixelsPerJpegByte = 256;
constexpr uint64_t kMaxJpegBlockScans = 30'000'000;

void CheckJpegMarkersCost(std::span<const uint8_t> data, const std::string& source) {
  uint64_t scans = 0, blocks = 0;
  for (size_t i = 0; i + 1 < data.size(); ++i) {
    if (data[i] != 0xFF) continue;
    const uint8_t m = data[i + 1];
    if (m == 0xDA) ++scans;
    // SOF0-SOF15 but DHT (C4), JPG (C8), DAC (CC): length, precision, height, width.
    if (m >= 0xC0 && m <= 0xCF && m != 0xC4 && m != 0xC8 && m != 0xCC && i + 8 < data.size()) {
      const uint64_t height = (uint64_t{data[i + 5]} << 8) | data[i + 6];
      const uint64_t width = (uint64_t{data[i + 7]} << 8) | data[i + 8];
      blocks = std::max(blocks, ((width + 7) / 8) * ((height + 7) / 8));
    }
  }
  if (scans * blocks > kMaxJpegBlockScans) {
    Fail(
        "{}: {} JPEG scans over {} blocks would take {} block decodes (a crafted file; at most "
        "{} are allowed)",
        source, scans, blocks, scans * blocks, kMaxJpegBlockScans);
  }
}

void CheckJpegCost(std::span<const uint8_t> data, const ImageHeader& h, const std::string& source) {
  size_t scans = 0;
  for (size_t i = 0; i + 1 < data.size(); ++i) {
    if (data[i] == 0xFF && data[i + 1] == 0xDA && ++scans > kMaxJpegScans) {
      Fail("{}: more than {} JPEG scans (a crafted file; photos have at most a few dozen)", source,
           kMaxJpegScans);
    }
  }
  const uint64_t pixels = static_cast<uint64_t>(h.width) * h.height;
  if (data.size() * kMaxPixelsPerJpegByte < pixels) {
    Fail("{}: the image is truncated: {} bytes cannot hold the {}x{} pixels its header declares",
         source, data.size(), h.width, h.height);
  }
}

}  // namespace

double ExifCamera::FocalLengthPixels(double max_size) const {
  // As COLMAP's image reader sets its prior: the 35 mm equivalent / 35 times
  // the longer side.
  if (focal_length_35mm > 0) return focal_length_35mm / 35.0 * max_size;
  if (focal_length_mm > 0 && focal_plane_pixels_per_mm > 0) {
    return focal_length_mm * focal_plane_pixels_per_mm;
  }
  return 0;
}

ImageHeader ReadImageHeader(std::span<const uint8_t> data, const std::string& source,
                            const ImageLimits& limits) {
  EnsureFreeImage();
  const FREE_IMAGE_FORMAT format = DetectFormat(data, source);
  if (format == FIF_JPEG) CheckJpegMarkersCost(data, source);
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
  if (FreeImage_GetImageType(header.get()) != FIT_BITMAP) {
    // A 16-bit PNG: decoding it whole (8 bytes a pixel and more) only to refuse it.
    Fail(
        "{}: unsupported pixel type (only 8-bit grey and colour images; 16-bit PNG: save it "
        "with 8 bits a channel)",
        source);
  }
  ImageHeader h{FreeImage_GetFormatFromFIF(format), FreeImage_GetWidth(header.get()),
                FreeImage_GetHeight(header.get())};
  h.exif_orientation = ExifOrientation(header.get());
  h.exif = ReadExifCamera(header.get());
  if (h.width == 0 || h.height == 0) Fail("{}: the image header says it is empty", source);
  if (format == FIF_JPEG) CheckJpegCost(data, h, source);
  if (h.width * h.height > limits.max_pixels) {
    Fail("{}: the image header says {}x{} pixels, more than the limit of {}", source, h.width,
         h.height, limits.max_pixels);
  }
  CheckImageSize(h, limits.expected_width, limits.expected_height, source);
  return h;
}

void CheckImageSize(const ImageHeader& h, uint64_t width, uint64_t height,
                    const std::string& source) {
  const auto fits = [&](uint64_t w, uint64_t ht) {
    return (!width || w == width) && (!height || ht == height);
  };
  if (fits(h.width, h.height) || (h.Turned() && fits(h.height, h.width))) return;
  if (h.Turned()) {
    Fail(
        "{}: the image is {}x{} pixels as stored, {}x{} as displayed (EXIF orientation {}), "
        "but the camera is {}x{}",
        source, h.width, h.height, h.height, h.width, h.exif_orientation, width, height);
  }
  Fail("{}: the image is {}x{} pixels but the camera is {}x{}", source, h.width, h.height, width,
       height);
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
  // libjpeg fills what is missing of a truncated file with grey and warns:
  // "Premature end of JPEG file" when the data run out, "Corrupt JPEG data:
  // premature end of data segment" when an end-of-image marker was appended.
  for (std::string m : freeimage_messages) {
    const std::string original = m;
    std::transform(m.begin(), m.end(), m.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (m.find("premature end") != std::string::npos) {
      Fail("{}: the image is truncated ({})", source, original);
    }
  }
  GreyImage stored = GreyFromBitmap(std::move(bitmap), source);
  stored.orientation.exif = header.exif_orientation;
  // Turned to its orientation unless the camera is the stored size (then the
  // camera was calibrated on the stored pixels).
  const bool stored_size_expected =
      (limits.expected_width || limits.expected_height) &&
      (!limits.expected_width || limits.expected_width == header.width) &&
      (!limits.expected_height || limits.expected_height == header.height);
  if (header.exif_orientation == 1 || stored_size_expected) return stored;
  return Oriented(stored, header.exif_orientation);
}

GreyImage GreyImageFromPixels(std::span<const uint8_t> pixels, int width, int height, int channels,
                              const std::string& source) {
  if (width <= 0 || height <= 0 || !(channels == 1 || channels == 3 || channels == 4)) {
    Fail("{}: {}x{} pixels of {} channels is no image", source, width, height, channels);
  }
  const uint64_t n = static_cast<uint64_t>(width) * static_cast<uint64_t>(height);
  if (pixels.size() != n * static_cast<uint64_t>(channels)) {
    Fail("{}: {} bytes, {}x{} pixels of {} channels need {}", source, pixels.size(), width, height,
         channels, n * channels);
  }
  if (channels == 1) return GreyImage{width, height, {pixels.begin(), pixels.end()}, {}};
  EnsureFreeImage();
  BitmapPtr bitmap(FreeImage_Allocate(width, height, 8 * channels), FreeImage_Unload);
  if (!bitmap) Fail("{}: out of memory for a {}x{} image", source, width, height);
  for (int y = 0; y < height; ++y) {
    BYTE* line = FreeImage_GetScanLine(bitmap.get(), height - 1 - y);  // bottom-up
    const uint8_t* in = pixels.data() + static_cast<size_t>(y) * width * channels;
    for (int x = 0; x < width; ++x, in += channels, line += channels) {
      line[FI_RGBA_RED] = in[0];
      line[FI_RGBA_GREEN] = in[1];
      line[FI_RGBA_BLUE] = in[2];
      if (channels == 4) line[FI_RGBA_ALPHA] = in[3];
    }
  }
  return GreyFromBitmap(std::move(bitmap), source);
}

GreyImage ReadGreyImage(const std::string& path, const ImageLimits& limits) {
  if (!FileExists(path)) Fail("{}: no such file", path);
  if (IsDirectory(path)) Fail("{}: is a directory, not an image", path);
  const std::string data = ReadFileToString(path);
  return DecodeGreyImage(std::span(reinterpret_cast<const uint8_t*>(data.data()), data.size()),
                         path, limits);
}

std::pair<int, int> DownscaledSize(int width, int height, int max_size) {
  if (std::max(width, height) <= max_size) return {width, height};
  const double scale = static_cast<double>(max_size) / std::max(width, height);
  return {std::max(1, static_cast<int>(width * scale)),
          std::max(1, static_cast<int>(height * scale))};
}

GreyImage DownscaleToMaxSize(const GreyImage& image, int max_size) {
  if (std::max(image.width, image.height) <= max_size) return image;
  EnsureFreeImage();
  const auto [width, height] = DownscaledSize(image.width, image.height, max_size);
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
