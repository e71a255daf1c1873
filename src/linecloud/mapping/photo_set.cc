#include "linecloud/mapping/photo_set.h"

#include <fnmatch.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <span>
#include <map>
#include <optional>
#include <set>
#include <tuple>

#include <fmt/format.h>

#include "linecloud/colmap/colmap_runner.h"
#include "linecloud/features/image.h"
#include "linecloud/pipeline/image_query.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace fs = std::filesystem;
namespace {

constexpr uint64_t kMaxPhotoBytes = 256ull << 20;

bool IsPhotoName(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return ext == ".jpg" || ext == ".jpeg" || ext == ".png";
}

std::vector<std::string> ExpandInputs(const std::vector<std::string>& inputs) {
  std::vector<std::string> files;
  for (const std::string& in : inputs) {
    std::error_code ec;
    if (fs::is_directory(in, ec)) {
      std::vector<std::string> found;
      for (const auto& e : fs::directory_iterator(in, ec)) {
        if (e.is_regular_file(ec) && IsPhotoName(e.path())) found.push_back(e.path().string());
      }
      if (found.empty()) Fail("{}: a folder without photos (*.jpg, *.jpeg, *.png)", in);
      std::sort(found.begin(), found.end());
      files.insert(files.end(), found.begin(), found.end());
    } else {
      files.push_back(in);
    }
  }
  return files;
}

// A whole file ends as its format says: a JPEG with its end-of-image marker
// near the end, a PNG with its IEND chunk. A photo cut off in a copy or an
// upload fails here, before hours of work, not in the middle of them.
void CheckWhole(std::span<const uint8_t> data, const std::string& format, const std::string& path) {
  if (format == "PNG") {
    static constexpr uint8_t kIend[] = {'I', 'E', 'N', 'D', 0xAE, 0x42, 0x60, 0x82};
    const auto tail = data.end() - std::min<size_t>(data.size(), 64);
    if (std::search(tail, data.end(), std::begin(kIend), std::end(kIend)) == data.end()) {
      Fail("{}: the PNG file is truncated (no IEND chunk at its end)", path);
    }
    return;
  }
  const size_t window = std::min<size_t>(data.size(), 1 << 16);
  for (size_t i = data.size(); i >= 2 && data.size() - i < window; --i) {
    if (data[i - 2] == 0xFF && data[i - 1] == 0xD9) return;
  }
  Fail("{}: the JPEG file is truncated (no end-of-image marker near its end)", path);
}

Photo ReadPhoto(const std::string& path, ExifCamera* exif) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) Fail("{}: no such photo (not a file)", path);
  const uint64_t bytes = fs::file_size(path, ec);
  if (ec) Fail("{}: cannot read the photo ({})", path, ec.message());
  if (bytes > kMaxPhotoBytes)
    Fail("{}: {} bytes, more than a photo's {} MB", path, bytes, kMaxPhotoBytes >> 20);
  const std::string text = ReadFileToString(path);
  const std::span<const uint8_t> data(reinterpret_cast<const uint8_t*>(text.data()), text.size());
  const ImageHeader header = ReadImageHeader(data, path);
  CheckWhole(data, header.format, path);
  Photo p;
  InputFingerprint fp;  // the bytes checked here are the bytes the project keeps
  fp.Add(text);
  p.blake2b = fp.Hex();
  p.path = path;
  p.name = fs::path(path).filename().string();
  if (std::any_of(p.name.begin(), p.name.end(), [](unsigned char c) { return std::isspace(c); })) {
    Fail("{}: a file name with a space; COLMAP's match lists cannot name it: rename the photo",
         path);
  }
  p.bytes = bytes;
  p.width = header.Turned() ? header.height : header.width;
  p.height = header.Turned() ? header.width : header.height;
  p.gps = header.exif.gps;
  *exif = header.exif;
  return p;
}

// COLMAP's camera for a photo without a given one: SIMPLE_RADIAL, the
// principal point at the centre, no distortion, the focal length from the
// EXIF or 1.2 × the longer side.
PhotoCamera DefaultCamera(uint64_t width, uint64_t height, const ExifCamera& exif) {
  PhotoCamera c;
  const double max_size = double(std::max(width, height));
  const double exif_focal = exif.FocalLengthPixels(max_size);
  c.camera.model_id = CameraModelId::kSimpleRadial;
  c.camera.width = width;
  c.camera.height = height;
  c.camera.params = {exif_focal > 0 ? exif_focal : 1.2 * max_size, width / 2.0, height / 2.0, 0.0};
  c.prior_focal_length = exif_focal > 0;
  const std::string device =
      fmt::format("{}{}{}", exif.make, exif.make.empty() ? "" : " ", exif.model);
  c.source = exif_focal > 0
                 ? fmt::format("EXIF{}{}, focal length {:.0f} px (refined by the mapper)",
                               device.empty() ? "" : " ", device, exif_focal)
                 : "guessed: no EXIF focal length (1.2 x the longer side, refined by the mapper)";
  return c;
}

}  // namespace

namespace {

// The cameras given: by photo size, and by file-name glob.
struct GivenCameras {
  std::map<std::pair<uint64_t, uint64_t>, size_t> by_size;
  std::vector<std::pair<std::string, size_t>> by_pattern;
};

GivenCameras ParseGivenCameras(const std::vector<std::string>& cameras, PhotoSet* set) {
  GivenCameras given;
  for (size_t k = 0; k < cameras.size(); ++k) {
    const std::string what = cameras.size() == 1 ? "--camera" : fmt::format("--camera #{}", k + 1);
    // "GLOB=MODEL W H PARAMS...": the camera of the photos whose file name
    // matches GLOB (two cameras of one size: a stereo rig's).
    std::string text = cameras[k], pattern;
    const size_t eq = text.find('=');
    if (eq != std::string::npos && text.substr(0, eq).find(' ') == std::string::npos) {
      pattern = text.substr(0, eq);
      text = text.substr(eq + 1);
    }
    PhotoCamera c{ParseCameraString(text, what), "given (" + what + ")", true, true};
    const auto size = std::make_pair(c.camera.width, c.camera.height);
    if (!pattern.empty()) {
      given.by_pattern.emplace_back(pattern, set->cameras.size());
    } else if (given.by_size.count(size)) {
      Fail(
          "{}: a second camera for {}x{} photos; give one camera per photo size, or name the "
          "photos of each (\"*_c0.png=MODEL W H PARAMS...\")",
          what, size.first, size.second);
    } else {
      given.by_size[size] = set->cameras.size();
    }
    set->cameras.push_back(std::move(c));
  }
  return given;
}

void ReadPhotos(const std::vector<std::string>& files, PhotoSet* set,
                std::vector<ExifCamera>* exif) {
  std::map<std::string, std::string> by_name;
  exif->resize(files.size());
  for (size_t k = 0; k < files.size(); ++k) {
    Photo p = ReadPhoto(files[k], &(*exif)[k]);
    const auto [it, fresh] = by_name.emplace(p.name, p.path);
    if (!fresh) {
      Fail(
          "{}: a second photo named {} (the first: {}); photos of a project need distinct file "
          "names",
          p.path, p.name, it->second);
    }
    set->photos.push_back(std::move(p));
  }
}

// A given camera of the photo's name or size, when there is one.
std::optional<size_t> GivenCamera(const Photo& p, const GivenCameras& given, const PhotoSet& set) {
  const auto named =
      std::find_if(given.by_pattern.begin(), given.by_pattern.end(),
                   [&](const auto& b) { return fnmatch(b.first.c_str(), p.name.c_str(), 0) == 0; });
  if (named != given.by_pattern.end()) {
    const Camera& c = set.cameras[named->second].camera;
    if (c.width != p.width || c.height != p.height) {
      Fail("{}: {}x{} pixels, but its camera ({}) is {}x{}", p.path, p.width, p.height,
           named->first, c.width, c.height);
    }
    return named->second;
  }
  if (const auto it = given.by_size.find({p.width, p.height}); it != given.by_size.end()) {
    return it->second;
  }
  return std::nullopt;
}

// Photos no given camera covers: one camera per size, make, model and focal
// length from their EXIF; without an EXIF focal length only when all photos
// have one size (a guess shared by photos of different sizes would be a
// wrong camera for some).
void AssignCameras(const GivenCameras& given, const std::vector<ExifCamera>& exif, PhotoSet* set) {
  std::set<std::pair<uint64_t, uint64_t>> sizes;
  for (const Photo& p : set->photos) sizes.insert({p.width, p.height});
  std::map<std::tuple<uint64_t, uint64_t, std::string, std::string, double>, size_t> derived;
  for (size_t k = 0; k < set->photos.size(); ++k) {
    Photo& p = set->photos[k];
    if (const auto c = GivenCamera(p, given, *set)) {
      p.camera = *c;
      continue;
    }
    const double focal = exif[k].FocalLengthPixels(double(std::max(p.width, p.height)));
    if (focal <= 0 && sizes.size() > 1) {
      Fail(
          "{}: {}x{} pixels and no EXIF focal length, among photos of {} sizes; give a camera "
          "for each size (--camera \"MODEL W H PARAMS...\", repeated)",
          p.path, p.width, p.height, sizes.size());
    }
    const auto key = std::make_tuple(p.width, p.height, exif[k].make, exif[k].model, focal);
    auto [it, fresh] = derived.emplace(key, set->cameras.size());
    if (fresh) set->cameras.push_back(DefaultCamera(p.width, p.height, exif[k]));
    p.camera = it->second;
  }
}

}  // namespace

PhotoSet ReadPhotoSet(const std::vector<std::string>& inputs,
                      const std::vector<std::string>& cameras, size_t min_photos) {
  const std::vector<std::string> files = ExpandInputs(inputs);
  if (files.empty()) Fail("no photos given: name the photos (or their folder) to map");
  if (files.size() < min_photos) {
    Fail(
        "{}: one photo; a map needs at least two photos of the place, taken from different "
        "positions",
        files.front());
  }
  PhotoSet set;
  const GivenCameras given = ParseGivenCameras(cameras, &set);
  std::vector<ExifCamera> exif;
  ReadPhotos(files, &set, &exif);
  AssignCameras(given, exif, &set);
  // A camera no photo takes is a mistake (width and height swapped, the
  // size of another sensor mode, a glob that matches nothing).
  for (size_t c = 0; c < cameras.size(); ++c) {
    if (std::none_of(set.photos.begin(), set.photos.end(),
                     [&](const Photo& p) { return p.camera == c; })) {
      const Camera& cam = set.cameras[c].camera;
      Fail("{}: no photo takes this camera ({}x{}; the photos are {}x{}{})",
           cameras.size() == 1 ? "--camera" : fmt::format("--camera #{}", c + 1), cam.width,
           cam.height, set.photos.front().width, set.photos.front().height,
           cameras[c].find('=') != std::string::npos ? ", or its file-name glob matches none" : "");
    }
  }
  std::sort(set.photos.begin(), set.photos.end(),
            [](const Photo& a, const Photo& b) { return a.name < b.name; });
  return set;
}

}  // namespace linecloud
