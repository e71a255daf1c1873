// linecloud's core API in one include: lifting a map to a line cloud
// (Speciale et al., "Privacy Preserving Image-Based Localization", CVPR 2019),
// the .lcm and COLMAP formats, the 16 pose estimators with RANSAC and
// refinement, and seeded synthetic queries. Link linecloud::core.
// linecloud::features adds linecloud/pipeline/localizer.h (a map loaded once,
// photos, features and queries answered) and linecloud/pipeline/image_query.h,
// linecloud::privacy the attacks and the audit (linecloud/privacy/*.h).
#pragma once

#include "linecloud/version.h"

#include "linecloud/util/error.h"
#include "linecloud/geometry/camera.h"
#include "linecloud/geometry/plucker.h"
#include "linecloud/geometry/rigid3.h"
#include "linecloud/solvers/minimal_problem.h"
#include "linecloud/estimation/ransac.h"
#include "linecloud/estimation/refine_pose.h"
#include "linecloud/lifting/key.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/lifting/line_cloud.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/io/colmap_database.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/io/lift_model.h"
#include "linecloud/localize/localize.h"
#include "linecloud/localize/query_json.h"
#include "linecloud/synthetic/localization_instances.h"
