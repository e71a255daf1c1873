// OpenGV (libopengv-dev) as a peer in `linecloud bench solvers`: only built
// when CMake finds OpenGV. Conventions converted to query_from_world:
// absolute pose returns [R | c] with R = world_from_cam rotation and c the
// viewpoint's position; threept_arun returns frame 1 from frame 2.
#include "linecloud/benchmarks/solver_bench.h"

#ifdef LINECLOUD_WITH_OPENGV
#include <opengv/absolute_pose/CentralAbsoluteAdapter.hpp>
#include <opengv/absolute_pose/NoncentralAbsoluteAdapter.hpp>
#include <opengv/absolute_pose/methods.hpp>
#include <opengv/point_cloud/PointCloudAdapter.hpp>
#include <opengv/point_cloud/methods.hpp>
#include <opengv/relative_pose/NoncentralRelativeAdapter.hpp>
#include <opengv/relative_pose/methods.hpp>
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

// The query rays and the map lines as the two viewpoints of OpenGV's
// generalized relative pose adapter: viewpoint 1 is the query rig (one camera
// per bearing; p6L: all at the origin), viewpoint 2 the world with one
// "camera" per line at its anchor looking along v. Both sixpt and seventeenpt
// return x1 = R12 x2 + t12, i.e. rig_from_world.
struct RayLineAdapterData {
  opengv::bearingVectors_t b1, b2;
  std::vector<int> c1, c2;
  opengv::translations_t offsets;
  opengv::rotations_t rotations;
  std::vector<Eigen::Vector3d> origins, directions;  // query rays, rig frame
};

RayLineAdapterData RaysAndLines(const MinimalSample& s, bool rig) {
  RayLineAdapterData d;
  for (size_t i = 0; i < s.bearings.size(); ++i) {
    const Rigid3d cam_from_rig = rig ? s.cam_from_rig[s.camera_index[i]] : Rigid3d();
    d.origins.push_back(cam_from_rig.Center());
    d.directions.push_back(cam_from_rig.rotation.inverse() * s.bearings[i].normalized());
    d.b1.push_back(s.bearings[i].normalized());
    d.c1.push_back(static_cast<int>(d.offsets.size()));
    d.offsets.push_back(d.origins.back());
    d.rotations.push_back(cam_from_rig.rotation.inverse().toRotationMatrix());
  }
  for (const PluckerLine& line : s.lines) {
    d.b2.push_back(line.v);
    d.c2.push_back(static_cast<int>(d.offsets.size()));
    d.offsets.push_back(line.Anchor());
    d.rotations.push_back(Eigen::Matrix3d::Identity());
  }
  return d;
}

// sixpt (Stewénius' 6-point generalized relative pose) gives rotations only;
// t is completed by linear least squares over the six ray-line equations
// (R v_i × d_i)ᵀ t = −(d_iᵀ R w_i + m_iᵀ R v_i).
void SixPoint(const MinimalSample& s, bool rig, std::vector<Sim3d>* out) {
  const RayLineAdapterData d = RaysAndLines(s, rig);
  opengv::relative_pose::NoncentralRelativeAdapter adapter(d.b1, d.b2, d.c1, d.c2, d.offsets,
                                                           d.rotations);
  const opengv::rotations_t solutions = opengv::relative_pose::sixpt(adapter);
  out->clear();
  for (const opengv::rotation_t& r : solutions) {
    Eigen::Matrix<double, 6, 3> a;
    Eigen::Matrix<double, 6, 1> rhs;
    for (int i = 0; i < 6; ++i) {
      const Eigen::Vector3d rv = r * s.lines[i].v;
      const Eigen::Vector3d m = d.origins[i].cross(d.directions[i]);
      a.row(i) = rv.cross(d.directions[i]).transpose();
      rhs[i] = -(d.directions[i].dot(r * s.lines[i].w) + m.dot(rv));
    }
    const Eigen::Vector3d t = a.colPivHouseholderQr().solve(rhs);
    out->emplace_back(1.0, Eigen::Quaterniond(r), t);
  }
}

// seventeenpt (Li, Hartley, Kim's linear generalized relative pose) on 17
// correspondences.
void SeventeenPoint(const MinimalSample& s, bool rig, std::vector<Sim3d>* out) {
  const RayLineAdapterData d = RaysAndLines(s, rig);
  opengv::relative_pose::NoncentralRelativeAdapter adapter(d.b1, d.b2, d.c1, d.c2, d.offsets,
                                                           d.rotations);
  const opengv::transformation_t t = opengv::relative_pose::seventeenpt(adapter);
  out->clear();
  out->emplace_back(1.0, Eigen::Quaterniond(Eigen::Matrix3d(t.leftCols<3>())), t.col(3));
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
         NoncentralAbsoluteAdapter adapter(n.bearings, n.cameras, n.points, n.offsets, n.rotations);
         AddAll(opengv::absolute_pose::gp3p(adapter), out);
       }},
      {"m-P3L+l+s", "opengv-gp3p (roles reversed)",
       [](const MinimalSample& s, std::vector<Sim3d>* out) {
         const Noncentral n = FromLines(s);
         NoncentralAbsoluteAdapter adapter(n.bearings, n.cameras, n.points, n.offsets, n.rotations);
         AddAll(opengv::absolute_pose::gp3p(adapter), out);
         for (Sim3d& p : *out) p = p.Inverse();
       }},
      {"p6L", "opengv-sixpt (+ linear t)",
       [](const MinimalSample& s, std::vector<Sim3d>* out) { SixPoint(s, false, out); }},
      {"m-p6L", "opengv-sixpt (+ linear t)",
       [](const MinimalSample& s, std::vector<Sim3d>* out) { SixPoint(s, true, out); }},
      {"p6L", "opengv-seventeenpt (17 corr.)",
       [](const MinimalSample& s, std::vector<Sim3d>* out) { SeventeenPoint(s, false, out); }, 17},
      {"m-p6L", "opengv-seventeenpt (17 corr.)",
       [](const MinimalSample& s, std::vector<Sim3d>* out) { SeventeenPoint(s, true, out); }, 17},
      {"m-P3P+l+s", "opengv-threept_arun",
       [](const MinimalSample& s, std::vector<Sim3d>* out) {
         const opengv::points_t local(s.points_local.begin(), s.points_local.end());
         const opengv::points_t world(s.points.begin(), s.points.end());
         opengv::point_cloud::PointCloudAdapter adapter(local, world);
         const opengv::transformation_t t = opengv::point_cloud::threept_arun(adapter);
         out->clear();
         out->emplace_back(1.0, Eigen::Quaterniond(Eigen::Matrix3d(t.leftCols<3>())), t.col(3));
       }},
  };
}
#else
std::vector<PeerSolver> OpenGvPeers() { return {}; }
#endif

}  // namespace linecloud
