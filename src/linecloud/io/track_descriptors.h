// One descriptor per map point, from the COLMAP database: each point's track
// lists (image, keypoint) observations, each with a SIFT descriptor.
//
// Aggregation (`medoid`, the default): the observed descriptor with the
// smallest summed L2 distance to the others in the track. It is a descriptor
// that was actually observed (so it matches the way query descriptors do and
// keeps SIFT's normalisation), and unlike the mean it is not pulled by
// outliers in the track. `mean` (rounded element-wise mean) is offered for
// comparison; it blurs the descriptor of long tracks spanning wide viewpoint
// changes.
#pragma once

#include <string>
#include <vector>

#include "linecloud/io/colmap_database.h"
#include "linecloud/io/colmap_model.h"

namespace linecloud {

enum class DescriptorAggregation { kMedoid, kMean };
DescriptorAggregation DescriptorAggregationFromName(const std::string& name);
const char* DescriptorAggregationName(DescriptorAggregation aggregation);

struct PointDescriptors {
  int dim = 0;
  std::vector<uint8_t> data;  // point_ids.size() x dim, row-major
};

// Descriptors for `point_ids` (in that order). Images are matched between the
// model and the database by name. Throws Error naming the database when an
// image or keypoint of a track is missing there (a database of another run).
PointDescriptors ComputePointDescriptors(const Reconstruction& reconstruction,
                                         const std::vector<uint64_t>& point_ids,
                                         const ColmapDatabase& database,
                                         DescriptorAggregation aggregation);

}  // namespace linecloud
