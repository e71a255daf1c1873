#include "linecloud/synthetic/scene_queries.h"

#include <algorithm>
#include <random>

#include "linecloud/util/error.h"

namespace linecloud {

void SceneQueryOptions::Check() const {
  if (!(outlier_ratio >= 0 && outlier_ratio < 1)) Fail("outlier ratio must be in [0, 1)");
  if (!(local_noise >= 0)) Fail("local point noise must be >= 0");
  if (rig_size < 1) Fail("rig size must be >= 1");
  if (!(local_scale > 0)) Fail("local scale must be > 0");
}

std::vector<SceneQuery> SceneQueriesForMethod(const SyntheticScene& scene, const MethodInfo& method,
                                              const SceneQueryOptions& options) {
  options.Check();
  std::mt19937_64 rng(options.seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<uint64_t> ids;
  for (const auto& [id, p] : scene.model.points3D) ids.push_back(id);
  std::sort(ids.begin(), ids.end());

  const size_t group = method.multi ? static_cast<size_t>(options.rig_size) : 1;
  const double s = method.similarity() ? options.local_scale : 1.0;
  std::vector<SceneQuery> out;
  for (size_t first = 0; first + group <= scene.queries.size(); first += group) {
    SceneQuery sq;
    const SyntheticQuery& q0 = scene.queries[first];
    sq.name = q0.name;
    const Rigid3d rig_from_world = q0.cam_from_world;
    sq.truth = Sim3d(s, rig_from_world.rotation, s * rig_from_world.translation);
    Query& query = sq.query;
    query.gravity_map = scene.gravity_in_world;
    query.gravity_query = q0.gravity_in_cam;
    for (size_t c = 0; c < group; ++c) {
      const SyntheticQuery& qc = scene.queries[first + c];
      query.cameras.push_back(qc.camera);
      if (method.multi) {
        const Rigid3d cam_from_rig = qc.cam_from_world * rig_from_world.Inverse();
        query.cam_from_rig.emplace_back(cam_from_rig.rotation, s * cam_from_rig.translation);
      }
      for (const SyntheticObservation& o : qc.observations) {
        QueryObservation obs;
        obs.camera = static_cast<int>(c);
        obs.xy = o.xy;
        obs.id = u(rng) < options.outlier_ratio ? ids[rng() % ids.size()] : o.point3D_id;
        query.observations.push_back(obs);
        if (method.local_points) {
          // Depth-like noise on the true point seen at this pixel.
          const Eigen::Vector3d x = scene.model.points3D.at(o.point3D_id).xyz;
          const double depth = (qc.cam_from_world * x).z();
          query.points_local.push_back(sq.truth * x + s * options.local_noise * depth *
                                                          Eigen::Vector3d(g(rng), g(rng), g(rng)));
        }
      }
    }
    out.push_back(std::move(sq));
  }
  return out;
}

}  // namespace linecloud
