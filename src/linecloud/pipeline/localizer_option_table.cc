#include "linecloud/pipeline/localizer_option_table.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <limits>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "linecloud/io/json_util.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using json = nlohmann::json;

OptionSpec Spec(std::string name, OptionType type, OptionScope scope, std::string help) {
  OptionSpec s;
  s.name = std::move(name);
  s.type = type;
  s.scope = scope;
  s.help = std::move(help);
  return s;
}

OptionSpec Bool(std::string name, OptionScope scope, std::string help,
                std::function<bool&(LocalizerOptions&)> member) {
  OptionSpec s = Spec(std::move(name), OptionType::kBool, scope, std::move(help));
  s.get = [member](const LocalizerOptions& o) {
    return json(member(const_cast<LocalizerOptions&>(o)));
  };
  s.set = [member](LocalizerOptions& o, const json& v) { member(o) = v.get<bool>(); };
  return s;
}

template <typename T>
OptionSpec Integer(std::string name, OptionScope scope, std::string help, double min, double max,
                   std::function<T&(LocalizerOptions&)> member) {
  OptionSpec s = Spec(std::move(name), OptionType::kInteger, scope, std::move(help));
  s.min = min;
  s.max = max;
  s.get = [member](const LocalizerOptions& o) {
    return json(member(const_cast<LocalizerOptions&>(o)));
  };
  s.set = [member](LocalizerOptions& o, const json& v) {
    member(o) = static_cast<T>(v.get<double>());
  };
  return s;
}

OptionSpec Number(std::string name, OptionScope scope, std::string help, double min, double max,
                  bool min_open, bool max_open, std::function<double&(LocalizerOptions&)> member) {
  OptionSpec s = Spec(std::move(name), OptionType::kNumber, scope, std::move(help));
  s.min = min;
  s.max = max;
  s.min_open = min_open;
  s.max_open = max_open;
  s.get = [member](const LocalizerOptions& o) {
    return json(member(const_cast<LocalizerOptions&>(o)));
  };
  s.set = [member](LocalizerOptions& o, const json& v) { member(o) = v.get<double>(); };
  return s;
}

std::vector<OptionSpec> MakeTable() {
  using S = OptionScope;
  const S map = S::kMap, req = S::kRequest;
  std::vector<OptionSpec> t;
  // --- the map's: SIFT, matching, the index, threads ---
  {
    OptionSpec s = Spec("features", OptionType::kChoice, map,
                        "SIFT extractor: colmap (COLMAP 3.8's CPU extractor's features, to the "
                        "bit) or opencv (OpenCV's SIFT, close to them)");
    s.choices = {"colmap", "opencv"};
    s.get = [](const LocalizerOptions& o) {
      return json(SiftExtractorName(o.image.sift.extractor));
    };
    s.set = [](LocalizerOptions& o, const json& v) {
      o.image.sift.extractor = ParseSiftExtractor(v.get<std::string>(), "features");
    };
    t.push_back(std::move(s));
  }
  t.push_back(Integer<int>(
      "max_image_size", map,
      "Photos with a larger side are downscaled before SIFT (COLMAP's "
      "SiftExtraction.max_image_size)",
      16, 100000, [](LocalizerOptions& o) -> int& { return o.image.sift.max_image_size; }));
  t.push_back(Integer<int>(
      "max_num_features", map,
      "At most this many SIFT features per photo (COLMAP's "
      "SiftExtraction.max_num_features)",
      1, 1 << 20, [](LocalizerOptions& o) -> int& { return o.image.sift.max_num_features; }));
  t.push_back(Integer<uint64_t>(
      "max_pixels", map,
      "Photos (JPEG or PNG) whose header announces more pixels are refused before decoding", 1,
      1e12, [](LocalizerOptions& o) -> uint64_t& { return o.image.max_pixels; }));
  t.push_back(Number("max_ratio", map, "Lowe's ratio test on descriptor angles (COLMAP's default)",
                     0, 1, true, false,
                     [](LocalizerOptions& o) -> double& { return o.image.matching.max_ratio; }));
  t.push_back(Bool("cross_check", map, "Keep only mutual nearest neighbours (exact matching)",
                   [](LocalizerOptions& o) -> bool& { return o.image.matching.cross_check; }));
  t.push_back(Integer<size_t>(
      "approximate_from", map,
      "Maps with at least this many descriptors are matched through the approximate index (0: "
      "none is, as exact_matching)",
      0, kMaxInteger, [](LocalizerOptions& o) -> size_t& { return o.image.approximate_from; }));
  {
    OptionSpec s = Spec("exact_matching", OptionType::kBool, map,
                        "Match exactly even on large maps (by default maps of approximate_from "
                        "descriptors or more use the approximate index)");
    s.get = [](const LocalizerOptions& o) { return json(o.image.approximate_from == 0); };
    s.set = [](LocalizerOptions& o, const json& v) {
      if (v.get<bool>()) {
        o.image.approximate_from = 0;
      } else if (o.image.approximate_from == 0) {
        o.image.approximate_from = ImageQueryOptions{}.approximate_from;
      }
    };
    t.push_back(std::move(s));
  }
  {
    OptionSpec s = Spec("index", OptionType::kChoice, map,
                        "Approximate index: ivf, faiss-ivf, faiss-hnsw, hnswlib or flann");
    s.choices = {"ivf", "faiss-ivf", "faiss-hnsw", "hnswlib", "flann"};
    s.get = [](const LocalizerOptions& o) {
      return json(DescriptorIndexKindName(o.image.index.kind));
    };
    s.set = [](LocalizerOptions& o, const json& v) {
      o.image.index.kind = ParseDescriptorIndexKind(v.get<std::string>(), "index");
    };
    t.push_back(std::move(s));
  }
  t.push_back(Integer<int>("nprobe", map, "IVF cells scanned per query descriptor", 1, 1 << 20,
                           [](LocalizerOptions& o) -> int& { return o.image.index.nprobe; }));
  {
    OptionSpec s = Integer<int>(
        "threads", map, "Threads for extraction and matching (results do not depend on it)", 1,
        1024, [](LocalizerOptions& o) -> int& { return o.image.threads; });
    s.set = [](LocalizerOptions& o, const json& v) {
      o.image.threads = o.image.index.threads = v.get<int>();
    };
    t.push_back(std::move(s));
  }
  {
    OptionSpec s = Spec("map_gravity", OptionType::kDirection, map,
                        "Gravity direction x,y,z in the map frame");
    s.nullable = true;
    s.null_means = "the one lift --gravity stored in the map";
    s.get = [](const LocalizerOptions& o) {
      if (!o.map_gravity) return json();
      return json{o.map_gravity->x(), o.map_gravity->y(), o.map_gravity->z()};
    };
    s.set = [](LocalizerOptions& o, const json& v) {
      if (v.is_null()) {
        o.map_gravity.reset();
      } else {
        o.map_gravity = Eigen::Vector3d(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
      }
    };
    t.push_back(std::move(s));
  }
  // --- each request's: RANSAC, refinement, the success criteria ---
  t.push_back(Number("threshold", req, "RANSAC inlier threshold in pixels", 0, 10000, true, false,
                     [](LocalizerOptions& o) -> double& { return o.localize.ransac.max_error; }));
  t.push_back(
      Integer<uint64_t>("seed", req, "RANSAC seed", 0, kMaxInteger,
                        [](LocalizerOptions& o) -> uint64_t& { return o.localize.ransac.seed; }));
  t.push_back(Number("confidence", req,
                     "RANSAC stops when an all-inlier sample was drawn with this probability", 0, 1,
                     true, true,
                     [](LocalizerOptions& o) -> double& { return o.localize.ransac.confidence; }));
  t.push_back(
      Integer<int>("min_iterations", req, "RANSAC draws at least", 0, 10000000,
                   [](LocalizerOptions& o) -> int& { return o.localize.ransac.min_iterations; }));
  t.push_back(
      Integer<int>("max_iterations", req, "RANSAC iteration cap", 1, 10000000,
                   [](LocalizerOptions& o) -> int& { return o.localize.ransac.max_iterations; }));
  t.push_back(Number(
      "max_seconds", req,
      "RANSAC time budget in seconds (0: none); a run it stops before min_iterations gives no pose",
      0, 86400, false, false,
      [](LocalizerOptions& o) -> double& { return o.localize.ransac.max_seconds; }));
  {
    OptionSpec s =
        Bool("uniform_sampling", req,
             "Uniform RANSAC samples even when matches have Lowe ratios (photos, or \"ratio\" in "
             "a query); by default the best-ranked matches are tried first (PROSAC)",
             [](LocalizerOptions& o) -> bool& { return o.localize.ransac.progressive_sampling; });
    s.get = [](const LocalizerOptions& o) { return json(!o.localize.ransac.progressive_sampling); };
    s.set = [](LocalizerOptions& o, const json& v) {
      o.localize.ransac.progressive_sampling = !v.get<bool>();
    };
    t.push_back(std::move(s));
  }
  t.push_back(
      Bool("local_optimization", req, "RANSAC's local optimisation of each better model",
           [](LocalizerOptions& o) -> bool& { return o.localize.ransac.local_optimization; }));
  t.push_back(Bool("refine", req, "The final LM refinement of the pose on its inliers",
                   [](LocalizerOptions& o) -> bool& { return o.localize.refine; }));
  t.push_back(Bool("refine_focal", req,
                   "Refine the focal length with the pose (one camera; the given focal is a prior, "
                   "e.g. from EXIF)",
                   [](LocalizerOptions& o) -> bool& { return o.localize.refine_focal; }));
  {
    OptionSpec s = Spec("min_inliers", OptionType::kInteger, req, "Inliers a pose needs");
    s.min = 0;
    s.max = 1 << 30;
    s.nullable = true;
    const SuccessCriteria d;
    s.null_means = fmt::format("{} on a point model, {} on a line cloud", d.min_inliers_points,
                               d.min_inliers_lines);
    s.get = [](const LocalizerOptions& o) {
      const SuccessCriteria& c = o.localize.success;
      const SuccessCriteria d;
      if (c.min_inliers_points == d.min_inliers_points &&
          c.min_inliers_lines == d.min_inliers_lines)
        return json();
      return c.min_inliers_points == c.min_inliers_lines ? json(c.min_inliers_points) : json();
    };
    s.set = [](LocalizerOptions& o, const json& v) {
      SuccessCriteria& c = o.localize.success;
      const SuccessCriteria d;
      c.min_inliers_points = v.is_null() ? d.min_inliers_points : v.get<int>();
      c.min_inliers_lines = v.is_null() ? d.min_inliers_lines : v.get<int>();
    };
    t.push_back(std::move(s));
  }
  t.push_back(Number(
      "min_inlier_ratio", req, "Share of the correspondences that must be inliers", 0, 1, false,
      false, [](LocalizerOptions& o) -> double& { return o.localize.success.min_inlier_ratio; }));
  t.push_back(Number("max_rotation_uncertainty", req,
                     "Largest estimated 1-sigma rotation uncertainty (degrees) of a success", 0,
                     360, true, false, [](LocalizerOptions& o) -> double& {
                       return o.localize.success.max_rotation_uncertainty_deg;
                     }));
  t.push_back(Number(
      "max_focal_discrepancy", req,
      "The calibration check: a pose is refused when the focal length its inliers fit best "
      "differs from the camera's by more than this fraction, significantly (0: no check)",
      0, 100, false, false,
      [](LocalizerOptions& o) -> double& { return o.localize.success.max_focal_discrepancy; }));
  t.push_back(Number(
      "max_principal_discrepancy", req,
      "The calibration check for the principal point: a pose is refused when the point its "
      "inliers fit best is farther from the camera's than this fraction of the image's width "
      "(x) or height (y), significantly (0: no check)",
      0, 1, false, false,
      [](LocalizerOptions& o) -> double& { return o.localize.success.max_principal_discrepancy; }));
  t.push_back(Number(
      "max_position_uncertainty", req,
      "Largest estimated 1-sigma position uncertainty (the matches' and the calibration's) of a "
      "success, as a fraction of the median distance to what the inliers see (one camera; 0: no "
      "check)",
      0, 1, false, false,
      [](LocalizerOptions& o) -> double& { return o.localize.success.max_position_uncertainty; }));
  return t;
}

}  // namespace

const std::vector<OptionSpec>& LocalizerOptionTable() {
  static const std::vector<OptionSpec> table = MakeTable();
  return table;
}

const OptionSpec* FindLocalizerOption(std::string_view name) {
  for (const OptionSpec& s : LocalizerOptionTable()) {
    if (s.name == name) return &s;
  }
  return nullptr;
}

void SetLocalizerOption(LocalizerOptions* options, const OptionSpec& spec, const json& value,
                        std::string_view where) {
  spec.set(*options, CheckedOptionValue(spec, value, where));
}

void SetLocalizerOptions(LocalizerOptions* options, const json& fields,
                         std::span<const OptionScope> scopes, std::string_view where,
                         std::span<const std::string_view> other_keys) {
  if (!fields.is_object()) Fail("{}: expected an object of options", where);
  for (const auto& [key, value] : fields.items()) {
    if (std::find(other_keys.begin(), other_keys.end(), key) != other_keys.end()) continue;
    const OptionSpec* spec = FindLocalizerOption(key);
    if (!spec) {
      std::vector<std::string> known(other_keys.begin(), other_keys.end());
      for (const std::string& name : LocalizerOptionNames(scopes)) known.push_back(name);
      Fail("{}: unknown option {} (known: {})", where, ShownInMessage(json(key)),
           fmt::join(known, ", "));
    }
    if (std::find(scopes.begin(), scopes.end(), spec->scope) == scopes.end()) {
      Fail("{}: '{}' is fixed when the map is loaded, not set per request", where, key);
    }
    SetLocalizerOption(options, *spec, value, where);
  }
}

std::vector<std::string> LocalizerOptionNames(std::span<const OptionScope> scopes) {
  std::vector<std::string> names;
  for (const OptionSpec& s : LocalizerOptionTable()) {
    if (std::find(scopes.begin(), scopes.end(), s.scope) != scopes.end()) names.push_back(s.name);
  }
  return names;
}

json LocalizerOptionsToJson(const LocalizerOptions& options) {
  json out = json::object();
  for (const OptionSpec& s : LocalizerOptionTable()) out[s.name] = s.get(options);
  return out;
}

json LocalizerOptionTableJson() {
  json out = json::array();
  for (const OptionSpec& s : LocalizerOptionTable()) {
    json o = OptionDescriptionJson(s, s.Default());
    o["scope"] = s.scope == OptionScope::kMap ? "map" : "request";
    out.push_back(std::move(o));
  }
  return out;
}

}  // namespace linecloud
