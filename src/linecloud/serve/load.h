// A load test of `linecloud serve` (a client of ours, bounded in count and
// time, 127.0.0.1 only): a server started in this process on a free port over
// a maps folder, driven at each concurrency by that many keep-alive clients
// with one request body — a photo (multipart) or its client features (JSON) —
// reporting throughput, p50 / p99 latency, statuses, and the server's resident
// memory over the run (a leak shows as growth); optionally the same client
// alone and under attack (LoadOptions::attack_seconds).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "linecloud/features/sift.h"
#include "linecloud/localize/query_json.h"
#include "linecloud/serve/load_report.h"
#include "linecloud/serve/server.h"

namespace linecloud {

struct LoadOptions {
  ServeOptions serve;  // maps_dir, threads, queue; listen is replaced by 127.0.0.1:0
  std::string map_id;
  std::string photo;   // JPEG / PNG file
  std::string camera;  // "MODEL W H PARAMS..."
  std::vector<int> concurrency = {1, 2, 4, 8, 32};
  int requests = 100;        // per concurrency level and body kind
  double max_seconds = 120;  // per level: stops sending after this
  bool photos = true;        // also the multipart photo (not only client features)
  int leak_requests = 0;     // > 0: that many more feature requests, RSS before / after
  int max_features = 8192;   // the client's feature budget (SIFT's cap)
  // > 0: one client's feature requests alone for this long, then as long
  // again while `attackers` threads send hostile requests (raw sockets:
  // nested JSON, chunked and oversized bodies, 500 headers, ranges, a NUL
  // in the path, a JPEG bomb, garbage bytes, wrong methods) and `dribblers`
  // sockets dribble header lines. Reports the client's p50 / p99 alone and
  // under attack, the attack's statuses by kind, resident memory.
  double attack_seconds = 0;
  int attackers = 4;
  int dribblers = 50;
  // A device's frames (RIG.json's cam_from_rig, points_local, gravity; one
  // photo per frame, all with `camera`): also levels of rig requests, as
  // client features and as photos, at every concurrency.
  std::string rig;
  std::vector<std::string> rig_photos;

  void Check() const;
};

LoadReport RunLoad(const LoadOptions& options);

// The JSON body of a client-features request (docs/http_api.md) for a photo:
// its SIFT by `extractor`, keypoints in COLMAP's pixel convention,
// descriptors base64. `camera` is "MODEL W H PARAMS...".
// `max_features` caps the detections as COLMAP does (whole levels from the
// coarsest; a device's budget).
std::string ClientFeaturesJson(const std::string& photo, const std::string& camera,
                               SiftExtractor extractor = SiftExtractor::kColmap,
                               int max_features = 8192);
// A device's frames: {"frames": [{camera, keypoints, descriptors,
// cam_from_rig}, ...]} with the rig's points_local, scale_known and gravity
// (RIG.json, localize/query_json.h). `cameras`: one for all photos, or one each.
std::string ClientRigJson(const std::vector<std::string>& photos,
                          const std::vector<std::string>& cameras, const RigFile& rig,
                          SiftExtractor extractor = SiftExtractor::kColmap,
                          int max_features = 8192);

}  // namespace linecloud
