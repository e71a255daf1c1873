// The 16 pose problems of Speciale et al., CVPR 2019 (Table 1), as data: one
// minimal sample type for all of them, a dispatcher to each method's minimal
// solver, and the residual of each method's constraint. Names, sample sizes
// and conventions: docs/methods.md.
#pragma once

#include <array>
#include <span>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/plucker.h"
#include "linecloud/geometry/rigid3.h"

namespace linecloud {

enum class MethodId {
  kP3P,
  kP2PU,
  kMP3P,
  kMP2PU,
  kMP3PL,
  kMP2PLU,
  kMP3PLS,
  kMP2PLUS,
  kP6L,
  kP4LU,
  kMP6L,
  kMP4LU,
  kMP4LL,
  kMP3LLU,
  kMP3LLS,
  kMP2LLUS,
};

struct MethodInfo {
  MethodId id;
  std::string_view name;
  int sample_size;
  bool lines;         // map of lines (privacy-preserving) vs points
  bool multi;         // several cameras (rig / generalized camera)
  bool local_points;  // query supplies 3D points X̃ (+λ)
  bool known_scale;   // +s (only meaningful with local_points)
  bool gravity;       // +u: rotation about y
  bool implemented;   // a minimal solver exists in this build

  bool similarity() const { return local_points && !known_scale; }
};

// The 16 methods in the paper's order.
std::span<const MethodInfo> AllMethods();
// Throws Error listing the valid names when `name` is unknown.
const MethodInfo& FindMethod(std::string_view name);

// What a query brings, naming the method that uses all of it (Speciale et
// al., CVPR 2019, Table 1): several cameras of a rig (m-), the query's own 3D
// points (+l, always a generalized camera: m-), their scale known (+s) and
// gravity in both frames (+u).
struct QueryTraits {
  bool lines = true;  // the map holds lines (else points)
  bool several_cameras = false;
  bool local_points = false;
  bool known_scale = false;  // only with local_points
  bool gravity = false;
};
const MethodInfo& MethodFor(const QueryTraits& traits);

// One minimal sample; fields a method does not use stay empty.
struct MinimalSample {
  std::vector<Eigen::Vector3d> bearings;      // unit, camera frame
  std::vector<int> camera_index;              // m- methods with bearings
  std::vector<Rigid3d> cam_from_rig;          // m- methods with bearings
  std::vector<Eigen::Vector3d> points_local;  // +l: X̃ in the query frame
  std::vector<Eigen::Vector3d> points;        // point map
  std::vector<PluckerLine> lines;             // line map
};

// Throws Error naming `source` and the field when the sample does not fit
// the method (missing field, wrong count, bad camera index, non-finite value).
void CheckSample(const MethodInfo& method, const MinimalSample& sample, std::string_view source);

// A checked sample in the form its solver takes: for m- methods with
// bearings, the rays in the rig frame (origin = camera centre c_i, direction
// R_cᵀ f_i), computed once. SolveMinimal builds one per call; `linecloud bench
// solvers` builds them before timing, so its µs/call is the solver alone — as
// PoseLib's benchmark times its solvers on prepared inputs. `sample` must
// outlive it.
class PreparedSample {
 public:
  static constexpr int kMaxSize = 6;  // the largest minimal sample (p6L)

  PreparedSample(const MethodInfo& method, const MinimalSample& sample);

  // The method's solver. Sim3 methods (method.similarity()) write *sim, the
  // others *rigid; returns the number of solutions (query_from_world).
  int Solve(std::vector<Rigid3d>* rigid, std::vector<Sim3d>* sim) const;

 private:
  const MethodInfo* method_;
  const MinimalSample* sample_;
  std::array<Eigen::Vector3d, kMaxSize> origins_, directions_;
  int num_rays_ = 0;
};

// Runs the method's minimal solver on a checked sample: every real solution
// as query_from_world (cam_from_world, rig_from_world or local_from_world),
// scale 1 for rigid methods. Throws Error when the method has no solver yet.
int SolveMinimal(const MethodInfo& method, const MinimalSample& sample,
                 std::vector<Sim3d>* solutions);

// Largest residual of the method's constraint over the sample, dimensionless:
// sine of the angle between bearing and point, or between bearing and the
// plane through the camera centre and the line; for local points, the
// point-to-point or point-to-line distance over max(1, |X̃|).
double MaxResidual(const MethodInfo& method, const MinimalSample& sample,
                   const Sim3d& query_from_world);

}  // namespace linecloud
