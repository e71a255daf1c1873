#include "linecloud/util/log.h"
#include "linecloud/eval/eval_prepare.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <random>
#include <set>
#include <unordered_map>

#include <Eigen/Geometry>
#include <fmt/core.h>

#include "linecloud/colmap/dataset.h"
#include "linecloud/util/statistics.h"
#include "linecloud/io/colmap_database.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

constexpr double kDeg = 180.0 / std::numbers::pi;

// world_new = s R world + t applied to every pose and point.
void TransformReconstruction(const Sim3d& new_from_old, Reconstruction* rec) {
  const Eigen::Quaterniond& q = new_from_old.rotation;
  const double s = new_from_old.scale;
  for (auto& [id, image] : rec->images) {
    Rigid3d& p = image.cam_from_world;
    const Eigen::Quaterniond r = p.rotation * q.inverse();
    p.translation = s * p.translation - (r * new_from_old.translation);
    p.rotation = r.normalized();
  }
  for (auto& [id, point] : rec->points3D) point.xyz = new_from_old * point.xyz;
}

const Image* FindImage(const Reconstruction& rec, const std::string& name) {
  for (const auto& [id, image] : rec.images) {
    if (image.name == name) return &image;
  }
  return nullptr;
}

Eigen::Vector3d RandomlyTilted(const Eigen::Vector3d& g, double sigma_deg, std::mt19937_64& rng) {
  if (sigma_deg <= 0) return g.normalized();
  std::normal_distribution<double> normal(0.0, sigma_deg / kDeg);
  std::uniform_real_distribution<double> uniform(0.0, 2 * std::numbers::pi);
  const double angle = std::abs(normal(rng));
  const Eigen::Vector3d a = g.unitOrthogonal();
  const Eigen::Vector3d b = g.normalized().cross(a);
  const double phi = uniform(rng);
  const Eigen::Vector3d axis = std::cos(phi) * a + std::sin(phi) * b;
  return (Eigen::AngleAxisd(angle, axis) * g).normalized();
}

// Ground-truth comparison after a similarity alignment on `align_names`;
// returns world_gt_from_world_rec.
Sim3d AlignToGroundTruth(const Reconstruction& rec, const std::map<std::string, Rigid3d>& gt,
                         const std::vector<std::string>& align_names, nlohmann::json* report) {
  std::vector<Eigen::Vector3d> src, dst;
  for (const std::string& name : align_names) {
    const Image* im = FindImage(rec, name);
    if (im && gt.count(name)) {
      src.push_back(im->cam_from_world.Center());
      dst.push_back(gt.at(name).Center());
    }
  }
  if (src.size() < 3)
    Fail("ground truth: only {} map cameras are both reconstructed and in gt/", src.size());
  // Rotation from the camera orientations (chordal mean of R_gt_iᵀ R_rec_i:
  // well constrained even when the centres lie near a line), then scale and
  // translation from the centres by least squares.
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
  for (const std::string& name : align_names) {
    const Image* im = FindImage(rec, name);
    if (im && gt.count(name)) {
      M += gt.at(name).rotation.toRotationMatrix().transpose() *
           im->cam_from_world.rotation.toRotationMatrix();
    }
  }
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d R = svd.matrixU() * svd.matrixV().transpose();
  if (R.determinant() < 0) {
    Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
    F(2, 2) = -1;
    R = svd.matrixU() * F * svd.matrixV().transpose();
  }
  Eigen::Vector3d c_mean = Eigen::Vector3d::Zero(), d_mean = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < src.size(); ++i) {
    c_mean += src[i] / src.size();
    d_mean += dst[i] / dst.size();
  }
  double num = 0, den = 0;
  for (size_t i = 0; i < src.size(); ++i) {
    num += (dst[i] - d_mean).dot(R * (src[i] - c_mean));
    den += (src[i] - c_mean).squaredNorm();
  }
  if (!(den > 0 && num > 0)) Fail("ground truth: the reconstructed camera centres are degenerate");
  const double s = num / den;
  Sim3d gt_from_rec(s, Eigen::Quaterniond(R).normalized(), d_mean - s * R * c_mean);
  Reconstruction aligned = rec;
  TransformReconstruction(gt_from_rec, &aligned);
  nlohmann::json per_image = nlohmann::json::array();
  std::vector<double> rot_map, pos_map, rot_query, pos_query;
  for (const auto& [id, im] : aligned.images) {
    if (!gt.count(im.name)) continue;
    const double r = RotationDistance(im.cam_from_world.rotation, gt.at(im.name).rotation) * kDeg;
    const double p = (im.cam_from_world.Center() - gt.at(im.name).Center()).norm();
    const bool is_map =
        std::find(align_names.begin(), align_names.end(), im.name) != align_names.end();
    (is_map ? rot_map : rot_query).push_back(r);
    (is_map ? pos_map : pos_query).push_back(p);
    per_image.push_back(
        {{"name", im.name}, {"map_camera", is_map}, {"rotation_deg", r}, {"position_m", p}});
  }
  auto max_of = [](const std::vector<double>& v) {
    return v.empty() ? 0.0 : *std::max_element(v.begin(), v.end());
  };
  (*report)["ground_truth"] = {{"aligned_on", src.size()},
                               {"scale", s},
                               {"max_rotation_deg", std::max(max_of(rot_map), max_of(rot_query))},
                               {"max_position_m", std::max(max_of(pos_map), max_of(pos_query))},
                               {"map_max_rotation_deg", max_of(rot_map)},
                               {"map_max_position_m", max_of(pos_map)},
                               {"query_max_rotation_deg", max_of(rot_query)},
                               {"query_max_position_m", max_of(pos_query)},
                               {"per_image", per_image}};
  return gt_from_rec;
}

// Metric scale from a calibrated stereo rig: median ratio of calibrated to
// reconstructed baselines over the registered pairs.
double ScaleFromRig(const EvalDataset& d, const Reconstruction& rec, int* pairs) {
  std::map<int64_t, std::vector<const Image*>> by_time;
  for (const auto& [id, im] : rec.images) {
    if (auto t = EurocTimestampNs(im.name)) by_time[*t].push_back(&im);
  }
  std::vector<double> ratios;
  for (const auto& [t, ims] : by_time) {
    if (ims.size() != 2) continue;
    const uint32_t c0 = d.image_camera.at(ims[0]->name), c1 = d.image_camera.at(ims[1]->name);
    if (!d.sensors->body_from_cam.count(c0) || !d.sensors->body_from_cam.count(c1)) continue;
    const double calibrated =
        (d.sensors->body_from_cam.at(c0).translation - d.sensors->body_from_cam.at(c1).translation)
            .norm();
    const double reconstructed =
        (ims[0]->cam_from_world.Center() - ims[1]->cam_from_world.Center()).norm();
    if (reconstructed > 0) ratios.push_back(calibrated / reconstructed);
  }
  *pairs = static_cast<int>(ratios.size());
  if (ratios.empty())
    Fail("no stereo pair is reconstructed: cannot make the reconstruction metric");
  return Median(ratios);
}

std::string GroupName(size_t k) { return fmt::format("g{:02d}", k); }

}  // namespace

void EvalPrepareOptions::Check() const {
  if (dataset_dir.empty()) Fail("--dataset: empty");
  if (work_dir.empty()) Fail("--work: empty");
  if (!(gravity_noise_deg >= 0 && gravity_noise_deg < 90))
    Fail("--gravity-noise-deg: {} not in [0, 90)", gravity_noise_deg);
  sfm.Check();
}

bool RefinePointFixedPoses(const std::vector<PointObservation>& obs, Eigen::Vector3d* point) {
  if (obs.size() < 2) return false;
  std::vector<Eigen::Vector2d> normalized(obs.size());
  std::vector<double> focal(obs.size());
  for (size_t i = 0; i < obs.size(); ++i) {
    normalized[i] = obs[i].camera->CamFromImg(obs[i].xy).head<2>();
    focal[i] = obs[i].camera->MeanFocalLength();
  }
  constexpr double kHuber = 2.0;  // px
  auto cost = [&](const Eigen::Vector3d& X) {
    double c = 0;
    for (size_t i = 0; i < obs.size(); ++i) {
      const Eigen::Vector3d x = obs[i].cam_from_world * X;
      if (!(x.z() > 1e-9)) return std::numeric_limits<double>::infinity();
      const double r = focal[i] * (x.head<2>() / x.z() - normalized[i]).norm();
      c += r <= kHuber ? 0.5 * r * r : kHuber * (r - 0.5 * kHuber);
    }
    return c;
  };
  Eigen::Vector3d X = *point;
  double c0 = cost(X);
  if (!std::isfinite(c0)) return false;
  const double initial = c0;
  double lambda = 1e-4;
  for (int iter = 0; iter < 20; ++iter) {
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < obs.size(); ++i) {
      const Eigen::Matrix3d R = obs[i].cam_from_world.rotation.toRotationMatrix();
      const Eigen::Vector3d x = R * X + obs[i].cam_from_world.translation;
      const double iz = 1.0 / x.z();
      const Eigen::Vector2d r = focal[i] * (x.head<2>() * iz - normalized[i]);
      Eigen::Matrix<double, 2, 3> dpi;
      dpi << iz, 0, -x.x() * iz * iz, 0, iz, -x.y() * iz * iz;
      const Eigen::Matrix<double, 2, 3> J = focal[i] * dpi * R;
      const double n = r.norm();
      const double w = n <= kHuber ? 1.0 : kHuber / n;
      H += w * J.transpose() * J;
      g += w * J.transpose() * r;
    }
    bool improved = false;
    for (int attempt = 0; attempt < 8 && !improved; ++attempt) {
      Eigen::Matrix3d A = H;
      A.diagonal() *= 1.0 + lambda;
      const Eigen::Vector3d step = -A.ldlt().solve(g);
      if (!step.allFinite()) break;
      const Eigen::Vector3d X_new = X + step;
      const double c_new = cost(X_new);
      if (c_new < c0) {
        const bool converged = c0 - c_new < 1e-12 * (1 + c0);
        X = X_new;
        c0 = c_new;
        lambda = std::max(lambda * 0.1, 1e-9);
        improved = true;
        if (converged) iter = 100;
      } else {
        lambda *= 10;
      }
    }
    if (!improved) break;
  }
  if (!(c0 < initial)) return false;
  *point = X;
  return true;
}

Reconstruction MapWithoutImages(const Reconstruction& full, const std::vector<std::string>& group) {
  Reconstruction map = full;
  std::set<uint32_t> removed;
  for (const auto& [id, im] : full.images) {
    if (std::find(group.begin(), group.end(), im.name) != group.end()) removed.insert(id);
  }
  for (uint32_t id : removed) map.images.erase(id);
  std::vector<uint64_t> dropped;
  for (auto& [pid, point] : map.points3D) {
    std::erase_if(point.track,
                  [&](const TrackElement& e) { return removed.count(e.image_id) > 0; });
    if (point.track.size() < 2) {
      dropped.push_back(pid);
      continue;
    }
    std::vector<PointObservation> obs;
    for (const TrackElement& e : point.track) {
      const Image& im = map.images.at(e.image_id);
      obs.push_back(
          {&map.cameras.at(im.camera_id), im.cam_from_world, im.points2D.at(e.point2D_idx).xy});
    }
    RefinePointFixedPoses(obs, &point.xyz);
  }
  for (uint64_t pid : dropped) {
    for (const TrackElement& e : map.points3D.at(pid).track) {
      map.images.at(e.image_id).points2D.at(e.point2D_idx).point3D_id = kInvalidPoint3DId;
    }
    map.points3D.erase(pid);
  }
  return map;
}

namespace {

// Units: the ground truth's metres, the rig's calibrated baseline, or none
// (the full reconstruction is transformed into them).
void SetUnits(const EvalDataset& dataset, Reconstruction* full_ptr, EvalWork* work_ptr) {
  Reconstruction& full = *full_ptr;
  EvalWork& work = *work_ptr;
  if (!dataset.ground_truth.empty()) {
    std::vector<std::string> align = dataset.MapOnlyImages();
    int usable = 0;
    for (const auto& n : align) usable += FindImage(full, n) && dataset.ground_truth.count(n);
    if (usable < 3) {
      align = dataset.images;  // too few map-only cameras: align on all
      work.reconstruction["alignment_note"] =
          "every image is a query of some group: aligned on all cameras";
    }
    const Sim3d gt_from_rec =
        AlignToGroundTruth(full, dataset.ground_truth, align, &work.reconstruction);
    TransformReconstruction(gt_from_rec, &full);
    work.units = "metres";
    const auto& g = work.reconstruction["ground_truth"];
    LogProgress(
        "[eval] reconstruction vs ground truth (similarity on {} map cameras): max {:.3f}° / "
        "{:.4f} m",
        g["aligned_on"].get<int>(), g["max_rotation_deg"].get<double>(),
        g["max_position_m"].get<double>());
  } else if (dataset.sensors && dataset.sensors->body_from_cam.size() >= 2) {
    int pairs = 0;
    const double s = ScaleFromRig(dataset, full, &pairs);
    TransformReconstruction(Sim3d(s, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero()),
                            &full);
    work.units = "metres";
    work.reconstruction["metric_scale"] = {
        {"source", "calibrated stereo baseline"}, {"pairs", pairs}, {"scale", s}};
    LogProgress("[eval] metric scale from the calibrated stereo baseline ({} pairs): {:.5f}", pairs,
                s);
  } else {
    work.units = "reconstruction units";
  }
}

// Gravity per image (camera frame) and in the world: the real IMU where there
// is one, else the scene's vertical tilted by the requested noise.
std::map<std::string, Eigen::Vector3d> GravityPerImage(const EvalDataset& dataset,
                                                       const Reconstruction& full,
                                                       const EvalPrepareOptions& options,
                                                       EvalWork* work_ptr) {
  EvalWork& work = *work_ptr;
  std::mt19937_64 rng(options.seed);
  std::map<std::string, Eigen::Vector3d> gravity_cam;
  if (dataset.sensors) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const auto& [id, im] : full.images) {
      const auto t = EurocTimestampNs(im.name);
      const uint32_t cam = dataset.image_camera.at(im.name);
      if (!t || !dataset.sensors->body_from_cam.count(cam))
        Fail("{}: no timestamp or sensor for image {}", dataset.dir, im.name);
      const Eigen::Vector3d g_body = GravityInBody(*dataset.sensors, *t);
      const Eigen::Vector3d g = dataset.sensors->body_from_cam.at(cam).rotation.inverse() * g_body;
      gravity_cam[im.name] = g;
      if (!dataset.IsQueryImage(im.name)) sum += im.cam_from_world.rotation.inverse() * g;
    }
    work.gravity_world = sum.normalized();
    work.gravity_source =
        "IMU accelerometer (mean within ±25 ms of each image); map: mean over map images";
    work.gravity_noise_deg = 0;
  } else {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const auto& [id, im] : full.images)
      sum += im.cam_from_world.rotation.inverse() * Eigen::Vector3d::UnitY();
    work.gravity_world = sum.normalized();
    for (const auto& [id, im] : full.images) {
      gravity_cam[im.name] = RandomlyTilted(im.cam_from_world.rotation * work.gravity_world,
                                            options.gravity_noise_deg, rng);
    }
    work.gravity_source = fmt::format(
        "ground truth: the mean image-down direction of all cameras, per image tilted by |N(0, "
        "{}°)|",
        options.gravity_noise_deg);
  }

  return gravity_cam;
}

// Indirect matching: a query keypoint matched to a map image's keypoint that
// observes a map point votes for that point; the most voted wins. `kps`: the
// query keypoint of each correspondence.
EvalImage IndirectCorrespondences(const std::string& name, const EvalDataset& dataset,
                                  const Reconstruction& full, const ColmapDatabase& database,
                                  const std::map<std::string, uint32_t>& db_id,
                                  const std::map<std::string, const Image*>& map_by_name,
                                  const std::map<std::string, Eigen::Vector3d>& gravity_cam,
                                  const std::string& colmap_dir, std::vector<uint32_t>* kps_out) {
  EvalImage image;
  image.name = name;
  image.camera_id = dataset.image_camera.at(name);
  image.cam_from_world = FindImage(full, name)->cam_from_world;
  image.gravity = gravity_cam.at(name);
  if (!db_id.count(name)) Fail("{}: image {} is not in COLMAP's database", colmap_dir, name);
  const uint32_t q = db_id.at(name);
  const FeatureKeypoints keypoints = database.ReadKeypoints(q);
  std::unordered_map<uint32_t, std::map<uint64_t, int>> votes;
  for (const auto& [map_name, map_image] : map_by_name) {
    if (!db_id.count(map_name)) continue;
    const FeatureMatches matches = database.ReadMatches(q, db_id.at(map_name));
    for (Eigen::Index r = 0; r < matches.rows(); ++r) {
      const uint32_t kq = matches(r, 0), km = matches(r, 1);
      if (km >= map_image->points2D.size() || kq >= keypoints.rows()) continue;
      const uint64_t pid = map_image->points2D[km].point3D_id;
      if (pid != kInvalidPoint3DId) ++votes[kq][pid];
    }
  }
  std::vector<uint32_t> kps;
  for (const auto& [kq, v] : votes) kps.push_back(kq);
  std::sort(kps.begin(), kps.end());
  for (uint32_t kq : kps) {
    const auto& v = votes.at(kq);
    const auto best = std::max_element(
        v.begin(), v.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
    EvalCorrespondence c;
    c.xy = {keypoints(kq, 0), keypoints(kq, 1)};
    c.point_id = best->first;
    c.votes = best->second;
    image.correspondences.push_back(c);
  }
  *kps_out = std::move(kps);
  return image;
}

// Largest rotation between a group's own reconstruction and the ground truth
// (relative to the group's first camera) for its rig to be used.
constexpr double kMaxLocalRigErrorDeg = 1.0;

// The rig and the +l structure from the group's own reconstruction (COLMAP on
// the group's images alone); leaves has_rig false when that fails or
// disagrees with the ground truth.
void AttachLocalStructure(const EvalDataset& dataset, const EvalPrepareOptions& options,
                          const std::string& colmap_dir, const std::string& group_dir,
                          const std::vector<std::string>& registered,
                          const std::map<std::string, std::vector<uint32_t>>& keypoint_of,
                          EvalGroup* group_ptr) {
  EvalGroup& group = *group_ptr;
  const std::string images_dir = JoinPaths(dataset.dir, "images");
  const EvalImage& first = group.images.front();
  const Rigid3d& cam0_from_world = first.cam_from_world;
  Rigid3d rig_from_cam0;  // identity: the rig frame is the first camera's
  const uint32_t cam0 = first.camera_id;
  const bool calibrated_rig = dataset.sensors && dataset.sensors->body_from_cam.count(cam0);
  if (calibrated_rig) rig_from_cam0 = dataset.sensors->body_from_cam.at(cam0);
  group.rig_from_world = rig_from_cam0 * cam0_from_world;
  group.gravity_rig = rig_from_cam0.rotation * first.gravity;
  if (registered.size() >= 2) {
    const Reconstruction local =
        ReconstructImageSubset(JoinPaths(colmap_dir, "database.db"), images_dir, registered,
                               JoinPaths(group_dir, "local"), options.sfm.colmap);
    const Image* l0 = FindImage(local, first.name);
    bool all = l0 != nullptr;
    for (const EvalImage& im : group.images) all = all && FindImage(local, im.name);
    if (all) {
      // metric = local units × m: from the ground truth (the aligned full
      // reconstruction) or from the rig's calibrated baselines.
      double local_baseline = 0, metric_baseline = 0;
      for (const EvalImage& im : group.images) {
        const Image* li = FindImage(local, im.name);
        local_baseline += (li->cam_from_world.Center() - l0->cam_from_world.Center()).norm();
        if (calibrated_rig && dataset.sensors->body_from_cam.count(im.camera_id) &&
            EurocTimestampNs(im.name) == EurocTimestampNs(first.name)) {
          metric_baseline += (dataset.sensors->body_from_cam.at(im.camera_id).translation -
                              rig_from_cam0.translation)
                                 .norm();
        } else {
          metric_baseline += (im.cam_from_world.Center() - cam0_from_world.Center()).norm();
        }
      }
      // A group's own reconstruction can be wrong where the full one is right
      // (entry-P10's two-view groups of a facade: 14.7° and 20.8° between the
      // cameras' relative rotation and the ground truth's). A device's
      // tracking is not that wrong; evaluated with such a rig, every m- method
      // is judged against a rig that does not exist. Skipped, and said.
      double worst_deg = 0;
      for (const EvalImage& im : group.images) {
        const Image* li = FindImage(local, im.name);
        const Eigen::Quaterniond local_rel =
            li->cam_from_world.rotation * l0->cam_from_world.rotation.inverse();
        const Eigen::Quaterniond true_rel =
            im.cam_from_world.rotation * cam0_from_world.rotation.inverse();
        worst_deg = std::max(worst_deg, local_rel.angularDistance(true_rel) * kDeg);
      }
      if (!calibrated_rig && worst_deg > kMaxLocalRigErrorDeg) {
        LogProgress(
            "[eval] group {}: its own reconstruction puts the cameras {:.1f}° off the ground "
            "truth's relative rotations (more than {}°); m- and +l methods skip it",
            group.name, worst_deg, kMaxLocalRigErrorDeg);
        local_baseline = 0;
      }
      if (local_baseline > 0 && metric_baseline > 0) {
        const double m = metric_baseline / local_baseline;
        group.has_rig = true;
        group.local_scale = 1.0 / m;
        group.rig_source = calibrated_rig ? "calibration"
                                          : "local reconstruction (metric scale from ground truth)";
        // rig_from_local: X_rig = rig_from_cam0 (m (R0 X + t0)).
        auto rig_from_local = [&](const Eigen::Vector3d& X) {
          return rig_from_cam0 * (m * (l0->cam_from_world * X));
        };
        for (EvalImage& im : group.images) {
          const Image* li = FindImage(local, im.name);
          if (calibrated_rig && dataset.sensors->body_from_cam.count(im.camera_id)) {
            im.cam_from_rig = dataset.sensors->body_from_cam.at(im.camera_id).Inverse();
          } else {
            // cam_from_rig = cam_from_local ∘ local_from_cam0 ∘ cam0_from_rig, metric.
            Rigid3d cam_from_cam0 = li->cam_from_world * l0->cam_from_world.Inverse();
            cam_from_cam0.translation *= m;
            im.cam_from_rig = cam_from_cam0 * rig_from_cam0.Inverse();
          }
          const std::vector<uint32_t>& kps = keypoint_of.at(im.name);
          for (size_t k = 0; k < im.correspondences.size(); ++k) {
            if (kps[k] >= li->points2D.size()) continue;
            const uint64_t pid = li->points2D[kps[k]].point3D_id;
            if (pid != kInvalidPoint3DId)
              im.correspondences[k].point_local = rig_from_local(local.points3D.at(pid).xyz);
          }
        }
      }
    }
    if (!group.has_rig && !all) {
      LogProgress(
          "[eval] group {}: COLMAP could not reconstruct the group on its own; m- methods skip "
          "it",
          group.name);
    }
  }
}

}  // namespace

EvalWork PrepareEvaluation(const EvalPrepareOptions& options) {
  options.Check();
  const EvalDataset dataset = ReadEvalDataset(options.dataset_dir);
  LogProgress("[eval] dataset {}: {} images, {} cameras, {} query groups{}{}", dataset.name,
              dataset.images.size(), dataset.cameras.size(), dataset.query_groups.size(),
              dataset.ground_truth.empty() ? "" : ", ground truth",
              dataset.sensors ? ", rig + IMU" : "");
  CreateDirectories(options.work_dir);
  const std::string colmap_dir = JoinPaths(options.work_dir, "colmap");
  Reconstruction full = ReconstructDataset(dataset, colmap_dir, options.sfm);
  full.Check(colmap_dir);

  EvalWork work;
  work.dataset = dataset.name;
  work.dataset_dir = options.dataset_dir;
  work.cameras = dataset.cameras;
  work.gravity_noise_deg = options.gravity_noise_deg;
  std::vector<std::string> unregistered;
  for (const std::string& name : dataset.images) {
    if (!FindImage(full, name)) unregistered.push_back(name);
  }
  work.reconstruction = {{"images", dataset.images.size()},
                         {"registered", full.images.size()},
                         {"points", full.points3D.size()},
                         {"unregistered", unregistered},
                         {"mean_track_length", full.MeanTrackLength()}};
  if (!unregistered.empty()) {
    LogProgress("[eval] warning: COLMAP did not register {} image(s): {}", unregistered.size(),
                fmt::format("{}", fmt::join(unregistered, " ")));
  }

  SetUnits(dataset, &full, &work);

  const std::map<std::string, Eigen::Vector3d> gravity_cam =
      GravityPerImage(dataset, full, options, &work);

  const ColmapDatabase database(JoinPaths(colmap_dir, "database.db"));
  std::map<std::string, uint32_t> db_id;
  for (const DatabaseImage& im : database.ReadImages()) db_id[im.name] = im.image_id;

  for (size_t gi = 0; gi < dataset.query_groups.size(); ++gi) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::vector<std::string>& names = dataset.query_groups[gi];
    EvalGroup group;
    group.name = GroupName(gi);
    group.map_dir = JoinPaths("groups", JoinPaths(group.name, "map"));
    const std::string group_dir = JoinPaths(options.work_dir, JoinPaths("groups", group.name));
    std::vector<std::string> registered;
    for (const std::string& n : names) {
      if (FindImage(full, n)) registered.push_back(n);
    }
    if (registered.empty()) {
      LogProgress("[eval] group {} ({}): no image registered, skipped", group.name,
                  fmt::join(names, " "));
      continue;
    }
    const Reconstruction map = MapWithoutImages(full, names);
    group.map_points = static_cast<int>(map.points3D.size());
    CreateDirectories(JoinPaths(options.work_dir, group.map_dir));
    WriteColmapModel(map, JoinPaths(options.work_dir, group.map_dir), ModelFormat::kBinary);
    std::map<std::string, const Image*> map_by_name;
    for (const auto& [id, im] : map.images) map_by_name[im.name] = &im;

    std::map<std::string, std::vector<uint32_t>> keypoint_of;  // per correspondence
    for (const std::string& name : registered) {
      group.images.push_back(IndirectCorrespondences(name, dataset, full, database, db_id,
                                                     map_by_name, gravity_cam, colmap_dir,
                                                     &keypoint_of[name]));
    }

    AttachLocalStructure(dataset, options, colmap_dir, group_dir, registered, keypoint_of, &group);
    int corr = 0, local_pts = 0;
    for (const EvalImage& im : group.images) {
      corr += static_cast<int>(im.correspondences.size());
      for (const auto& c : im.correspondences) local_pts += c.point_local.has_value();
    }
    LogProgress(
        "[eval] group {} ({}): map {} images / {} points, {} correspondences, {} with local "
        "points{} ({:.1f} s)",
        group.name, fmt::join(registered, " "), map.images.size(), map.points3D.size(), corr,
        local_pts, group.has_rig ? ", rig from " + group.rig_source : "",
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    work.groups.push_back(std::move(group));
  }
  if (work.groups.empty()) Fail("{}: no query group could be prepared", options.dataset_dir);
  const std::string out = JoinPaths(options.work_dir, "prepared.json");
  WriteFileAtomically(out, [&](std::ostream& o) { o << EvalWorkToJson(work).dump(1) << "\n"; });
  LogProgress("[eval] wrote {}", out);
  return work;
}

}  // namespace linecloud
