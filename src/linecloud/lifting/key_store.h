// The per-user key store: the default lifting key belongs to the *model*, not
// to an output path. A model is recognised by its sketch — hashes of its
// (point id, observing image) pairs — so a second `lift` of the same model,
// of a re-optimised copy, or of a subset of its points (another output path,
// encoding or run) finds the key of the first and puts no second line through
// any point. The sketch holds no coordinates: a store that leaks gives an
// attacker no position, only which images saw which point id.
//
// Layout: DIR (mode 0700) holds, per registered key, FINGERPRINT.model (the
// sketch and the path of the key file) and, for keys the store created,
// FINGERPRINT.key (mode 0600).
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "linecloud/lifting/key.h"

namespace linecloud {

// Hash of one (point id, image name) pair of a model's tracks.
uint64_t SketchElement(uint64_t point_id, std::string_view image_name);

struct KeyStoreMatch {
  std::string key_path;
  LiftingKey key;
  size_t shared = 0;      // sketch elements the model shares with the entry
  size_t comparable = 0;  // of the model's elements the entry could hold
};

class KeyStore {
 public:
  // Opens (creating with mode 0700) the store at `dir`; refuses a directory
  // that others can read or write.
  explicit KeyStore(std::string dir);

  // $LINECLOUD_KEY_STORE, else $XDG_DATA_HOME/linecloud/keys, else
  // $HOME/.local/share/linecloud/keys.
  static std::string DefaultDirectory();

  const std::string& dir() const { return dir_; }

  // The registered key of a model sharing at least 3 elements and 5 % of the
  // comparable ones with `elements` (the entry sharing most), or nothing.
  // Throws Error when the matching entry's key file is gone or unreadable.
  std::optional<KeyStoreMatch> Find(std::span<const uint64_t> elements,
                                    bool allow_shared_key = false) const;

  // Records `key` (kept at `key_path`) as the key of the model of `elements`.
  void Register(const LiftingKey& key, const std::string& key_path,
                std::span<const uint64_t> elements) const;

  // A new key for the model of `elements`, written into the store and registered.
  KeyStoreMatch CreateKey(DirectionSet directions, std::span<const uint64_t> elements) const;

 private:
  std::string dir_;
};

}  // namespace linecloud
