#include "linecloud/io/track_descriptors.h"

#include <cmath>
#include <limits>
#include <unordered_map>

#include "linecloud/util/error.h"

namespace linecloud {
namespace {

constexpr size_t kMaxMedoidTrack = 64;

}  // namespace

DescriptorAggregation DescriptorAggregationFromName(const std::string& name) {
  if (name == "medoid") return DescriptorAggregation::kMedoid;
  if (name == "mean") return DescriptorAggregation::kMean;
  Fail("unknown descriptor aggregation '{}' (expected medoid or mean)", name);
}

const char* DescriptorAggregationName(DescriptorAggregation aggregation) {
  return aggregation == DescriptorAggregation::kMedoid ? "medoid" : "mean";
}

PointDescriptors ComputePointDescriptors(const Reconstruction& rec,
                                         const std::vector<uint64_t>& point_ids,
                                         const ColmapDatabase& db,
                                         DescriptorAggregation aggregation) {
  std::unordered_map<std::string, uint32_t> db_id_by_name;
  for (const DatabaseImage& im : db.ReadImages()) db_id_by_name[im.name] = im.image_id;

  // Descriptors of every model image, loaded once.
  std::unordered_map<uint32_t, FeatureDescriptors> descriptors;
  int dim = -1;
  for (const auto& [image_id, image] : rec.images) {
    const auto it = db_id_by_name.find(image.name);
    if (it == db_id_by_name.end()) {
      Fail("{}: image '{}' of the model is not in the database", db.path(), image.name);
    }
    FeatureDescriptors d = db.ReadDescriptors(it->second);
    if (d.rows() > 0) {
      if (dim >= 0 && d.cols() != dim) {
        Fail("{}: descriptors of image '{}' have {} dimensions, others {}", db.path(), image.name,
             d.cols(), dim);
      }
      dim = static_cast<int>(d.cols());
    }
    descriptors.emplace(image_id, std::move(d));
  }
  if (dim <= 0) Fail("{}: the database holds no descriptors for the model's images", db.path());

  PointDescriptors out;
  out.dim = dim;
  out.data.resize(point_ids.size() * dim);
  std::vector<const uint8_t*> track;
  std::vector<double> sum_dist;
  for (size_t k = 0; k < point_ids.size(); ++k) {
    const Point3D& point = rec.points3D.at(point_ids[k]);
    track.clear();
    for (const TrackElement& el : point.track) {
      const FeatureDescriptors& d = descriptors.at(el.image_id);
      if (el.point2D_idx >= d.rows()) {
        Fail(
            "{}: image '{}' has {} descriptors but point3D {} observes "
            "keypoint {}; is this the database the model was built from?",
            db.path(), rec.images.at(el.image_id).name, d.rows(), point_ids[k], el.point2D_idx);
      }
      track.push_back(d.row(el.point2D_idx).data());
    }
    uint8_t* dst = out.data.data() + k * dim;
    if (track.empty()) {
      Fail("point3D {} has an empty track: no descriptor can be attached", point_ids[k]);
    }
    if (aggregation == DescriptorAggregation::kMean) {
      for (int c = 0; c < dim; ++c) {
        double sum = 0;
        for (const uint8_t* t : track) sum += t[c];
        dst[c] = static_cast<uint8_t>(std::lround(sum / track.size()));
      }
      continue;
    }
    // Bounded work on hostile input: the medoid is quadratic in the track's
    // length, so a long track (a 20 000-long one took 18 s) is represented by
    // kMaxMedoidTrack of its observations, evenly spaced along it.
    if (track.size() > kMaxMedoidTrack) {
      std::vector<const uint8_t*> sample;
      for (size_t m = 0; m < kMaxMedoidTrack; ++m)
        sample.push_back(track[m * track.size() / kMaxMedoidTrack]);
      track.swap(sample);
    }
    sum_dist.assign(track.size(), 0.0);
    for (size_t a = 0; a < track.size(); ++a) {
      for (size_t b = a + 1; b < track.size(); ++b) {
        int64_t sq = 0;
        for (int c = 0; c < dim; ++c) {
          const int diff = int{track[a][c]} - int{track[b][c]};
          sq += diff * diff;
        }
        const double dist = std::sqrt(static_cast<double>(sq));
        sum_dist[a] += dist;
        sum_dist[b] += dist;
      }
    }
    size_t best = 0;
    for (size_t a = 1; a < track.size(); ++a) {
      if (sum_dist[a] < sum_dist[best]) best = a;
    }
    std::copy(track[best], track[best] + dim, dst);
  }
  return out;
}

}  // namespace linecloud
