// Images as COLMAP's feature extractor sees them: decoded by FreeImage (the
// library COLMAP 3.8 reads images with), converted to 8-bit grey by
// FreeImage's own conversion, rows top to bottom.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace linecloud {

// A photo's EXIF orientation (1-8; 1: as stored) and whether the pixels were
// turned to it (DecodeGreyImage).
struct ImageOrientation {
  int exif = 1;
  bool applied = false;
};

struct GreyImage {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> pixels;  // row-major, the top row first
  ImageOrientation orientation;

  uint8_t at(int x, int y) const { return pixels[static_cast<size_t>(y) * width + x]; }
};

// What an encoded image may be, checked on its header before any pixel is
// decoded (a 138-byte PNG can announce 60000 x 60000 pixels).
struct ImageLimits {
  uint64_t max_pixels = 50'000'000;
  uint64_t expected_width = 0;  // 0: any; else the header must say exactly this
  uint64_t expected_height = 0;
};

// What a photo's EXIF says of its camera and place (absent tags: empty / 0 /
// nullopt). Read from the header, as COLMAP's image reader reads it.
struct ExifCamera {
  std::string make, model;
  double focal_length_35mm = 0;  // FocalLengthIn35mmFilm, mm
  double focal_length_mm = 0;    // FocalLength, mm
  // FocalPlaneXResolution in pixels per mm (its unit applied); 0 when absent.
  double focal_plane_pixels_per_mm = 0;
  std::optional<Eigen::Vector3d> gps;  // latitude, longitude (degrees), altitude (m, 0 if absent)

  // The focal length in pixels of a photo whose longer side has `max_size`
  // pixels, from the 35 mm equivalent or the focal plane's resolution; 0 when
  // the EXIF cannot tell.
  double FocalLengthPixels(double max_size) const;
};

struct ImageHeader {
  std::string format;  // FreeImage's name, e.g. "JPEG", "PNG"
  uint64_t width = 0;  // as stored
  uint64_t height = 0;
  int exif_orientation = 1;  // 5-8: displayed turned by 90° (width and height swap)
  ExifCamera exif;
  bool Turned() const { return exif_orientation >= 5 && exif_orientation <= 8; }
};

// The format, size and EXIF orientation from the header alone (FreeImage's
// FIF_LOAD_NOPIXELS); throws Error naming `source` for data that is no image,
// a format whose size cannot be read without decoding it, or a size the limits
// refuse. An expected size may be the stored one or, for a photo whose EXIF
// orientation turns it, the displayed one.
ImageHeader ReadImageHeader(std::span<const uint8_t> data, const std::string& source,
                            const ImageLimits& limits = {});

// ReadImageHeader's size check on its own: a camera of `width` x `height` (0:
// any) is the image's stored size or, when its EXIF orientation turns it, its
// displayed size; throws Error naming `source` otherwise.
void CheckImageSize(const ImageHeader& header, uint64_t width, uint64_t height,
                    const std::string& source);

// Decodes an encoded JPEG or PNG image (bytes, e.g. an HTTP body; other
// formats are refused: FreeImage's other decoders are not hardened) after
// ReadImageHeader's checks. The EXIF orientation is applied (the pixels as
// the photo is displayed) unless the limits expect the stored size: a camera
// calibrated on the stored pixels (COLMAP's, which reads them as stored)
// keeps them. Throws Error naming `source` when it is not an
// image FreeImage can read, corrupt, truncated (a JPEG that ends before its
// last scan), empty, or refused by the limits.
GreyImage DecodeGreyImage(std::span<const uint8_t> data, const std::string& source,
                          const ImageLimits& limits = {});

// DecodeGreyImage of a file's bytes; throws Error naming `path` when the file
// is missing or unreadable, too.
GreyImage ReadGreyImage(const std::string& path, const ImageLimits& limits = {});

// Grey pixels from raw 8-bit pixels of 1 (grey), 3 (RGB) or 4 (RGBA)
// channels, row-major, top row first — converted exactly as DecodeGreyImage
// converts a decoded colour photo (FreeImage's conversion, as COLMAP's), so
// that the same frame gives the same features by every route.
GreyImage GreyImageFromPixels(std::span<const uint8_t> pixels, int width, int height, int channels,
                              const std::string& source);

// Bilinear downscaling as COLMAP does before extraction when the larger side
// exceeds `max_size` (FreeImage_Rescale); returns the image unchanged otherwise.
GreyImage DownscaleToMaxSize(const GreyImage& image, int max_size);
// The width and height DownscaleToMaxSize gives an image of this size.
std::pair<int, int> DownscaledSize(int width, int height, int max_size);

}  // namespace linecloud
