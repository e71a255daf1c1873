// What POST /v1/maps/{id}/localize brings, read from the wire into the
// Localizer's terms: one photo or a device's frames (the m- methods of
// Speciale et al., CVPR 2019: a generalized camera from the frames' relative
// poses; +l with the device's own 3D points, +s when their scale is metric,
// +u with gravity), as multipart parts or as a JSON body of client features
// (docs/http_api.md):
//   multipart: image + camera, or image[k] + camera[k] (or one camera) +
//     cam_from_rig[k] for k = 0..n-1; points_local (JSON text), scale_known,
//     gravity, method and request options as text parts;
//   JSON: {camera, keypoints, descriptors} or {frames: [{camera, keypoints,
//     descriptors, cam_from_rig}, ...]}; points_local, scale_known, gravity,
//     method and request options as fields.
// Throws Error naming the part or field (400), FramesOverLimit (413) past
// `max_frames`. The request options are kept as sent: the server checks them
// against the map's (RequestOptions).
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "linecloud/features/sift.h"
#include "linecloud/geometry/camera.h"
#include "linecloud/geometry/rigid3.h"
#include "linecloud/localize/localize.h"
#include "linecloud/pipeline/localizer.h"
#include "linecloud/util/error.h"

namespace linecloud {

// More frames than the server takes in one request.
struct FramesOverLimit : Error {
  using Error::Error;
};

// A camera a client may send: its size and focal lengths within what a
// photo can have (Error naming `where`).
void CheckServedCamera(const Camera& camera, const std::string& where);

struct WireFrame {
  std::string name;   // the part or field it came in ("image", "image[1]", "frames[2]")
  std::string image;  // the encoded photo (multipart, never empty); empty for features
  SiftFeatures features;
  Camera camera;
  Rigid3d cam_from_rig;
};

struct LocalizeBody {
  std::vector<WireFrame> frames;
  std::string method;
  std::optional<Eigen::Vector3d> gravity;  // rig (or camera) frame
  std::vector<LocalPoint> points_local;
  std::optional<bool> scale_known;
  nlohmann::json options = nlohmann::json::object();  // request-option fields, as sent

  // The frames as the Localizer takes them (pointing into this body).
  std::vector<QueryPhoto> Photos() const;
  // The rig fields on a request (method, gravity, local points, their scale).
  void SetOn(LocalizeRequest* request) const;
};

LocalizeBody ReadMultipartBody(const std::map<std::string, std::string>& parts, int max_frames);
LocalizeBody ReadJsonBody(const nlohmann::json& body, int max_frames);

}  // namespace linecloud
