// Fuzzes the COLMAP database reader (read-only, immutable SQLite): the bytes
// are written to a file and every table is read. Failures must be
// linecloud::Error; anything else is a finding.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>

#include "linecloud/io/colmap_database.h"
#include "linecloud/util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::string path = "/tmp/linecloud_db_fuzz_" + std::to_string(getpid()) + ".db";
  if (FILE* f = std::fopen(path.c_str(), "wb")) {
    std::fwrite(data, 1, size, f);
    std::fclose(f);
  } else {
    return 0;
  }
  try {
    const linecloud::ColmapDatabase db(path);
    db.ReadCameras();
    for (const linecloud::DatabaseImage& image : db.ReadImages()) {
      db.ReadKeypoints(image.image_id);
      db.ReadDescriptors(image.image_id);
    }
    db.ReadAllMatches();
    db.ReadTwoViewGeometries();
  } catch (const linecloud::Error&) {
  }
  return 0;
}
