// The maps a server holds: DIR/ID.lcm (+ the owner's ID.json and
// ID.audit.json), each loaded once into a Localizer, swapped as a whole on
// reload (SIGHUP) while requests in flight keep the set they started with.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "linecloud/pipeline/localizer.h"
#include "linecloud/io/geo.h"
#include "linecloud/serve/metrics.h"

namespace linecloud {

// Map ids: [A-Za-z0-9_-]{1,64} (no std::regex: its GCC 12 code warns).
bool IsMapId(const std::string& id);

struct LoadedMap {
  std::string id;
  std::unique_ptr<Localizer> localizer;
  nlohmann::json info;  // GET /v1/maps
  nlohmann::json
      details;  // GET /v1/maps/{id}: what `linecloud info --json` says, and the geo-anchor
  // GET /v1/maps/{id}/segments: every line clipped to the box of the lines'
  // anchors, x0 y0 z0 x1 y1 z1 as float32, in a fixed pseudo-random order (a
  // prefix is a uniform subset). What the .lcm holds, nothing more.
  std::vector<float> segments;
  std::optional<GeoAnchor> anchor;
  // The owner published the lines (DIR/ID.json "publish_lines": true):
  // reader tokens get /segments too. Never a default: a line cloud
  // downloaded whole gives back most of its points to the density attack.
  bool publish_lines = false;
  // Size and mtime of ID.lcm, ID.json and ID.audit.json: a map whose files
  // are unchanged is kept on reload.
  std::vector<std::pair<uintmax_t, int64_t>> stamp;
};
using MapSet = std::map<std::string, std::shared_ptr<const LoadedMap>>;

class MapRegistry {
 public:
  // `log` takes notices (JSON lines); load errors are counted in `metrics`.
  // `defaults`: every map's Localizer options, before its ID.json "options".
  MapRegistry(std::string maps_dir, LocalizerOptions defaults,
              std::function<void(const std::string&)> log, Metrics* metrics)
      : maps_dir_(std::move(maps_dir)),
        defaults_(std::move(defaults)),
        log_(std::move(log)),
        metrics_(metrics) {}

  std::shared_ptr<const MapSet> Maps() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return maps_;
  }
  // Reads the folder: new maps in, removed out, changed reloaded (unchanged
  // files kept). Throws Error when the folder is not one; a map that does not
  // load is logged and counted, its last version kept.
  void Load();
  // Load() for a reload (SIGHUP): nothing stops the service — a folder that
  // is gone or unreadable keeps every map; logged and counted
  // (linecloud_map_load_errors_total).
  void Reload();

 private:
  std::shared_ptr<const LoadedMap> LoadMap(const std::string& id, const std::string& path) const;
  void Log(const std::string& line) const { log_(line); }

  const std::string maps_dir_;
  const LocalizerOptions defaults_;
  const std::function<void(const std::string&)> log_;
  Metrics* const metrics_;
  mutable std::mutex mutex_;
  std::shared_ptr<const MapSet> maps_ = std::make_shared<MapSet>();
};

}  // namespace linecloud
