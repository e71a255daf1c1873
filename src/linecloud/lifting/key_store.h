// The per-user key store: the default lifting key belongs to the *model*, not
// to an output path. A model is recognised by its sketch — hashes of its
// (point id, observing image) pairs — so a second `lift` of the same model,
// of a re-optimised copy, or of a subset of its points (another output path,
// encoding or run) finds the key of the first and puts no second line through
// any point. The sketch holds no coordinates: a store that leaks gives an
// attacker no position, only which images saw which point id.
//
// Elements come from both the image names and the track indices (image id,
// keypoint index) of each observation, so that renaming a model's images
// (e.g. a folder prefix) or re-numbering them leaves it recognisable.
//
// Layout: DIR (mode 0700, owned by the user, not a link; its parents are
// created 0700) holds, per registered key, FINGERPRINT.model (the sketch and
// the path of the key file), for keys the store created FINGERPRINT.key (mode
// 0600), and `.lock`: find-or-create runs under an exclusive flock of it, so
// two processes lifting one new model at once get one key, not two.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "linecloud/lifting/key.h"

namespace linecloud {

// Hash of one (point id, image name) pair of a model's tracks.
uint64_t SketchElement(uint64_t point_id, std::string_view image_name);
// Hash of one observation by what its image's features say — (keypoint index,
// its position rounded to whole pixels) — whatever the point's id or the
// image's name: a version renumbered, renamed or re-triangulated from the
// same features keeps these.
uint64_t SketchObservationElement(uint32_t point2D_idx, const Eigen::Vector2d& xy);
// Hash of one (point id, image id, keypoint index) track element.
uint64_t SketchTrackElement(uint64_t point_id, uint32_t image_id, uint32_t point2D_idx);

struct KeyStoreMatch {
  std::string key_path;
  LiftingKey key;
  size_t shared = 0;      // sketch elements the model shares with the entry
  size_t comparable = 0;  // of the model's elements the entry could hold
  // The entry was registered with a release ledger (identity.h); false for
  // entries of linecloud before ledgers, whose lines are the keyed
  // directions of the point ids.
  bool with_ledger = true;
};

class KeyStore {
 public:
  // Opens (creating it and its missing parents with mode 0700) the store at
  // `dir`; refuses a symbolic link, a directory owned by another user, and one
  // that others can read or write.
  explicit KeyStore(std::string dir);

  // An exclusive lock of the whole store (flock on DIR/.lock), released when
  // destroyed. Hold it across Find + CreateKey / Register.
  class Lock {
   public:
    explicit Lock(const std::string& dir);
    ~Lock();
    Lock(const Lock&) = delete;
    Lock& operator=(const Lock&) = delete;

   private:
    int fd_ = -1;
  };
  Lock LockExclusive() const { return Lock(dir_); }

  // $LINECLOUD_KEY_STORE, else $XDG_DATA_HOME/linecloud/keys, else
  // $HOME/.local/share/linecloud/keys.
  static std::string DefaultDirectory();

  const std::string& dir() const { return dir_; }

  // The registered key of a model sharing at least 3 elements and 5 % of the
  // comparable ones with `elements`, or nothing. Throws Error when entries of
  // two different keys match (naming both: one of the two keys must go), when
  // the matching entry's key file is gone or unreadable, or when its key no
  // longer has the fingerprint it was registered under (the file was edited).
  // An unreadable entry is skipped with a warning on standard error naming it.
  std::optional<KeyStoreMatch> Find(std::span<const uint64_t> elements,
                                    bool allow_shared_key = false) const;

  // A 32-byte secret of this store's user (DIR/cache.secret, 0600, created
  // on first use) that authenticates caches the user writes, e.g. a map's
  // descriptor index: a cache someone else planted is never parsed.
  std::array<uint8_t, 32> CacheSecret() const;

  // Retires the registration of `fingerprint` (renamed FINGERPRINT.model.retired;
  // the key file stays): for `lift --force`, whose new key replaces the old one.
  void Retire(const LiftingKey::Id& fingerprint) const;

  // Records `key` (kept at `key_path`) as the key of the model of `elements`.
  void Register(const LiftingKey& key, const std::string& key_path,
                std::span<const uint64_t> elements) const;

  // One place, one key, on every machine (issue [rebuild]): the entry of
  // `fingerprint` — its key, the model's registration, its release ledger —
  // as one bundle file (mode 0600, as secret as the key).
  void ExportEntry(const LiftingKey::Id& fingerprint, const std::string& bundle) const;
  // Installs a bundle's entry in this store (the key as FINGERPRINT.key).
  // Refuses a bundle whose model has another key here, and a ledger that
  // differs from the one here unless `replace_ledger`. Hold the lock.
  // Returns what it installed.
  std::string ImportEntry(const std::string& bundle, bool replace_ledger) const;

 private:
  std::string dir_;
};

}  // namespace linecloud
