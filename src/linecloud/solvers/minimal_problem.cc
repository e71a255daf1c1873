#include "linecloud/solvers/minimal_problem.h"

#include <array>
#include <string>

#include "linecloud/solvers/m_p2l_lus.h"
#include "linecloud/solvers/m_p2p_lu.h"
#include "linecloud/solvers/m_p2p_lus.h"
#include "linecloud/solvers/m_p2p_u.h"
#include "linecloud/solvers/m_p3l_ls.h"
#include "linecloud/solvers/m_p3l_lu.h"
#include "linecloud/solvers/m_p3p.h"
#include "linecloud/solvers/m_p4l_l.h"
#include "linecloud/solvers/m_p4l_u.h"
#include "linecloud/solvers/m_p3p_l.h"
#include "linecloud/solvers/m_p3p_ls.h"
#include "linecloud/solvers/p2p_u.h"
#include "linecloud/solvers/p3p.h"
#include "linecloud/solvers/p6l.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

//                                   name          n  lines  multi  local  scale  grav.  impl.
constexpr std::array<MethodInfo, 16> kMethods = {{
    {MethodId::kP3P, "p3P", 3, false, false, false, false, false, true},
    {MethodId::kP2PU, "p2P+u", 2, false, false, false, false, true, true},
    {MethodId::kMP3P, "m-p3P", 3, false, true, false, false, false, true},
    {MethodId::kMP2PU, "m-p2P+u", 2, false, true, false, false, true, true},
    {MethodId::kMP3PL, "m-P3P+l", 3, false, true, true, false, false, true},
    {MethodId::kMP2PLU, "m-P2P+l+u", 2, false, true, true, false, true, true},
    {MethodId::kMP3PLS, "m-P3P+l+s", 3, false, true, true, true, false, true},
    {MethodId::kMP2PLUS, "m-P2P+l+u+s", 2, false, true, true, true, true, true},
    {MethodId::kP6L, "p6L", 6, true, false, false, false, false, true},
    {MethodId::kP4LU, "p4L+u", 4, true, false, false, false, true, true},
    {MethodId::kMP6L, "m-p6L", 6, true, true, false, false, false, true},
    {MethodId::kMP4LU, "m-p4L+u", 4, true, true, false, false, true, true},
    {MethodId::kMP4LL, "m-P4L+l", 4, true, true, true, false, false, true},
    {MethodId::kMP3LLU, "m-P3L+l+u", 3, true, true, true, false, true, true},
    {MethodId::kMP3LLS, "m-P3L+l+s", 3, true, true, true, true, false, true},
    {MethodId::kMP2LLUS, "m-P2L+l+u+s", 2, true, true, true, true, true, true},
}};

bool UsesBearings(const MethodInfo& m) { return !m.local_points; }

template <typename Pose>
int Collect(const std::vector<Pose>& poses, std::vector<Sim3d>* out) {
  out->clear();
  for (const Pose& p : poses) {
    if constexpr (std::is_same_v<Pose, Sim3d>) {
      out->push_back(p);
    } else {
      out->emplace_back(1.0, p.rotation, p.translation);
    }
  }
  return static_cast<int>(out->size());
}

}  // namespace

std::span<const MethodInfo> AllMethods() { return kMethods; }

const MethodInfo& FindMethod(std::string_view name) {
  std::string names;
  for (const MethodInfo& m : kMethods) {
    if (m.name == name) return m;
    names += (names.empty() ? "" : ", ") + std::string(m.name);
  }
  Fail("unknown method '{}' (methods: {})", name, names);
}

const MethodInfo& MethodFor(const QueryTraits& t) {
  const bool multi = t.several_cameras || t.local_points;
  const bool known_scale = t.local_points && t.known_scale;
  for (const MethodInfo& m : kMethods) {
    if (m.lines == t.lines && m.multi == multi && m.local_points == t.local_points &&
        m.known_scale == known_scale && m.gravity == t.gravity) {
      return m;
    }
  }
  Fail("no method for this query");  // unreachable: the table has every combination
}

void CheckSample(const MethodInfo& m, const MinimalSample& s, std::string_view source) {
  const size_t n = static_cast<size_t>(m.sample_size);
  const auto require = [&](const auto& field, const char* name, bool needed) {
    if (needed && field.size() != n) {
      Fail("{}: method {} needs {} entries in '{}', got {}", source, m.name, n, name, field.size());
    }
  };
  const auto finite = [&](const std::vector<Eigen::Vector3d>& v, const char* name) {
    for (size_t i = 0; i < v.size(); ++i) {
      if (!v[i].allFinite()) Fail("{}: '{}'[{}] is not finite", source, name, i);
    }
  };
  require(s.bearings, "bearings", UsesBearings(m));
  require(s.points_local, "points_local", m.local_points);
  require(s.points, "points", !m.lines);
  require(s.lines, "lines", m.lines);
  finite(s.bearings, "bearings");
  finite(s.points_local, "points_local");
  finite(s.points, "points");
  for (size_t i = 0; i < s.bearings.size(); ++i) {
    if (!(s.bearings[i].norm() > 0)) Fail("{}: 'bearings'[{}] is zero", source, i);
  }
  for (size_t i = 0; i < s.lines.size(); ++i) {
    if (!s.lines[i].IsValid(1e-6)) {
      Fail("{}: 'lines'[{}] is not a valid Plücker line (need |v| = 1, v·w = 0)", source, i);
    }
  }
  if (m.multi && UsesBearings(m)) {
    require(s.camera_index, "camera_index", true);
    if (s.cam_from_rig.empty()) Fail("{}: method {} needs 'cam_from_rig'", source, m.name);
    for (size_t i = 0; i < n; ++i) {
      if (s.camera_index[i] < 0 ||
          static_cast<size_t>(s.camera_index[i]) >= s.cam_from_rig.size()) {
        Fail("{}: 'camera_index'[{}] = {} but there are {} cameras in 'cam_from_rig'", source, i,
             s.camera_index[i], s.cam_from_rig.size());
      }
    }
  }
}

PreparedSample::PreparedSample(const MethodInfo& method, const MinimalSample& sample)
    : method_(&method), sample_(&sample) {
  if (!method.multi || !UsesBearings(method)) return;
  if (sample.bearings.size() > static_cast<size_t>(kMaxSize)) {
    Fail("method {}: {} bearings, a minimal sample has at most {}", method.name,
         sample.bearings.size(), kMaxSize);
  }
  num_rays_ = static_cast<int>(sample.bearings.size());
  for (int i = 0; i < num_rays_; ++i) {
    const Rigid3d& cam_from_rig = sample.cam_from_rig[sample.camera_index[i]];
    origins_[i] = cam_from_rig.Center();
    directions_[i] = cam_from_rig.rotation.inverse() * sample.bearings[i];
  }
}

int PreparedSample::Solve(std::vector<Rigid3d>* rigid, std::vector<Sim3d>* sim) const {
  const MinimalSample& s = *sample_;
  const std::span<const Eigen::Vector3d> origins(origins_.data(), num_rays_);
  const std::span<const Eigen::Vector3d> directions(directions_.data(), num_rays_);
  switch (method_->id) {
    case MethodId::kP3P:
      return p3p(s.bearings, s.points, rigid);
    case MethodId::kP2PU:
      return p2p_u(s.bearings, s.points, rigid);
    case MethodId::kMP3P:
      return m_p3p(origins, directions, s.points, rigid);
    case MethodId::kMP2PU:
      return m_p2p_u(origins, directions, s.points, rigid);
    case MethodId::kMP3PL:
      return m_p3p_l(s.points_local, s.points, sim);
    case MethodId::kMP2PLU:
      return m_p2p_lu(s.points_local, s.points, sim);
    case MethodId::kMP3PLS:
      return m_p3p_ls(s.points_local, s.points, rigid);
    case MethodId::kMP2PLUS:
      return m_p2p_lus(s.points_local, s.points, rigid);
    case MethodId::kP4LU:
      return p4l_u(s.bearings, s.lines, rigid);
    case MethodId::kMP4LU:
      return m_p4l_u(origins, directions, s.lines, rigid);
    case MethodId::kMP4LL:
      return m_p4l_l(s.lines, s.points_local, sim);
    case MethodId::kMP3LLU:
      return m_p3l_lu(s.lines, s.points_local, sim);
    case MethodId::kMP3LLS:
      return m_p3l_ls(s.lines, s.points_local, rigid);
    case MethodId::kMP2LLUS:
      return m_p2l_lus(s.lines, s.points_local, rigid);
    case MethodId::kP6L:
      return p6l(s.bearings, s.lines, rigid);
    case MethodId::kMP6L:
      return m_p6l(origins, directions, s.lines, rigid);
  }
  Fail("method {} has no minimal solver in this build yet", method_->name);
}

int SolveMinimal(const MethodInfo& m, const MinimalSample& s, std::vector<Sim3d>* out) {
  // Scratch buffers reused across calls (RANSAC calls this in a hot loop).
  thread_local std::vector<Rigid3d> rigid;
  thread_local std::vector<Sim3d> sim;
  const PreparedSample prepared(m, s);
  prepared.Solve(&rigid, &sim);
  return m.similarity() ? Collect(sim, out) : Collect(rigid, out);
}

double MaxResidual(const MethodInfo& m, const MinimalSample& s, const Sim3d& pose) {
  double worst = 0;
  const size_t n = static_cast<size_t>(m.sample_size);
  for (size_t i = 0; i < n; ++i) {
    double r;
    if (m.local_points) {
      const Eigen::Vector3d& x = s.points_local[i];
      const double dist =
          m.lines ? Transform(pose, s.lines[i]).DistanceTo(x) : (x - pose * s.points[i]).norm();
      r = dist / std::max(1.0, x.norm());
    } else {
      Rigid3d cam_from_world(pose.rotation, pose.translation);
      if (m.multi) cam_from_world = s.cam_from_rig[s.camera_index[i]] * cam_from_world;
      const Eigen::Vector3d f = s.bearings[i].normalized();
      if (m.lines) {
        const PluckerLine l = Transform(cam_from_world, s.lines[i]);
        r = std::abs(f.dot(l.w)) / std::max(l.w.norm(), 1e-300);
      } else {
        const Eigen::Vector3d x = cam_from_world * s.points[i];
        r = f.cross(x).norm() / std::max(x.norm(), 1e-300);
      }
    }
    worst = std::max(worst, r);
  }
  return worst;
}

}  // namespace linecloud
