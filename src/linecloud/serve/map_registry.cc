#include "linecloud/serve/map_registry.h"

#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <numeric>
#include <random>

#include <fmt/format.h>

#include "linecloud/geometry/plucker.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/io/line_cloud_info.h"
#include "linecloud/io/ply.h"
#include "linecloud/pipeline/localizer_option_table.h"
#include "linecloud/serve/wire.h"
#include "linecloud/io/json_util.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {

namespace fs = std::filesystem;
using json = nlohmann::json;

// Map ids: [A-Za-z0-9_-]{1,64} (no std::regex: its GCC 12 code warns).
bool IsMapId(const std::string& id) {
  if (id.empty() || id.size() > 64) return false;
  return std::all_of(id.begin(), id.end(),
                     [](unsigned char c) { return std::isalnum(c) != 0 || c == '_' || c == '-'; });
}

namespace {

std::pair<uintmax_t, int64_t> FileStamp(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return {0, 0};
  return {static_cast<uintmax_t>(st.st_size),
          static_cast<int64_t>(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec};
}

// LoadedMap::stamp of the map file DIR/ID.lcm.
std::vector<std::pair<uintmax_t, int64_t>> MapStamp(const std::string& lcm_path) {
  const std::string base = lcm_path.substr(0, lcm_path.size() - 4);  // without ".lcm"
  return {FileStamp(lcm_path), FileStamp(base + ".json"), FileStamp(base + ".audit.json")};
}

// The segments of LoadedMap::segments.
std::vector<float> MapSegments(const LineCloud& cloud) {
  Eigen::Vector3d min, max;
  AnchorBoundingBox(cloud, &min, &max);
  std::vector<size_t> order(cloud.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::shuffle(order.begin(), order.end(), std::mt19937_64(20261125));
  std::vector<float> out;
  out.reserve(6 * order.size());
  for (const size_t i : order) {
    Eigen::Vector3d a, b;
    if (!ClipToBox(cloud.lines[i], min, max, &a, &b)) a = b = cloud.lines[i].Anchor();
    for (const Eigen::Vector3d& p : {a, b}) {
      for (int k = 0; k < 3; ++k) out.push_back(static_cast<float>(p[k]));
    }
  }
  return out;
}

// A map's options: the server's defaults with the owner's "options" of
// DIR/ID.json (any option of the table but the two the server sets itself).
LocalizerOptions MapOptions(const LocalizerOptions& defaults, const json& fields,
                            const std::string& path) {
  const std::string where = path + ": options";
  if (!fields.is_object()) Fail("{}: expected an object of options", where);
  for (const char* own : {"threads", "max_pixels"}) {
    if (fields.contains(own))
      Fail("{}: '{}' is set for every map by the server's flags", where, own);
  }
  LocalizerOptions o = defaults;
  constexpr OptionScope kEvery[] = {OptionScope::kMap, OptionScope::kRequest};
  SetLocalizerOptions(&o, fields, kEvery, where);
  o.Check();
  return o;
}

}  // namespace

std::shared_ptr<const LoadedMap> MapRegistry::LoadMap(const std::string& id,
                                                      const std::string& path) const {
  auto m = std::make_shared<LoadedMap>();
  m->id = id;
  m->stamp = MapStamp(path);
  const LineCloud cloud = ReadLineCloud(path);
  const std::string anchor_path = JoinPaths(maps_dir_, id + ".json");
  const bool has_owner_file = FileExists(anchor_path);
  json owner_file;
  LocalizerOptions lo = defaults_;
  if (has_owner_file) {
    owner_file = ParseRequestJson(ReadFilePrefix(anchor_path, 1 << 16), anchor_path);
    if (!owner_file.is_object()) Fail("{}: expected a JSON object", anchor_path);
    if (owner_file.contains("options"))
      lo = MapOptions(defaults_, owner_file["options"], anchor_path);
  }
  m->localizer = std::make_unique<Localizer>(cloud, lo, id);
  if (has_owner_file) {
    if (owner_file.contains("geo_anchor")) {
      m->anchor = GeoAnchorFromJson(owner_file, anchor_path);
    }
    if (owner_file.contains("publish_lines")) {
      if (!owner_file["publish_lines"].is_boolean()) {
        Fail("{}: publish_lines: expected true or false", anchor_path);
      }
      m->publish_lines = owner_file["publish_lines"].get<bool>();
    }
  }
  m->info = {{"id", id},
             {"lines", cloud.size()},
             {"descriptors", cloud.has_descriptors() ? cloud.descriptor_type : "none"},
             {"encoding", std::string(LineEncodingName(cloud.encoding))},
             {"gravity", cloud.gravity.has_value()},
             {"geo_anchored", m->anchor.has_value()}};
  m->details = LineCloudInfo(cloud);
  m->details["id"] = id;
  if (m->anchor) m->details["geo_anchor"] = owner_file["geo_anchor"];
  m->details["publish_lines"] = m->publish_lines;
  const std::string audit_path = JoinPaths(maps_dir_, id + ".audit.json");
  if (m->publish_lines && FileExists(audit_path)) {
    // What publishing costs, from the owner's audit: the share of points
    // the density attack recovered within 1 % of the scene diagonal.
    try {
      const json audit = ParseRequestJson(ReadFilePrefix(audit_path, 1 << 22), audit_path);
      const json share = audit.value(
          json::json_pointer("/density_attack/recovery/within_diagonal_percent/1"), json());
      if (share.is_number() && share.get<double>() >= 0 && share.get<double>() <= 1) {
        m->details["audit_recovered_share"] = share;
      } else if (!share.is_null()) {  // a share no audit gives: not shown to readers
        Fail("density_attack.recovery.within_diagonal_percent.1: {} is not a share in [0, 1]",
             ShownInMessage(share));
      }
    } catch (const std::exception& e) {
      Log(DumpJson(json{{"notice", fmt::format("map {}: audit not read: {}", id, e.what())}}));
    }
  }
  m->segments = MapSegments(cloud);
  return m;
}

void MapRegistry::Reload() {
  try {
    Load();
  } catch (const std::exception& e) {
    if (metrics_) metrics_->MapLoadError();
    Log(DumpJson(json{{"notice", fmt::format("reload failed, the maps are kept: {}", e.what())}}));
  }
}

void MapRegistry::Load() {
  if (!fs::is_directory(maps_dir_)) Fail("serve: {} is not a folder", maps_dir_);
  const std::shared_ptr<const MapSet> old = Maps();
  auto next = std::make_shared<MapSet>();
  for (const auto& e : fs::directory_iterator(maps_dir_)) {
    if (e.path().extension() != ".lcm") continue;
    const std::string id = e.path().stem().string();
    if (!IsMapId(id)) {
      // One JSON line whatever bytes the name has (DumpJson replaces invalid UTF-8).
      Log(DumpJson(json{{"notice", fmt::format("skipped {}: map ids are [A-Za-z0-9_-]{{1,64}}",
                                               e.path().filename().string())}}));
      continue;
    }
    const std::string path = e.path().string();
    const auto kept = old->find(id);
    if (kept != old->end() && kept->second->stamp == MapStamp(path)) {
      (*next)[id] = kept->second;
      continue;
    }
    try {
      (*next)[id] = LoadMap(id, path);
    } catch (const std::exception& err) {
      if (metrics_) metrics_->MapLoadError();
      if (kept != old->end()) {
        (*next)[id] = kept->second;
        Log(DumpJson(
            json{{"notice", fmt::format("map {} not reloaded, its last version is kept: {}", id,
                                        err.what())}}));
      } else {
        Log(DumpJson(json{{"notice", fmt::format("map {} not loaded: {}", id, err.what())}}));
      }
    }
  }
  std::lock_guard<std::mutex> lock(mutex_);
  maps_ = next;
}

}  // namespace linecloud
