// `linecloud lift` as a library call: a COLMAP model (and optionally its
// database) to a line-cloud file, under the model's one key.
//
// The key: `key_file` when given (created there, mode 0600, if it does not
// exist yet), otherwise the key store's key of the model (key_store.h),
// created on the model's first lifting. Refused, with an error naming the
// files: a key other than the one the store knows for this model; replacing
// an output lifted with another key, or whose lines differ from the new ones
// (e.g. a version-1 compact map); the compact encoding under a sphere key.
#pragma once

#include <functional>
#include <optional>
#include <span>
#include <string>

#include <Eigen/Core>

#include "linecloud/io/track_descriptors.h"
#include "linecloud/lifting/identity.h"
#include "linecloud/lifting/key_store.h"
#include "linecloud/lifting/line_cloud.h"
#include "linecloud/lifting/sparsify.h"

namespace linecloud {

struct LiftModelOptions {
  std::string model_dir;
  std::string out_path;   // empty: the cloud is returned, not written
  std::string key_file;   // empty: the key store's key of the model
  std::string key_store;  // empty: KeyStore::DefaultDirectory()
  std::string database;   // empty: no descriptors
  DescriptorAggregation aggregation = DescriptorAggregation::kMedoid;
  bool compact = false;
  bool force = false;                      // replace an output lifted with another key
  bool allow_shared_key = false;           // accept a key file others can read
  std::optional<Eigen::Vector3d> gravity;  // the model frame's gravity direction
  double sparsify = 0;                     // share of the points dropped (sparsify.h)
  SparsifyMode sparsify_mode = SparsifyMode::kUniform;
  IdentityOptions identity;  // how a point keeps its line across versions
  // A project's own identity (`linecloud map`): the model's names and point
  // ids are known to the key store mixed with this (0: the model alone), so
  // another project with the same photo names or point ids is never taken for
  // it; the same photos' features still find its key.
  uint64_t identity_salt = 0;
  // Optional further selection after sparsifying (e.g. privacy/resist.h):
  // indices into (ids, points) of the points to keep.
  std::function<std::vector<size_t>(const LiftingKey&, std::span<const uint64_t>,
                                    std::span<const Eigen::Vector3d>)>
      select_points;

  void Check() const;
};

struct LiftModelResult {
  LineCloud cloud;
  size_t num_points = 0;
  std::string key_path;
  // "new key in the key store", "key store", "new key file", "key file",
  // or "legacy key file" (OUT.key from before the key store).
  std::string key_source;
  std::string key_store;  // the store holding the key's registration and ledger
  // Why another release of this place would be easy to align with this one
  // (empty when nothing says so): geographic coordinates, photos with GPS.
  std::string georeferenced;
  IdentityResult identity;  // where each point's direction came from
  double seconds = 0;
};

// The sketch elements of a model: per observation of a point, hashes of
// (point id, image name), (point id, image id, keypoint) and (image name,
// keypoint) — the last survives renumbered points. `salt` != 0: the first
// two kinds mixed with it (a project's own identity: names and point ids
// alone never make two projects one); the photos' features stay comparable.
std::vector<uint64_t> ModelSketchElements(const Reconstruction& model, uint64_t salt = 0);

// A model's points `ids` (sorted) as the identity rule sees them: positions,
// keyed observation hashes, image centres (identity.h).
struct IdentityInputData {
  std::vector<Eigen::Vector3d> points;
  std::vector<uint32_t> observation_start;
  std::vector<uint64_t> observations;
  std::vector<std::pair<uint64_t, Eigen::Vector3d>> images;
  std::vector<uint64_t> sketches;  // descriptor sketches, when the lift has descriptors
  IdentityInput input;             // views of the above
  IdentityInputData() = default;
  IdentityInputData(const IdentityInputData&) = delete;
  IdentityInputData(IdentityInputData&&) = default;
};
IdentityInputData MakeIdentityInput(const Reconstruction& model, const LiftingKey& key,
                                    std::span<const uint64_t> ids);

LiftModelResult LiftModel(const LiftModelOptions& options);

// The key of a model that was lifted before: `key_file` when given, else the
// key store's (empty `key_store`: the default store). Throws Error naming the
// model when the store does not know it.
LiftingKey ModelKey(const Reconstruction& model, const std::string& model_name,
                    const std::string& key_file, const std::string& key_store);

}  // namespace linecloud
