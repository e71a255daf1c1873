// OpenGV (libopengv-dev) as a peer in `linecloud bench solvers`: only built
// when CMake finds OpenGV. Conventions converted to query_from_world:
// absolute pose returns [R | c] with R = world_from_cam rotation and c the
// viewpoint's position; threept_arun returns frame 1 from frame 2.
#include "linecloud/eval/solver_bench.h"

#ifdef LINECLOUD_WITH_OPENGV
#include <opengv/absolute_pose/CentralAbsoluteAdapter.hpp>
#include <opengv/absolute_pose/NoncentralAbsoluteAdapter.hpp>
#include <opengv/absolute_pose/methods.hpp>
#include <opengv/point_cloud/PointCloudAdapter.hpp>
#include <opengv/point_cloud/methods.hpp>
#endif

namespace linecloud {

#ifdef LINECLOUD_WITH_OPENGV
namespace {

Sim3d FromViewpointPose(const opengv::transformation_t& t) {
  const Eigen::Matrix3d r = t.leftCols<3>().transpose();
  return Sim3d(1.0, Eigen::Quaterniond(r), -r * t.col(3));
}

void AddAll(const opengv::transformations_t& ts, std::vector<Sim3d>* out) {
  out->clear();
  for (const auto& t : ts) out->push_back(FromViewpointPose(t));
}

opengv::bearingVectors_t Bearings(const MinimalSample& s) {
  return opengv::bearingVectors_t(s.bearings.begin(), s.bearings.end());
}

// Generalized-camera adapter data: each bearing in its own camera.
struct Noncentral {
  opengv::bearingVectors_t bearings;
  std::vector<int> cameras;
  opengv::points_t points;
  opengv::translations_t offsets;
  opengv::rotations_t rotations;
};

Noncentral FromRig(const MinimalSample& s) {
  Noncentral n;
  n.bearings = Bearings(s);
  n.cameras = s.camera_index;
  n.points.assign(s.points.begin(), s.points.end());
  for (const Rigid3d& cam_from_rig : s.cam_from_rig) {
    n.offsets.push_back(cam_from_rig.Center());
    n.rotations.push_back(cam_from_rig.rotation.inverse().toRotationMatrix());
  }
  return n;
}

// Lines as the rays of a generalized camera (roles of map and query swapped):
// ray i starts at the line's anchor with direction v_i; the "world points"
// are the local points X̃. The result is world_from_local, inverted here.
Noncentral FromLines(const MinimalSample& s) {
  Noncentral n;
  for (size_t i = 0; i < s.lines.size(); ++i) {
    n.bearings.push_back(s.lines[i].v);
    n.cameras.push_back(static_cast<int>(i));
    n.offsets.push_back(s.lines[i].Anchor());
    n.rotations.push_back(Eigen::Matrix3d::Identity());
  }
  n.points.assign(s.points_local.begin(), s.points_local.end());
  return n;
}

}  // namespace

std::vector<PeerSolver> OpenGvPeers() {
  using opengv::absolute_pose::CentralAbsoluteAdapter;
  using opengv::absolute_pose::NoncentralAbsoluteAdapter;
  return {
      {"p3P", "opengv-p3p_kneip",
       [](const MinimalSample& s, std::vector<Sim3d>* out) {
         const opengv::bearingVectors_t b = Bearings(s);
         const opengv::points_t p(s.points.begin(), s.points.end());
         CentralAbsoluteAdapter adapter(b, p);
         AddAll(opengv::absolute_pose::p3p_kneip(adapter), out);
       }},
      {"p3P", "opengv-p3p_gao",
       [](const MinimalSample& s, std::vector<Sim3d>* out) {
         const opengv::bearingVectors_t b = Bearings(s);
         const opengv::points_t p(s.points.begin(), s.points.end());
         CentralAbsoluteAdapter adapter(b, p);
         AddAll(opengv::absolute_pose::p3p_gao(adapter), out);
       }},
      {"m-p3P", "opengv-gp3p",
       [](const MinimalSample& s, std::vector<Sim3d>* out) {
         const Noncentral n = FromRig(s);
         NoncentralAbsoluteAdapter adapter(n.bearings, n.cameras, n.points, n.offsets,
                                           n.rotations);
         AddAll(opengv::absolute_pose::gp3p(adapter), out);
       }},
      {"m-P3L+l+s", "opengv-gp3p (roles reversed)",
       [](const MinimalSample& s, std::vector<Sim3d>* out) {
         const Noncentral n = FromLines(s);
         NoncentralAbsoluteAdapter adapter(n.bearings, n.cameras, n.points, n.offsets,
                                           n.rotations);
         AddAll(opengv::absolute_pose::gp3p(adapter), out);
         for (Sim3d& p : *out) p = p.Inverse();
       }},
      {"m-P3P+l+s", "opengv-threept_arun",
       [](const MinimalSample& s, std::vector<Sim3d>* out) {
         const opengv::points_t local(s.points_local.begin(), s.points_local.end());
         const opengv::points_t world(s.points.begin(), s.points.end());
         opengv::point_cloud::PointCloudAdapter adapter(local, world);
         const opengv::transformation_t t = opengv::point_cloud::threept_arun(adapter);
         out->clear();
         out->emplace_back(1.0, Eigen::Quaterniond(Eigen::Matrix3d(t.leftCols<3>())),
                           t.col(3));
       }},
  };
}
#else
std::vector<PeerSolver> OpenGvPeers() { return {}; }
#endif

}  // namespace linecloud
