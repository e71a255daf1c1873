#include "linecloud/localize/query_from_model.h"

#include "linecloud/lifting/lifting.h"
#include "linecloud/util/error.h"

namespace linecloud {

ModelQuery QueryFromModelImage(const Reconstruction& model, const std::string& model_name,
                               const std::string& image_name, const LiftingKey* key) {
  const Image* image = nullptr;
  for (const auto& [id, im] : model.images) {
    if (im.name == image_name) image = &im;
  }
  if (!image) Fail("{}: no image named '{}' in the model", model_name, image_name);
  ModelQuery out;
  out.cam_from_world = image->cam_from_world;
  out.query.cameras.push_back(model.cameras.at(image->camera_id));
  for (const Point2D& p : image->points2D) {
    if (p.point3D_id == kInvalidPoint3DId) continue;
    out.query.observations.push_back({0, p.xy, p.point3D_id, std::nullopt, std::nullopt});
  }
  if (key) {
    std::vector<uint64_t> point_ids;
    for (const QueryObservation& o : out.query.observations) point_ids.push_back(o.id);
    const std::vector<uint64_t> line_ids = LineIdsOfPoints(*key, point_ids);
    for (size_t i = 0; i < line_ids.size(); ++i) out.query.observations[i].line_id = line_ids[i];
  }
  if (out.query.observations.empty()) {
    Fail("{}: image '{}' sees no 3D point of the model", model_name, image_name);
  }
  return out;
}

}  // namespace linecloud
