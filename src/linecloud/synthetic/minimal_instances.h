// Seeded random instances of the 16 minimal problems with their true pose,
// for the solver tests and `linecloud bench solvers`: random rotations (about
// y for +u), translations, scales in [0.1, 10] (log-uniform) for Sim3
// methods, random rig layouts for m- methods, random line signs.
#pragma once

#include <random>
#include <string_view>

#include "linecloud/solvers/minimal_problem.h"

namespace linecloud {

struct MinimalInstance {
  MinimalSample sample;
  Sim3d truth;  // query_from_world
};

// Near-degenerate families of the ray-to-line problems (bearing methods on a
// line map; other methods ignore the family): the bench characterises the
// solvers on them.
enum class InstanceFamily {
  kGeneric,            // ~90° field of view, random line directions
  kNarrowFov,          // 10° field of view
  kLinesAlongRays,     // each line within ~1° of its viewing ray
  kLinesThroughPoint,  // all lines through one world point
};
std::string_view FamilyName(InstanceFamily family);

// `num_correspondences` > 0 overrides the method's sample size (bearing
// methods only; for peers that need more than a minimal sample).
MinimalInstance RandomMinimalInstance(const MethodInfo& method, std::mt19937_64& rng,
                                      InstanceFamily family = InstanceFamily::kGeneric,
                                      int num_correspondences = 0);

struct PoseError {
  double rotation_rad = 0;
  double translation_rel = 0;  // |t − t_true| / max(1, |t_true|)
  double scale_rel = 0;
};
PoseError ComparePoses(const Sim3d& estimate, const Sim3d& truth);

}  // namespace linecloud
