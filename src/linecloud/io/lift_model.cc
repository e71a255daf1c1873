#include "linecloud/io/lift_model.h"
#include "linecloud/geometry/line_grid.h"

#include <fmt/format.h>

#include "linecloud/lifting/sparsify.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <unordered_map>

#include "linecloud/io/colmap_database.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/lifting/release_ledger.h"
#include "linecloud/util/error.h"
#include "linecloud/util/log.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

struct ResolvedKey {
  LiftingKey key;
  std::string path;
  std::string source;
  bool create = false;  // the key file is still to be written
  std::optional<LiftingKey::Id> retire;
  // The store's entry of this key was written with a release ledger.
  bool registered_with_ledger = false;
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

// The key of this lifting, found or (only in memory) made; `create` /
// `create_file` say what Persist must still write.
ResolvedKey ResolveKey(const LiftModelOptions& o, const KeyStore& store,
                       const std::vector<uint64_t>& elements, const std::string& key_file) {
  const std::optional<KeyStoreMatch> known = store.Find(elements, o.allow_shared_key);
  const DirectionSet directions = o.compact ? DirectionSet::kCompact256 : DirectionSet::kSphere;
  if (key_file.empty()) {
    if (known) {
      return {known->key, known->key_path, "key store", false, std::nullopt, known->with_ledger};
    }
    // Before the key store, the default key lived next to the output.
    const std::string legacy = o.out_path + ".key";
    if (!o.out_path.empty() && FileExists(legacy)) {
      return {ReadKeyFile(legacy, o.allow_shared_key),
              legacy,
              "legacy key file",
              false,
              std::nullopt,
              false};
    }
    const LiftingKey key = LiftingKey::Generate(directions);
    return {key,
            JoinPaths(store.dir(), ToHex(key.Fingerprint()) + ".key"),
            "new key in the key store",
            true,
            std::nullopt,
            false};
  }
  const bool create = !FileExists(key_file);
  // A new key file is the user's own: never one written into the key store.
  if (create) CheckNotProtected(key_file);
  const LiftingKey key =
      create ? LiftingKey::Generate(directions) : ReadKeyFile(key_file, o.allow_shared_key);
  if (known && known->key.Fingerprint() != key.Fingerprint() && !o.force) {
    Fail(
        "{}: this model was lifted before with the key {} (fingerprint {}); lifting it with {} "
        "too would reveal every point the two maps share (their lines intersect there). Use "
        "that key, or pass --force if nothing lifted with it was ever shared",
        o.model_dir, known->key_path, ToHex(known->key.Fingerprint()), key_file);
  }
  ResolvedKey r{key,
                key_file,
                create ? "new key file" : "key file",
                create,
                std::nullopt,
                known && known->key.Fingerprint() == key.Fingerprint() && known->with_ledger};
  if (known && known->key.Fingerprint() != key.Fingerprint()) r.retire = known->key.Fingerprint();
  return r;
}

// After every check passed: the new key written, the model registered.
void PersistKey(const KeyStore& store, const ResolvedKey& key,
                const std::vector<uint64_t>& elements) {
  const ProtectedWriteScope writing_the_store;
  if (key.create) WriteKeyFile(key.path, key.key);
  // --force: the new key replaces the old one for this model.
  if (key.retire) store.Retire(*key.retire);
  store.Register(key.key, key.path, elements);
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

std::vector<uint64_t> ModelSketchElements(const Reconstruction& model, uint64_t salt) {
  // SplitMix64's finaliser of an element and the salt: a project's names and
  // track indices are its own (another survey's 0000.jpg is another photo).
  const auto salted = [salt](uint64_t e) {
    if (salt == 0) return e;
    uint64_t z = e ^ (salt * 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  };
  std::vector<uint64_t> elements;
  for (const auto& [id, point] : model.points3D) {
    if (point.track.empty()) elements.push_back(salted(SketchElement(id, "")));
    for (const TrackElement& t : point.track) {
      const auto im = model.images.find(t.image_id);
      const std::string_view name =
          im == model.images.end() ? std::string_view{} : std::string_view{im->second.name};
      elements.push_back(salted(SketchElement(id, name)));
      // Names can change (a folder prefix) while the tracks stay.
      elements.push_back(salted(SketchTrackElement(id, t.image_id, t.point2D_idx)));
      // Point ids and image names change (re-triangulation, a mapper re-run,
      // renumbering, renaming) while the features stay: never salted, so the
      // same photos' features find one key whichever project or lift has them.
      if (im != model.images.end() && t.point2D_idx < im->second.points2D.size()) {
        elements.push_back(
            SketchObservationElement(t.point2D_idx, im->second.points2D[t.point2D_idx].xy));
      }
    }
  }
  return elements;
}

IdentityInputData MakeIdentityInput(const Reconstruction& model, const LiftingKey& key,
                                    std::span<const uint64_t> ids) {
  const ObservationHasher hasher(key);
  IdentityInputData d;
  // An image is found again by its features (renamed, renumbered) or by its
  // file name (a folder prefix added or removed).
  std::unordered_map<uint32_t, uint64_t> features_hash;
  std::vector<Eigen::Vector2d> keypoints;
  for (const auto& [image_id, image] : model.images) {
    const std::string name = std::filesystem::path(image.name).filename().string();
    keypoints.clear();
    for (size_t k = 0; k < std::min<size_t>(image.points2D.size(), 16); ++k) {
      keypoints.push_back(image.points2D[k].xy);
    }
    const uint64_t features = hasher.ImageFeatures(name, image.points2D.size(), keypoints);
    features_hash[image_id] = features;
    d.images.push_back({features, image.cam_from_world.Center()});
    d.images.push_back({hasher.Image(name), image.cam_from_world.Center()});
  }
  d.points.reserve(ids.size());
  d.observation_start.reserve(ids.size() + 1);
  for (const uint64_t id : ids) {
    const Point3D& p = model.points3D.at(id);
    d.points.push_back(p.xyz);
    d.observation_start.push_back(static_cast<uint32_t>(d.observations.size()));
    for (const TrackElement& t : p.track) {
      const auto h = features_hash.find(t.image_id);
      if (h != features_hash.end()) {
        d.observations.push_back(hasher.Observation(h->second, t.point2D_idx));
      }
    }
  }
  if (d.observations.size() >= (size_t{1} << 32)) Fail("lift: too many observations");
  d.observation_start.push_back(static_cast<uint32_t>(d.observations.size()));
  d.input.ids = ids;
  d.input.points = d.points;
  d.input.observation_start = d.observation_start;
  d.input.observations = d.observations;
  d.input.images = d.images;
  return d;
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

namespace {

// A model in geographic coordinates (UTM, ECEF: far from the origin for its
// size) or whose photos carry GPS: another owner's map of the place is then
// in (nearly) the same frame, or easily put there.
std::string GeoreferencedBecause(std::span<const Eigen::Vector3d> points, size_t gps_images) {
  std::vector<std::string> why;
  if (gps_images > 0) why.push_back(fmt::format("{} of its photos carry GPS", gps_images));
  if (!points.empty()) {
    const Eigen::AlignedBox3d box = RobustBox(points, 0.005, 0.0);
    const double size = box.diagonal().norm();
    const double distance = box.center().norm();
    if (distance > 1000 && distance > 100 * size) {
      why.push_back(fmt::format(
          "its coordinates look geographic: its centre lies {:.0f} units from the origin, "
          "{:.0f} times its size",
          distance, distance / std::max(size, 1e-300)));
    }
  }
  std::string out;
  for (const std::string& w : why) out += (out.empty() ? "" : "; ") + w;
  return out;
}

}  // namespace

LiftModelResult LiftModel(const LiftModelOptions& o) {
  o.Check();
  const auto start = std::chrono::steady_clock::now();
  const Reconstruction rec = ReadColmapModel(o.model_dir);
  const std::vector<uint64_t> ids = rec.SortedPoint3DIds();
  if (ids.empty()) Fail("{}: the model has no 3D points to lift", o.model_dir);

  PointDescriptors descriptors;
  size_t gps_images = 0;
  if (!o.database.empty()) {
    const ColmapDatabase db(o.database);
    descriptors = ComputePointDescriptors(rec, ids, db, o.aggregation);
    gps_images = db.ImagesWithPositionPriors();
  }
  const KeyStore store(o.key_store.empty() ? KeyStore::DefaultDirectory() : o.key_store);
  RefuseOutputInKeyStore(o, store);
  // The whole lift under one lock of the store: two lifts of one model must
  // neither make two keys nor release two lines of one point.
  const KeyStore::Lock lock = store.LockExclusive();
  const std::vector<uint64_t> elements = ModelSketchElements(rec, o.identity_salt);
  const ResolvedKey key = ResolveKey(o, store, elements, o.key_file);

  // One physical point, one line (identity.h): directions from the key's
  // release ledger.
  const std::string ledger_path = LedgerPath(store.dir(), key.key.Fingerprint());
  const bool has_ledger = FileExists(ledger_path);
  if (!has_ledger && key.registered_with_ledger) {
    Fail(
        "{}: the release ledger of this model's key is missing; restore it from a backup. "
        "Without it the points of this version could get lines crossing the released ones",
        ledger_path);
  }
  ReleaseLedger ledger = ReadLedger(ledger_path);
  IdentityInputData identity_input = MakeIdentityInput(rec, key.key, ids);
  if (descriptors.dim > 0) {
    const DescriptorSketcher sketcher(key.key, descriptors.dim);
    identity_input.sketches.resize(ids.size());
    for (size_t i = 0; i < ids.size(); ++i) {
      identity_input.sketches[i] = sketcher.Sketch(
          std::span<const uint8_t>(descriptors.data.data() + i * descriptors.dim, descriptors.dim));
    }
    identity_input.input.sketches = identity_input.sketches;
  }
  LiftModelResult result;
  IdentityOptions identity_options = o.identity;
  // A key that released maps before ledgers existed: its lines are the keyed
  // directions of the point ids, kept as they are.
  identity_options.legacy_release = !key.create && !has_ledger;
  result.identity = AssignDirections(key.key, identity_input.input, ledger, identity_options);
  const IdentityResult& identity = result.identity;

  std::vector<uint64_t> kept_ids;
  std::vector<Eigen::Vector3d> kept_points;
  std::vector<size_t> kept_rows;  // rows of `ids`
  // A sparse map holds a subset of the full map's lines (sparsify.h).
  for (const size_t i :
       SparsifyPoints(key.key, ids, identity_input.points, o.sparsify, o.sparsify_mode)) {
    if (!identity.keep[i]) continue;
    kept_ids.push_back(ids[i]);
    // On its released line when it kept one (identity.h).
    kept_points.push_back(identity.anchors[i]);
    kept_rows.push_back(i);
  }
  if (o.select_points) {
    std::vector<uint64_t> selected_ids;
    std::vector<Eigen::Vector3d> selected_points;
    std::vector<size_t> selected_rows;
    for (const size_t k : o.select_points(key.key, kept_ids, kept_points)) {
      selected_ids.push_back(kept_ids.at(k));
      selected_points.push_back(kept_points.at(k));
      selected_rows.push_back(kept_rows.at(k));
    }
    kept_ids.swap(selected_ids);
    kept_points.swap(selected_points);
    kept_rows.swap(selected_rows);
  }
  std::vector<Eigen::Vector3d> directions;
  std::vector<uint8_t> compact;
  for (const size_t i : kept_rows) {
    directions.push_back(identity.directions[i]);
    compact.push_back(identity.compact[i]);
  }
  LiftingOptions lifting;
  lifting.encoding = o.compact ? LineEncoding::kCompact : LineEncoding::kPlucker;
  result.cloud = LiftPoints(kept_ids, kept_points, key.key, lifting, directions, compact);
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
  // Every check passed: the key, the model's registration and the ledger
  // (before the map: a release recorded but never written is harmless, a map
  // written but not recorded is not), then the map.
  PersistKey(store, key, elements);
  if (RecordRelease(identity_input.input, identity, kept_rows, &ledger) || !has_ledger) {
    const ProtectedWriteScope writing_the_store;
    WriteLedger(ledger_path, ledger);
  }
  if (!o.out_path.empty()) WriteLineCloud(result.cloud, o.out_path);
  result.num_points = ids.size();
  result.key_path = key.path;
  result.key_source = key.source;
  result.key_store = store.dir();
  result.georeferenced = GeoreferencedBecause(identity_input.points, gps_images);
  if (key.create && !result.georeferenced.empty()) {
    // [rebuild] Two stores, one place: nothing ties the two keys together.
    LogWarning(
        "this model is georeferenced: {}. Another map of this place released under another "
        "key (another machine, another owner, another store) gives its points back once the "
        "two are aligned, and georeferenced maps come nearly aligned. Release every map of a "
        "place from one key store (linecloud keys export / import moves it to another "
        "machine); `linecloud audit --other` measures two maps together",
        result.georeferenced);
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace linecloud
