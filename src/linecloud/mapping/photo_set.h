// The photos of a map project, checked before any long work: every file
// readable, a whole JPEG or PNG whose header gives its size, names unique,
// at least two photos; and a camera for each (given, else from its EXIF, one
// per size and make/model, else — one size only — COLMAP's guess refined by
// its mapper). Every refusal names the file.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/camera.h"

namespace linecloud {

struct PhotoCamera {
  Camera camera;
  // "given" (--camera: fixed), "EXIF <make model>, <f> mm (35 mm equivalent)"
  // or "guessed (no EXIF focal length)": refined by the mapper.
  std::string source;
  bool given = false;
  bool prior_focal_length = false;  // COLMAP trusts the focal length (EXIF)
};

struct Photo {
  std::string path;  // as given
  std::string name;  // the file name: the photo's name in the project
  uint64_t bytes = 0;
  uint64_t width = 0, height = 0;      // as displayed (EXIF orientation applied)
  size_t camera = 0;                   // index into PhotoSet::cameras
  std::optional<Eigen::Vector3d> gps;  // EXIF: latitude, longitude, altitude
  // BLAKE2b of the bytes checked (InputFingerprint::AddFile's), set by
  // ReadPhotoSet; when set, the features are extracted only from these bytes
  // (a photo replaced mid-run is refused, not mixed into the project).
  std::string blake2b;
};

struct PhotoSet {
  std::vector<Photo> photos;  // sorted by name
  std::vector<PhotoCamera> cameras;
};

// `inputs`: photo files and folders (a folder: its *.jpg, *.jpeg, *.png,
// any case, not recursive). `cameras`: COLMAP camera strings ("MODEL W H
// PARAMS..."), each the camera of the photos of its size; "GLOB=MODEL W H
// PARAMS..." the camera of the photos whose file name matches GLOB. `min_photos`: 2
// for a new map, 1 for an update.
PhotoSet ReadPhotoSet(const std::vector<std::string>& inputs,
                      const std::vector<std::string>& cameras, size_t min_photos = 2);

}  // namespace linecloud
