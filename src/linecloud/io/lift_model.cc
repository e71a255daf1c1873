#include "linecloud/io/lift_model.h"

#include "linecloud/lifting/sparsify.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iostream>

#include "linecloud/io/colmap_database.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

struct ResolvedKey {
  LiftingKey key;
  std::string path;
  std::string source;
};

// Refuses an output that would replace a key or an entry of the key store
// (`lift --out` naming the store's own .key file would lose the key).
void RefuseOutputInKeyStore(const LiftModelOptions& o, const KeyStore& store) {
  if (o.out_path.empty()) return;
  RefuseOutputOverInputs(o.out_path, {o.key_file, store.dir()}, "--out");
  std::error_code ec;
  const std::filesystem::path parent =
      std::filesystem::absolute(o.out_path, ec).lexically_normal().parent_path();
  if (!ec && std::filesystem::equivalent(parent, store.dir(), ec)) {
    Fail("--out {} is inside the key store {}: refusing to write maps among the keys", o.out_path,
         store.dir());
  }
}

ResolvedKey ResolveKey(const LiftModelOptions& o, const std::vector<uint64_t>& elements) {
  const KeyStore store(o.key_store.empty() ? KeyStore::DefaultDirectory() : o.key_store);
  RefuseOutputInKeyStore(o, store);
  // Find-or-create under one lock: two lifts of a new model started at once
  // must not create two keys.
  const KeyStore::Lock lock = store.LockExclusive();
  const std::optional<KeyStoreMatch> known = store.Find(elements, o.allow_shared_key);
  const DirectionSet directions = o.compact ? DirectionSet::kCompact256 : DirectionSet::kSphere;
  if (o.key_file.empty()) {
    if (known) return {known->key, known->key_path, "key store"};
    // Before the key store, the default key lived next to the output.
    const std::string legacy = o.out_path + ".key";
    if (!o.out_path.empty() && FileExists(legacy)) {
      const LiftingKey key = ReadKeyFile(legacy, o.allow_shared_key);
      store.Register(key, legacy, elements);
      return {key, legacy, "legacy key file"};
    }
    const KeyStoreMatch created = store.CreateKey(directions, elements);
    return {created.key, created.key_path, "new key in the key store"};
  }
  const bool create = !FileExists(o.key_file);
  if (create) WriteKeyFile(o.key_file, LiftingKey::Generate(directions));
  const LiftingKey key = ReadKeyFile(o.key_file, o.allow_shared_key);
  if (known && known->key.Fingerprint() != key.Fingerprint() && !o.force) {
    if (create) std::remove(o.key_file.c_str());
    Fail(
        "{}: this model was lifted before with the key {} (fingerprint {}); lifting it with {} "
        "too would reveal every point the two maps share (their lines intersect there). Use "
        "that key, or pass --force if nothing lifted with it was ever shared",
        o.model_dir, known->key_path, ToHex(known->key.Fingerprint()), o.key_file);
  }
  // --force: the new key replaces the old one for this model.
  if (known && known->key.Fingerprint() != key.Fingerprint())
    store.Retire(known->key.Fingerprint());
  store.Register(key, o.key_file, elements);
  return {key, o.key_file, create ? "new key file" : "key file"};
}

// Refuses to replace a map whose lines differ from the new ones: the old and
// new line of a point would intersect in the point.
void CheckExistingOutput(const LiftModelOptions& o, const LineCloud& cloud, const LiftingKey& key) {
  if (o.out_path.empty() || !FileExists(o.out_path) || o.force) return;
  LineCloud existing;
  try {
    existing = ReadLineCloud(o.out_path);
  } catch (const Error&) {
    Fail("{}: exists and is not a readable line cloud; remove it or pass --force", o.out_path);
  }
  if (existing.key_fingerprint != cloud.key_fingerprint) {
    Fail(
        "{}: was lifted with another key (fingerprint {}); lifting one model with two keys "
        "reveals its points by intersecting the lines. Lift with that map's key, or pass "
        "--force if the old file was never shared",
        o.out_path, ToHex(existing.key_fingerprint));
  }
  // The new cloud's ids are sorted: binary search. Version-1 files carry point ids.
  const std::vector<uint64_t> existing_ids =
      existing.keyed_line_ids ? existing.ids : LineIdsOfPoints(key, existing.ids);
  for (size_t i = 0; i < existing.size(); ++i) {
    const auto it = std::lower_bound(cloud.ids.begin(), cloud.ids.end(), existing_ids[i]);
    if (it == cloud.ids.end() || *it != existing_ids[i]) continue;
    if (existing.lines[i].v.cross(cloud.lines[it - cloud.ids.begin()].v).norm() > 1e-9) {
      Fail(
          "{}: holds other lines through the same points (an older {} lifting under this key); "
          "writing these too would reveal the points where the two lines cross. Keep the old "
          "file's encoding, or pass --force if it was never shared",
          o.out_path, LineEncodingName(existing.encoding));
    }
  }
}

}  // namespace

void LiftModelOptions::Check() const {
  if (model_dir.empty()) Fail("lift: no model folder given (--model)");
  if (!(sparsify >= 0 && sparsify < 1)) Fail("--sparsify: {} is not a share in [0, 1)", sparsify);
}

std::vector<uint64_t> ModelSketchElements(const Reconstruction& model) {
  std::vector<uint64_t> elements;
  for (const auto& [id, point] : model.points3D) {
    if (point.track.empty()) elements.push_back(SketchElement(id, ""));
    for (const TrackElement& t : point.track) {
      const auto im = model.images.find(t.image_id);
      elements.push_back(SketchElement(id, im == model.images.end() ? "" : im->second.name));
      // Names can change (a folder prefix) while the tracks stay.
      elements.push_back(SketchTrackElement(id, t.image_id, t.point2D_idx));
    }
  }
  return elements;
}

LiftingKey ModelKey(const Reconstruction& model, const std::string& model_name,
                    const std::string& key_file, const std::string& key_store) {
  if (!key_file.empty()) return ReadKeyFile(key_file);
  const KeyStore store(key_store.empty() ? KeyStore::DefaultDirectory() : key_store);
  const std::optional<KeyStoreMatch> known = store.Find(ModelSketchElements(model));
  if (!known) {
    Fail(
        "{}: the key store {} has no key for this model; lift it first (linecloud lift), or "
        "pass --key-file",
        model_name, store.dir());
  }
  return known->key;
}

LiftModelResult LiftModel(const LiftModelOptions& o) {
  o.Check();
  const auto start = std::chrono::steady_clock::now();
  const Reconstruction rec = ReadColmapModel(o.model_dir);
  const std::vector<uint64_t> ids = rec.SortedPoint3DIds();
  if (ids.empty()) Fail("{}: the model has no 3D points to lift", o.model_dir);

  PointDescriptors descriptors;
  if (!o.database.empty()) {
    const ColmapDatabase db(o.database);
    descriptors = ComputePointDescriptors(rec, ids, db, o.aggregation);
  }
  const ResolvedKey key = ResolveKey(o, ModelSketchElements(rec));

  std::vector<Eigen::Vector3d> points;
  points.reserve(ids.size());
  for (const uint64_t id : ids) points.push_back(rec.points3D.at(id).xyz);
  LiftingOptions lifting;
  lifting.encoding = o.compact ? LineEncoding::kCompact : LineEncoding::kPlucker;
  LiftModelResult result;
  // A sparse map holds a subset of the full map's lines (sparsify.h).
  std::vector<uint64_t> kept_ids;
  std::vector<Eigen::Vector3d> kept_points;
  for (const size_t i : SparsifyPoints(key.key, ids, points, o.sparsify, o.sparsify_mode)) {
    kept_ids.push_back(ids[i]);
    kept_points.push_back(points[i]);
  }
  if (o.select_points) {
    std::vector<uint64_t> selected_ids;
    std::vector<Eigen::Vector3d> selected_points;
    for (const size_t k : o.select_points(key.key, kept_ids, kept_points)) {
      selected_ids.push_back(kept_ids.at(k));
      selected_points.push_back(kept_points.at(k));
    }
    kept_ids.swap(selected_ids);
    kept_points.swap(selected_points);
  }
  result.cloud = LiftPoints(kept_ids, kept_points, key.key, lifting);
  if (descriptors.dim > 0) {
    // Descriptors follow the lines' (line-id) order; `ids` (their rows) is sorted.
    LineCloud& c = result.cloud;
    const std::vector<uint64_t> point_ids = PointIdsOfLines(key.key, c.ids);
    c.descriptor_dim = descriptors.dim;
    c.descriptors.resize(c.size() * descriptors.dim);
    for (size_t k = 0; k < c.size(); ++k) {
      const size_t row = std::lower_bound(ids.begin(), ids.end(), point_ids[k]) - ids.begin();
      std::copy_n(descriptors.data.data() + row * descriptors.dim, descriptors.dim,
                  c.descriptors.data() + k * descriptors.dim);
    }
    c.descriptor_type = "colmap-sift-uint8";
    c.descriptor_aggregation = DescriptorAggregationName(o.aggregation);
  }
  if (o.gravity) {
    if (!o.gravity->allFinite() || !(o.gravity->norm() > 0)) {
      Fail("--gravity must be a non-zero direction x,y,z");
    }
    result.cloud.gravity = o.gravity->normalized();
  }
  CheckExistingOutput(o, result.cloud, key.key);
  if (!o.out_path.empty()) WriteLineCloud(result.cloud, o.out_path);
  result.num_points = ids.size();
  result.key_path = key.path;
  result.key_source = key.source;
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace linecloud
