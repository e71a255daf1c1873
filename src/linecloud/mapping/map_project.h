// `linecloud map`: photos in, a served map out. A project folder (private:
// the photos' features, the COLMAP database, the point model, the reports,
// the key's identity) is built in stages, each stamped with a fingerprint of
// its inputs, so that the same command after Ctrl-C or a killed process
// continues from the last finished stage and ends with the same map:
//
//   photos    checked before any long work (photo_set.h); project.json
//   features  SIFT into database.db (per photo: a killed run keeps whole ones)
//   matches   pairs, matched and verified (sfm.h)
//   mapper    COLMAP's mapper into sparse/; the largest model into model/
//   lift      the owner's key (the key store; the project's own identity)
//             and its release ledger: map.lcm
//   audit     what the density attack and the map's own crossings recover
//   publish   MAPS_DIR/ID.lcm, ID.json (geo_anchor when the photos carry
//             GPS), ID.audit.json: nothing else leaves the project
//
// `update`: new photos registered into the released model (COLMAP's
// image_registrator, point_triangulator, bundle_adjuster), lifted through
// the ledger so that every released point keeps its line.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "linecloud/mapping/sfm.h"

namespace linecloud {

struct MapOptions {
  std::vector<std::string> photos;  // files and folders
  std::string project_dir;
  std::vector<std::string> cameras;  // "MODEL W H PARAMS...", one per photo size
  std::string out;                   // MAPS_DIR/ID; empty: the project's map only
  bool update = false;
  SfmOptions sfm;
  std::string key_store;  // empty: the user's (KeyStore::DefaultDirectory)
  std::string key_file;   // empty: the project's key in the key store
  bool audit = true;
  // Optional survey poses (COLMAP images.txt, cam_from_world): the model's
  // cameras compared with them after a similarity alignment.
  std::string ground_truth;
  // A calibrated stereo rig's baseline: "A,B,METRES" — the photo named with
  // A replaced by B was taken at the same moment by the rig's other camera,
  // METRES apart. The model is scaled to metres (the median over such pairs).
  std::string stereo;

  void Check() const;
};

struct MapStage {
  std::string name;
  bool reused = false;  // finished by an earlier run
  double seconds = 0;
  nlohmann::ordered_json details;
};

struct MapReport {
  std::string project, project_id;
  bool update = false;
  std::vector<MapStage> stages;
  size_t photos = 0, registered = 0, points = 0, models = 0;
  std::vector<std::pair<std::string, std::string>> unregistered;  // name, why
  double mean_track_length = 0, mean_reprojection_error_px = 0;
  size_t lines = 0, lines_kept = 0, lines_new = 0, lines_withdrawn = 0;
  std::string map, map_json, map_audit;  // the served files (empty: not published)
  nlohmann::ordered_json ground_truth;   // the comparison with MapOptions::ground_truth
  nlohmann::ordered_json ToJson() const;
};

// Progress lines ("[map] ...") go to the log (util/log.h).
MapReport BuildMap(const MapOptions& options);

}  // namespace linecloud
