// The user-facing localization API: Query × Map × Options → Result. One
// RANSAC (estimation/ransac.h) around the chosen method's minimal solver,
// then Levenberg–Marquardt refinement of the reprojection error (eq. 2 for
// point maps, eq. 6 for line clouds; Speciale et al., CVPR 2019).
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <variant>
#include <vector>

#include <Eigen/Core>

#include "linecloud/estimation/local_scale.h"
#include "linecloud/estimation/pose_data.h"
#include "linecloud/estimation/ransac.h"
#include "linecloud/estimation/refine_pose.h"
#include "linecloud/geometry/camera.h"
#include "linecloud/geometry/plucker.h"
#include "linecloud/geometry/rigid3.h"
#include "linecloud/lifting/key.h"
#include "linecloud/lifting/line_cloud.h"
#include "linecloud/solvers/minimal_problem.h"

namespace linecloud {

struct Reconstruction;  // io/colmap_model.h
struct PlyCamera;       // io/ply.h

struct QueryObservation {
  int camera = 0;
  Eigen::Vector2d xy;  // pixels, COLMAP convention (top-left pixel centre at 0.5, 0.5)
  uint64_t id = 0;     // map point id, or the id of the line lifted from it
  // The line id when `id` is a point id (the map owner's query files, e.g.
  // the demo's): used with a line cloud instead of `id`.
  std::optional<uint64_t> line_id;
  // Lowe's ratio of the descriptor match behind this correspondence (best /
  // second-best distance; lower is more distinctive). When every observation
  // has one, RANSAC tries the best-ranked first (PROSAC, estimation/sampler.h).
  std::optional<double> match_ratio;
};

struct Query {
  std::vector<Camera> cameras;
  std::vector<Rigid3d> cam_from_rig;  // one per camera; empty: identity
  std::vector<QueryObservation> observations;
  std::vector<Eigen::Vector3d> points_local;     // +l: one per observation, rig frame
  std::optional<Eigen::Vector3d> gravity_query;  // +u: gravity direction, rig frame
  std::optional<Eigen::Vector3d> gravity_map;    // +u: gravity direction, map frame
};

// A device's own 3D point for the +l methods (its tracking's local map): X̃ in
// the rig frame, seen in photo `frame` at its keypoint `keypoint` (the index
// in that photo's features, as given or as extracted with the map's SIFT
// options, as `linecloud features` writes them).
struct LocalPoint {
  int frame = 0;
  int64_t keypoint = 0;
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
};

// A traditional map: point coordinates by id.
struct PointMap {
  std::unordered_map<uint64_t, Eigen::Vector3d> points;
};
// A privacy-preserving map: lines by id, no coordinates to hold points.
struct LineMap {
  std::unordered_map<uint64_t, PluckerLine> lines;
};
using LocalizationMap = std::variant<PointMap, LineMap>;

PointMap PointMapFromModel(const Reconstruction& model);
// Lines by line id (what a query matched against the map's descriptors has).
LineMap LineMapFromCloud(const LineCloud& cloud);
// Lines by the id of the point each was lifted from: for the key's owner
// (evaluation, synthetic queries), whose correspondences carry point ids.
LineMap LineMapByPointId(const LineCloud& cloud, const LiftingKey& key);

// When a pose counts as found. COLMAP registers an image with at least 30
// inliers making up at least 25 % of its matches. A line gives one
// constraint (eq. 6: the offset across its projection) where a point gives two
// (eq. 2), so a line cloud needs twice the inliers for the same number of
// constraints, and a wrong pose collects chance inliers far more easily
// against lines (a band around a projected line, not a disc around a point):
// see docs/localize.md for the measurements behind the defaults.
struct SuccessCriteria {
  int min_inliers_points = 30;
  int min_inliers_lines = 60;
  double min_inlier_ratio = 0.25;
  // Upper bound on the estimated 1-σ rotation uncertainty (PoseUncertainty).
  double max_rotation_uncertainty_deg = 1.0;
  // Single-camera queries whose focal length is not refined: a wrong focal
  // length biases the pose far beyond its noise-based uncertainty. Refused
  // when the focal length that fits the inliers best (the profile of the cost
  // over the focal length) differs from the camera's by more than this
  // fraction, and the camera's is outside its 99.7 % interval, and that
  // interval is no wider than this fraction (CalibrationCheck). 0: no check.
  double max_focal_discrepancy = 0.1;
  // The same test for the principal point, as a fraction of the image's
  // width (x) and height (y): refused when the point the inliers fit is more
  // than this far, outside its 99.7 % interval, and that interval within 5 %
  // of the size (a principal point 15 % off gave a "success" 10.8° wrong, 5 %
  // off 3.2°).
  double max_principal_discrepancy = 0.01;
  // Upper bound on the estimated 1-σ position uncertainty (the matches' and
  // the calibration's), as a fraction of the median distance from the camera
  // to what its inliers see; one camera with the calibration check. A focal
  // length 5 % off passes the check and moves the camera along its axis: the
  // calibration's share of the uncertainty shows it (fountain: 4 % of the
  // distance; right cameras at most 0.4 % on real photos, 1.2 % on the
  // demo room's few inliers). 0: no check.
  double max_position_uncertainty = 0.02;
  // A pose is refused as ambiguous when RANSAC's competitor search (ransac.h)
  // found another pose, more than 1° from it, that explains at least this
  // share of its inlier count among matches it does not explain: the matches
  // do not tell the two apart. 0: no check.
  double max_runner_up_share = 0.8;

  // No criteria: every pose RANSAC finds is a success (the paper's protocol
  // and the benchmarks, which judge poses by their error to the truth).
  static SuccessCriteria None() {
    return {.min_inliers_points = 0,
            .min_inliers_lines = 0,
            .min_inlier_ratio = 0,
            .max_rotation_uncertainty_deg = std::numeric_limits<double>::infinity(),
            .max_focal_discrepancy = 0,
            .max_principal_discrepancy = 0,
            .max_position_uncertainty = 0,
            .max_runner_up_share = 0};
  }

  void Check() const;
};

struct LocalizeOptions {
  RansacOptions ransac;  // max_error in px
  bool refine = true;
  RefineOptions refinement;                             // final LM; `similarity` follows the method
  RefineOptions local_refinement{.max_iterations = 3};  // RANSAC's local optimisation
  SuccessCriteria success;
  // Single-camera queries: the focal length is a prior (e.g. from EXIF) and
  // is refined with the pose after RANSAC, as COLMAP's registration can.
  bool refine_focal = false;

  void Check() const;
};

// The camera fitted as a whole (CalibrationCheck::joint): θ = (log of a
// factor on the focal length, cx shift, cy shift in px, log of a factor on fy
// alone, radial λ of the division model, tangential p1, p2), the aspect ratio
// only for a camera with fx and fy (`active`).
inline constexpr int kJointParameters = 7;
struct JointCalibration {
  bool fitted = false;
  int parameters = 0;  // how many were fitted (the deviance's degrees of freedom)
  std::array<bool, kJointParameters> active = {};
  std::array<double, kJointParameters> theta = {};
  std::array<double, kJointParameters> se = {
      std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
      std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
      std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
      std::numeric_limits<double>::infinity()};
  double deviance = 0;
  // The factor (≥ 1) the standard errors widen by for the verdict: the
  // fit's Wald statistic brought down to its deviance (FitCalibrationJointly).
  double se_scale = 1;
  // How far the pose moves from the camera as given to the fitted one
  // (rotation in degrees, centre in world units).
  double pose_shift_deg = 0, pose_shift_centre = 0;
  // χ² with `parameters` degrees of freedom at 99.7 %, times the deviance's
  // overdispersion on real photos: the deviance beyond it rejects the camera
  // as given. A true camera's deviance is larger than χ² says: over fountain
  // 0000 under 42 keys and 3 maps of its own camera, median 10.0 for seven
  // parameters where χ²₇'s is 6.35 (the map's own small errors, residuals not
  // independent), and two of 42 beyond 21.6 — a true camera refused in CI
  // (p1 +0.0027) and in the wrong-camera bench (cy +13 px, with p1 +0.0029).
  static constexpr double kOverdispersion = 1.6;
  double DevianceLimit() const {
    constexpr std::array<double, 8> kLimit = {0, 8.81, 11.62, 13.93, 16.01, 17.96, 19.80, 21.58};
    return kOverdispersion * kLimit[static_cast<size_t>(std::clamp(parameters, 1, 7))];
  }
  // The data reject the camera as given (fitted, its deviance beyond the limit).
  bool RejectsGiven() const { return fitted && deviance > DevianceLimit(); }
};

// The calibration check (one camera, focal length not refined): the focal
// length the inliers fit best, its standard error (of its logarithm, the pose
// marginalised) and 99.7 % interval, and the given focal length's deviance
// (χ²₁ under Gaussian noise). Undetermined (a flat scene): se = +∞.
inline constexpr double kCalibrationZ = 3.0;  // the interval: ± 3 standard errors
struct CalibrationCheck {
  double best_fit_focal = 0;
  double log_focal_se = std::numeric_limits<double>::infinity();
  std::array<double, 2> interval = {0, std::numeric_limits<double>::infinity()};
  double deviance = 0;
  // The principal point, each axis profiled as the focal length is (the pose
  // refined anew for each shift): the given one, the one the inliers fit
  // best, its standard error (px) and the given one's deviance.
  std::array<double, 2> given_principal = {0, 0};
  std::array<double, 2> best_fit_principal = {0, 0};
  std::array<double, 2> principal_se = {std::numeric_limits<double>::infinity(),
                                        std::numeric_limits<double>::infinity()};
  std::array<double, 2> principal_deviance = {0, 0};
  std::array<double, 2> image_size = {0, 0};  // width, height (px)
  // The pose's 1-σ RMS uncertainty from the calibration's (rotation in
  // degrees, centre in world units): for each parameter, how the refitted
  // pose moves with it times its mean square error, from a prior (the camera
  // trusted to a third of what the check lets through; a refined focal
  // length not at all) and the profile's estimate (CalibrationMeanSquare).
  double rotation_deg = 0;
  double position = 0;
  // The aspect ratio (log of a factor on fy alone; cameras with fx and fy)
  // and the first radial distortion coefficient (a change to k1; a PINHOLE
  // camera tried as OPENCV), each profiled as the others: the change that
  // fits best, its standard error, the given camera's deviance.
  struct Extra {
    bool tested = false;
    double best = 0, se = std::numeric_limits<double>::infinity(), deviance = 0;
    bool at_edge = false;
  };
  Extra log_aspect, radial;
  // Whether the least cost lay at an end of the range searched (focal
  // length, cx, cy): the camera is farther off than the check reaches.
  std::array<bool, 3> at_edge = {false, false, false};
  // The camera fitted as a whole, the pose free (from the camera as given,
  // also when the focal length is refined): each parameter's change, its
  // marginal standard error, and the given camera's deviance. One at a
  // time, the profiles above can settle where two wrong parameters
  // compensate each other.
  JointCalibration joint;
  // With the focal length refined: the principal point fitted jointly with
  // it from the camera as given (a refined focal length and the pose absorb
  // much of a wrong principal point).
  std::optional<std::array<double, 2>> refit_principal;
};

struct LocalizeResult {
  // True only when the criteria hold; otherwise `failure` says why (a pose
  // RANSAC found but the criteria rejected is still in query_from_world).
  bool success = false;
  std::string failure;
  bool has_pose = false;
  int num_correspondences = 0;
  // Observations whose pixel the camera cannot undistort (undistortion does
  // not give it back, e.g. far outside the image): left out, counted as outliers.
  int rejected_observations = 0;
  // The pose's uncertainty: the matches' (below) and the calibration's
  // (CalibrationCheck) together.
  PoseUncertainty uncertainty;
  PoseUncertainty matches_uncertainty;  // from the matches' noise alone
  // The median distance (world units) from the camera to what its inliers
  // see (a point, or a line's point nearest the viewing ray); one camera
  // with the calibration check, else 0.
  double inlier_distance = 0;
  std::optional<double> refined_focal;  // with LocalizeOptions::refine_focal
  // The focal length the inliers fit best, from the calibration check.
  std::optional<double> best_fit_focal;
  std::optional<CalibrationCheck> calibration_check;
  double given_focal = 0;  // the query camera's (first camera's) mean focal length
  // +l methods seen by one camera: the scale fitted to the local points
  // (estimation/local_scale.h), since the reprojections leave it free.
  std::optional<LocalScaleFit> local_scale;
  Sim3d query_from_world;    // cam_from_world (one image) / rig_from_world / local_from_world
  Sim3d initial;             // RANSAC's estimate before the final refinement
  std::vector<int> inliers;  // observation indices
  // Per query camera (several cameras only): observations and inliers. A rig
  // pose is a success only when every camera with enough observations fits it.
  std::vector<int> camera_observations, camera_inliers;
  RansacStats stats;
  // RANSAC's runner-up (stats.runner_up_inliers > 0): its rotation's angle to
  // RANSAC's model, degrees.
  double runner_up_rotation_deg = 0;
  double refine_ms = 0;
  // Checking and preparing the query (undistortion, map look-ups), and the
  // success checks after the refinement (calibration check, uncertainty).
  double prepare_ms = 0, check_ms = 0;
  int refine_iterations = 0;
  // Mean reprojection errors (px) over RANSAC's inliers, at `initial` and at
  // `query_from_world`; an inlier the refined pose puts behind its camera is
  // left out of the second (always finite).
  double reprojection_initial_px = 0;
  double reprojection_refined_px = 0;
};

// A common mistake a camera's numbers show, as advice to the user, or "": a
// photo turned with only width and height swapped (a portrait photo with a
// landscape principal point, or the other way round), a camera made for the
// photo at another size (its principal point a multiple of this one's centre).
std::string CameraMistakeHint(const std::array<double, 2>& size,
                              const std::array<double, 2>& principal);
std::string CameraMistakeHint(const Camera& camera);

// Why the calibration check rejects the camera (a parameter outside its
// interval by more than the criteria allow), naming the parameter whose
// refit explains the inliers best and the app mistake the numbers show; ""
// when it does not.
std::string CalibrationFailure(const CalibrationCheck& check, double given_focal,
                               const SuccessCriteria& criteria);

// Why a pose RANSAC found does not meet the criteria ("" when it does): its
// support, the calibration check, the runner-up, the uncertainty.
std::string SuccessFailure(const MethodInfo& method, const LocalizeResult& result,
                           const SuccessCriteria& criteria);

// A query checked and turned into the solvers' frames: observations
// undistorted, map points/lines looked up by id, and for +u both frames
// rotated so that gravity is −y (identity otherwise).
struct PreparedQuery {
  PoseData data;
  Eigen::Quaterniond aligned_from_query = Eigen::Quaterniond::Identity();
  Eigen::Quaterniond aligned_from_map = Eigen::Quaterniond::Identity();

  // query_from_world = query_from_aligned ∘ pose ∘ aligned_from_map.
  Sim3d ToQueryFromWorld(const Sim3d& aligned_pose) const;
};

// Observation indices by match ratio, best first (stable); empty unless every
// observation has a match_ratio.
std::vector<int> MatchRanking(const std::vector<QueryObservation>& observations);

// Throws Error like Localize.
PreparedQuery PrepareQuery(const MethodInfo& method, const Query& query, const LocalizationMap& map,
                           std::string_view source = "query");

// Throws Error unless `method` has a solver and suits the map's kind (lines
// or points): what Localize checks first, for callers that check before
// their own work (matching a photo).
void CheckMethodAndMap(const MethodInfo& method, const LocalizationMap& map);

// Throws Error (naming `source`) for input the method cannot use: wrong map
// kind, too few observations, unknown ids, bad camera indices, non-finite
// values, missing local points or gravity. Observations whose pixel the camera
// cannot undistort are left out and counted (rejected_observations); result
// indices refer to the query as given.
LocalizeResult Localize(const MethodInfo& method, const Query& query, const LocalizationMap& map,
                        const LocalizeOptions& options, std::string_view source = "query");

// The query's cameras where the result put them (world_from_cam, with the
// scale of +s methods), for drawing (WriteLocalizationPly).
std::vector<PlyCamera> LocalizedCameras(const Query& query, const LocalizeResult& result);

// The rotation taking direction `gravity` to −y (the +u convention).
Eigen::Matrix3d GravityAlignment(const Eigen::Vector3d& gravity);

}  // namespace linecloud
