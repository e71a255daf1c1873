// A QUERY.json from an image registered in a COLMAP model: its 2D–3D
// correspondences, with the point ids (for the point model) and, given the
// model's lifting key, the line ids (for its line cloud). Lets a map owner
// check the whole path on their own data; the image helped build the map, so
// it is not a held-out test.
#pragma once

#include <string>

#include "linecloud/io/colmap_model.h"
#include "linecloud/lifting/key.h"
#include "linecloud/localize/localize.h"

namespace linecloud {

struct ModelQuery {
  Query query;
  Rigid3d cam_from_world;  // the model's pose of the image (the reference)
};

// Throws Error naming the model when the image is not in it or sees no point.
ModelQuery QueryFromModelImage(const Reconstruction& model, const std::string& model_name,
                               const std::string& image_name, const LiftingKey* key);

}  // namespace linecloud
