// Localizer: a map loaded once, photos, client features and queries answered
// from many Python threads (the GIL is released while a request runs).
#include <filesystem>
#include <memory>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "linecloud/features/sift.h"
#include "linecloud/features/sift_opencv.h"
#include "linecloud/features/sift_scale_space.h"
#include "linecloud/io/json_util.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/localize/query_json.h"
#include "linecloud/pipeline/localizer.h"
#include "linecloud/pipeline/localizer_option_table.h"
#include "linecloud/pipeline/localizer_result_json.h"
#include "linecloud/python/bindings.h"
#include "linecloud/python/convert.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud::python {
namespace {

constexpr const char* kClass = "Localizer";

// The Localizer and the defaults a Python user gave it.
struct PyLocalizer {
  std::shared_ptr<const Localizer> localizer;
  std::string method;  // empty: the map's default for the number of photos
  std::string source;
};

// Keyword arguments as JSON, None left out (Python's "the default"). Names
// that are neither an option of `scopes` nor in `own` are a TypeError.
nlohmann::json OptionKwargs(const py::kwargs& kwargs, std::span<const OptionScope> scopes,
                            std::span<const std::string_view> own, const std::string& where) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [key, value] : kwargs) {
    const std::string name = key.cast<std::string>();
    const OptionSpec* spec = FindLocalizerOption(name);
    const bool mine = std::find(own.begin(), own.end(), name) != own.end();
    if (!mine && !spec) {
      std::vector<std::string> known(own.begin(), own.end());
      for (const std::string& n : LocalizerOptionNames(scopes)) known.push_back(n);
      throw py::type_error(fmt::format("{}: unexpected keyword argument '{}' (options: {})", where,
                                       name, fmt::join(known, ", ")));
    }
    if (value.is_none()) continue;
    j[name] = ToJson(value, where + ": " + name);
  }
  return j;
}

constexpr OptionScope kEveryScope[] = {OptionScope::kMap, OptionScope::kRequest};
constexpr OptionScope kRequestScope[] = {OptionScope::kRequest};

LocalizerOptions MakeOptions(const py::kwargs& kwargs, int threads) {
  LocalizerOptions options;
  SetLocalizerOption(&options, *FindLocalizerOption("threads"), threads, kClass);
  SetLocalizerOptions(&options, OptionKwargs(kwargs, kEveryScope, {}, kClass), kEveryScope, kClass);
  options.Check();
  return options;
}

PyLocalizer MakeLocalizer(py::object cloud_or_path, std::optional<std::string> method, int threads,
                          const py::kwargs& kwargs) {
  const LocalizerOptions options = MakeOptions(kwargs, threads);
  if (options.image.sift.extractor == SiftExtractor::kOpenCV) SetOpenCVThreads(threads);
  PyLocalizer out;
  out.method = method.value_or("");
  if (!out.method.empty()) FindMethod(out.method);  // an unknown name fails here, not later
  if (py::isinstance<LineCloud>(cloud_or_path)) {
    const LineCloud& cloud = cloud_or_path.cast<const LineCloud&>();
    out.source = "LineCloud";
    GilReleased release;
    out.localizer = std::make_shared<const Localizer>(cloud, options, out.source);
    return out;
  }
  out.source = py::str(py::module_::import("os").attr("fspath")(cloud_or_path));
  // A map file's index is cached as the CLI caches it (the same file: built once for both).
  LocalizerOptions cached = options;
  UseIndexCache(out.source, &cached);
  GilReleased release;
  out.localizer = std::make_shared<const Localizer>(ReadLineCloud(out.source), cached, out.source);
  return out;
}

// The per-request options of every localize_* call.
struct Request {
  LocalizeRequest request;
  bool with_inliers = true;
  std::vector<Rigid3d> cam_from_rig;
};

// points_local: [{"frame", "keypoint", "xyz"}, ...] as the service takes it,
// or columns {"frame": N, "keypoint": N, "xyz": N x 3} (numpy arrays).
std::vector<LocalPoint> LocalPoints(const nlohmann::json& j, const std::string& where) {
  if (!j.is_object()) return ParseLocalPointsJson(j, where);
  for (const char* key : {"frame", "keypoint", "xyz"}) {
    if (!j.contains(key) || !j[key].is_array()) {
      Fail("{}: columns need '{}' as an array (or give a list of {{frame, keypoint, xyz}})", where,
           key);
    }
  }
  const size_t n = j["frame"].size();
  if (j["keypoint"].size() != n || j["xyz"].size() != n || j.size() != 3) {
    Fail("{}: frame, keypoint and xyz must have one row per point (and nothing else)", where);
  }
  nlohmann::json rows = nlohmann::json::array();
  for (size_t i = 0; i < n; ++i) {
    rows.push_back(
        {{"frame", j["frame"][i]}, {"keypoint", j["keypoint"][i]}, {"xyz", j["xyz"][i]}});
  }
  return ParseLocalPointsJson(rows, where);
}

Request MakeRequest(const PyLocalizer& self, const py::kwargs& kwargs, const std::string& where,
                    bool photos) {
  static constexpr std::string_view kOwn[] = {"method",       "gravity",      "threads",
                                              "with_inliers", "cam_from_rig", "points_local",
                                              "scale_known"};
  const std::span<const std::string_view> own(kOwn, photos ? 7 : 4);
  py::dict plain;
  py::object rig = py::none();
  for (const auto& [key, value] : kwargs) {
    if (photos && key.cast<std::string>() == "cam_from_rig") {
      rig = py::reinterpret_borrow<py::object>(value);
    } else {
      plain[key] = value;
    }
  }
  const nlohmann::json o = OptionKwargs(py::kwargs(plain), kRequestScope, own, where);
  Request r;
  r.request.method = StringOption(o, "method", where).value_or(self.method);
  if (!r.request.method.empty()) FindMethod(r.request.method);
  if (o.contains("gravity") && !o["gravity"].is_null()) {
    r.request.gravity = JsonVector3(o["gravity"], where + ": gravity");
  }
  // The request-scope options on the Localizer's defaults (one table: the CLI's and the service's).
  const bool any = std::any_of(o.items().begin(), o.items().end(), [&](const auto& item) {
    return std::find(own.begin(), own.end(), item.key()) == own.end();
  });
  if (any) {
    LocalizerOptions options = self.localizer->options();
    SetLocalizerOptions(&options, o, kRequestScope, where, own);
    options.localize.Check();  // combinations (min_iterations <= max_iterations) before any work
    r.request.options = options.localize;
  }
  if (auto v = IntegerOption(o, "threads", where)) {
    if (*v < 1 || *v > 1024) Fail("{}: threads must be in [1, 1024], got {}", where, *v);
    r.request.threads = static_cast<int>(*v);
  }
  r.with_inliers = BoolOption(o, "with_inliers", where).value_or(true);
  if (o.contains("points_local")) {
    r.request.points_local = LocalPoints(o["points_local"], where + ": points_local");
  }
  r.request.scale_known = BoolOption(o, "scale_known", where);
  // Ctrl-C: the request polls Python's signal handlers while it runs without
  // the GIL (a handler that raises stops it; ResultToDict re-raises).
  r.request.should_stop = PythonSignalRaised;
  if (!rig.is_none()) {
    if (!py::isinstance<py::list>(rig) && !py::isinstance<py::tuple>(rig)) {
      throw py::type_error(where + ": cam_from_rig must be a list of pose dicts");
    }
    size_t k = 0;
    for (py::handle pose : rig) {
      r.cam_from_rig.push_back(PoseFromDict(pose, fmt::format("{}: cam_from_rig[{}]", where, k++)));
    }
  }
  return r;
}

py::dict ResultToDict(const LocalizerResult& r, bool with_inliers) {
  if (PyErr_Occurred()) throw py::error_already_set();  // a signal handler raised (Ctrl-C)
  return FromJson(LocalizerResultToJson(r, with_inliers)).cast<py::dict>();
}
// Whether `value` is one photo's rows written as Python lists ([[x, y], ...]
// or [[d0, ..., d127], ...]), not a list of photos' arrays.
bool IsRowList(py::handle value) {
  if (!py::isinstance<py::list>(value) && !py::isinstance<py::tuple>(value)) return false;
  const py::sequence rows = py::reinterpret_borrow<py::sequence>(value);
  if (rows.size() == 0) return false;
  const py::handle first = rows[0];
  if (!py::isinstance<py::list>(first) && !py::isinstance<py::tuple>(first)) return false;
  const py::sequence row = py::reinterpret_borrow<py::sequence>(first);
  return row.size() > 0 && (py::isinstance<py::int_>(row[0]) || py::isinstance<py::float_>(row[0]));
}

// One photo or a list of them (a rig), each with its camera.
std::vector<py::handle> Items(py::handle value, bool* many) {
  *many =
      (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value)) && !IsRowList(value);
  std::vector<py::handle> items;
  if (*many) {
    for (py::handle item : value) items.push_back(item);
  } else {
    items.push_back(value);
  }
  return items;
}

std::vector<Camera> Cameras(py::handle camera, size_t photos, const std::string& where) {
  bool many = false;
  const std::vector<py::handle> items = Items(camera, &many);
  std::vector<Camera> cameras;
  for (size_t k = 0; k < items.size(); ++k) {
    cameras.push_back(CameraFromDict(
        items[k], many ? fmt::format("{}: camera[{}]", where, k) : where + ": camera"));
  }
  if (cameras.size() == 1) cameras.resize(photos, cameras[0]);
  if (cameras.size() != photos) {
    Fail("{}: {} photos but {} cameras (give one for all, or one per photo)", where, photos,
         cameras.size());
  }
  return cameras;
}

// Photos of a request: per photo its camera, rig pose and name; the bytes,
// images or features they point to live in `storage` during the call.
struct PhotoStorage {
  std::vector<std::string> bytes;
  std::vector<GreyImage> images;
  std::vector<SiftFeatures> features;
};

void SetRig(std::vector<QueryPhoto>& photos, const Request& r, const std::string& where) {
  if (photos.size() == 1 && r.cam_from_rig.empty()) return;
  if (r.cam_from_rig.size() != photos.size()) {
    Fail("{}: {} photos need {} cam_from_rig poses, got {}", where, photos.size(), photos.size(),
         r.cam_from_rig.size());
  }
  for (size_t k = 0; k < photos.size(); ++k) photos[k].cam_from_rig = r.cam_from_rig[k];
}

void AddImage(py::handle image, const std::string& name, PhotoStorage* storage, QueryPhoto* photo) {
  if (py::isinstance<py::bytes>(image) || py::isinstance<py::bytearray>(image) ||
      py::isinstance<py::memoryview>(image)) {
    // bytes(x) copies any buffer (bytearray, memoryview) into one string.
    const py::object copy = py::module_::import("builtins").attr("bytes")(image);
    storage->bytes.push_back(copy.cast<std::string>());
    photo->name = name;
  } else if (py::isinstance<py::array>(image)) {
    const py::array array = py::reinterpret_borrow<py::array>(image);
    if (array.ndim() != 2 || array.dtype().kind() != 'u' || array.dtype().itemsize() != 1) {
      throw py::type_error(fmt::format(
          "{}: expected a grey uint8 H x W array (convert colour photos first, or pass the "
          "encoded file), got dtype {} with {} dimensions",
          name, py::str(array.dtype()).cast<std::string>(), array.ndim()));
    }
    const auto pixels = py::array_t<uint8_t, py::array::c_style>::ensure(array);
    GreyImage grey;
    grey.height = static_cast<int>(pixels.shape(0));
    grey.width = static_cast<int>(pixels.shape(1));
    grey.pixels.assign(pixels.data(), pixels.data() + pixels.size());
    storage->images.push_back(std::move(grey));
    photo->name = name;
  } else if (py::hasattr(image, "read")) {  // an open binary file (a closed one raises)
    const py::object data = image.attr("read")();
    if (!py::isinstance<py::bytes>(data)) {
      throw py::type_error(name + ": the file's read() must give bytes (open it with 'rb')");
    }
    storage->bytes.push_back(data.cast<std::string>());
    photo->name =
        py::hasattr(image, "name") ? py::str(image.attr("name")).cast<std::string>() : name;
  } else if (py::isinstance<py::str>(image) || py::hasattr(image, "__fspath__")) {
    const std::string path = py::str(py::module_::import("os").attr("fspath")(image));
    storage->bytes.push_back(ReadFileToString(path));
    photo->name = path;
  } else {
    throw py::type_error(fmt::format(
        "{}: expected a path, an open binary file, the encoded file's bytes or a grey uint8 "
        "array, got {}",
        name, py::str(py::type::of(image).attr("__name__")).cast<std::string>()));
  }
}

py::dict LocalizeImages(const PyLocalizer& self, ImageArg image, CameraArg camera,
                        const py::kwargs& kwargs) {
  const std::string where = "Localizer.localize_image";
  const Request r = MakeRequest(self, kwargs, where, true);
  bool many = false;
  const std::vector<py::handle> items = Items(image, &many);
  if (items.empty()) Fail("{}: no photo given", where);
  const std::vector<Camera> cameras = Cameras(camera, items.size(), where);
  PhotoStorage storage;
  storage.bytes.reserve(items.size());
  storage.images.reserve(items.size());
  std::vector<QueryPhoto> photos(items.size());
  for (size_t k = 0; k < items.size(); ++k) {
    const size_t bytes = storage.bytes.size(), images = storage.images.size();
    AddImage(items[k], many ? fmt::format("image[{}]", k) : "image", &storage, &photos[k]);
    if (storage.bytes.size() > bytes) {
      const std::string& b = storage.bytes.back();
      photos[k].encoded = {reinterpret_cast<const uint8_t*>(b.data()), b.size()};
    } else if (storage.images.size() > images) {
      photos[k].image = &storage.images.back();
    }
    photos[k].camera = cameras[k];
  }
  SetRig(photos, r, where);
  LocalizerResult result;
  {
    GilReleased release;
    result = self.localizer->LocalizePhotos(photos, r.request);
  }
  return ResultToDict(result, r.with_inliers);
}

py::dict LocalizeFeatures(const PyLocalizer& self, ArrayArg keypoints, ArrayArg descriptors,
                          CameraArg camera, const py::kwargs& kwargs) {
  const std::string where = "Localizer.localize_features";
  const Request r = MakeRequest(self, kwargs, where, true);
  bool many_k = false, many_d = false;
  const std::vector<py::handle> k_items = Items(keypoints, &many_k);
  const std::vector<py::handle> d_items = Items(descriptors, &many_d);
  if (many_k != many_d || k_items.size() != d_items.size()) {
    Fail("{}: keypoints and descriptors: one array each, or lists of equal length", where);
  }
  if (k_items.empty()) Fail("{}: no photo given", where);
  const std::vector<Camera> cameras = Cameras(camera, k_items.size(), where);
  PhotoStorage storage;
  storage.features.resize(k_items.size());
  std::vector<QueryPhoto> photos(k_items.size());
  for (size_t k = 0; k < k_items.size(); ++k) {
    const std::string suffix = many_k ? fmt::format("[{}]", k) : "";
    // N x 2 (x, y) or N x 4 (x, y, scale, orientation), COLMAP's pixel convention;
    // rows written as Python lists taken as the array they spell.
    const auto as_array = [](py::handle v) {
      return IsRowList(v) ? py::module_::import("numpy").attr("asarray")(v)
                          : py::reinterpret_borrow<py::object>(v);
    };
    const py::object k_rows = as_array(k_items[k]);
    const py::array array = py::array::ensure(k_rows);
    const int cols = array && array.ndim() == 2 && array.shape(1) == 4 ? 4 : 2;
    size_t n = 0, nd = 0;
    const std::vector<double> xy = FiniteRows(k_rows, cols, "keypoints" + suffix, &n);
    SiftFeatures& f = storage.features[k];
    f.descriptors = ByteRows(as_array(d_items[k]), 128, "descriptors" + suffix, &nd);
    if (nd != n) Fail("{}: {} keypoints but {} descriptors{}", where, n, nd, suffix);
    f.keypoints.resize(n);
    for (size_t i = 0; i < n; ++i) {
      f.keypoints[i].x = static_cast<float>(xy[cols * i]);
      f.keypoints[i].y = static_cast<float>(xy[cols * i + 1]);
      if (cols == 4) {
        f.keypoints[i].scale = static_cast<float>(xy[cols * i + 2]);
        f.keypoints[i].orientation = static_cast<float>(xy[cols * i + 3]);
      }
    }
    f.image_width = static_cast<int>(cameras[k].width);
    f.image_height = static_cast<int>(cameras[k].height);
    photos[k].features = &f;
    photos[k].camera = cameras[k];
    photos[k].name = "features" + suffix;
  }
  SetRig(photos, r, where);
  LocalizerResult result;
  {
    GilReleased release;
    result = self.localizer->LocalizePhotos(photos, r.request);
  }
  return ResultToDict(result, r.with_inliers);
}

py::dict LocalizeQuery(const PyLocalizer& self, QueryArg query, const py::kwargs& kwargs) {
  const std::string where = "Localizer.localize_query";
  const Request r = MakeRequest(self, kwargs, where, false);
  if (!py::isinstance<py::dict>(query)) {
    throw py::type_error(where + ": expected a QUERY.json-like dict");
  }
  const Query q = ParseQueryJson(ToJson(query, "query"), "query");
  LocalizerResult result;
  {
    GilReleased release;
    result = self.localizer->LocalizeQuery(q, r.request, "query");
  }
  return ResultToDict(result, r.with_inliers);
}

}  // namespace

void BindLocalizer(py::module_& m) {
  // A photo's memory, and a bound for the process: SIFT's scale space is most of it (~320
  // bytes per pixel after the downscaling to max_image_size; decoding adds ~8).
  constexpr double kMB = 1024.0 * 1024.0;
  m.def(
      "set_memory_limit",
      [](double mb) {
        if (!(mb == 0 || (mb >= 1 && mb <= 1e7))) {
          throw py::value_error(fmt::format(
              "set_memory_limit: mb must be 0 (no limit) or a number in [1, 1e7], got {}", mb));
        }
        SetSiftMemoryLimit(static_cast<size_t>(mb * kMB));
      },
      py::arg("mb"),
      "Bounds SIFT's scale space of all photos the process extracts at once (every Localizer, "
      "every thread) to `mb` megabytes: a photo waits for room while others finish; one that "
      "alone needs more raises ValueError naming both. 0: no limit (the default). As `linecloud "
      "serve --memory-budget-mb` does for the service.");
  m.def(
      "memory_in_use",
      [] {
        const SiftMemoryUse use = SiftMemoryInUse();
        py::dict d;
        d["limit_mb"] = static_cast<double>(use.limit) / kMB;
        d["reserved_mb"] = static_cast<double>(use.reserved) / kMB;
        d["pooled_mb"] = static_cast<double>(use.pooled) / kMB;
        return d;
      },
      "SIFT's scale space now: limit_mb (0: none), reserved_mb (by photos being extracted), "
      "pooled_mb (kept mapped for the next ones).");
  m.def(
      "photo_memory_mb",
      [](int width, int height) {
        if (width < 1 || height < 1 || width > 1'000'000 || height > 1'000'000) {
          throw py::value_error(fmt::format(
              "photo_memory_mb: width and height must be in [1, 1e6], got {} x {}", width, height));
        }
        return static_cast<double>(SiftScaleSpaceBytes(width, height)) / kMB;
      },
      py::arg("width"), py::arg("height"),
      "The megabytes of SIFT's scale space one photo of this size takes while it is extracted "
      "(after the downscaling to 3 200 px; its decoding adds ~8 bytes per pixel): what each "
      "thread localizing photos holds, and what set_memory_limit counts.");
  m.def(
      "localizer_options", [] { return FromJson(LocalizerOptionTableJson()); },
      "The Localizer's options, one dict each (name, flag, scope, type, default, help; min / "
      "max, choices): the same table the command line's flags and the service's fields are "
      "made from.");
  py::class_<PyLocalizer>(m, kClass,
                          "A map loaded once, many photos localized: SIFT, matching to the "
                          "map's descriptors, RANSAC with the method's minimal solver, LM. Safe "
                          "to call from many threads; each call releases the GIL.")
      .def(py::init(&MakeLocalizer), py::arg("cloud_or_path"), py::arg("method") = py::none(),
           py::arg("threads") = 1,
           "cloud_or_path: a LineCloud or a .lcm path. Options: every option of "
           "linecloud.localizer_options() (the CLI's localize flags, snake_case): the map's "
           "(features, index, max_ratio, ...) and the defaults of its requests (threshold, seed, "
           "max_iterations, min_inliers, ...).")
      .def("localize_image", &LocalizeImages, py::arg("image"), py::arg("camera"),
           "image: a path, the encoded file's bytes or a grey uint8 H x W array (or a list of "
           "them with cam_from_rig=[pose, ...] for a rig); camera: a camera dict (or one per "
           "photo). points_local=[{frame, keypoint, xyz}, ...] (or columns) and scale_known for "
           "the +l methods. Options: method, gravity, threads, with_inliers and every "
           "request-scope option "
           "of linecloud.localizer_options() (threshold, seed, max_seconds, refine_focal, ...). "
           "Returns localize's result dict.")
      .def("localize_features", &LocalizeFeatures, py::arg("keypoints"), py::arg("descriptors"),
           py::arg("camera"),
           "keypoints: N x 2 (or N x 4 with scale, orientation) in COLMAP's pixel convention; "
           "descriptors: N x 128 uint8 in COLMAP's SIFT normalisation. Lists for a rig.")
      .def("localize_query", &LocalizeQuery, py::arg("query"),
           "query: a dict laid out as QUERY.json (cameras, observations, ...).")
      .def_property_readonly(
          "options",
          [](const PyLocalizer& s) {
            return FromJson(LocalizerOptionsToJson(s.localizer->options()));
          },
          "Every option's value on this Localizer (name -> value)")
      .def_property_readonly("size", [](const PyLocalizer& s) { return s.localizer->size(); })
      .def_property_readonly("has_descriptors",
                             [](const PyLocalizer& s) { return s.localizer->has_descriptors(); })
      .def("__len__", [](const PyLocalizer& s) { return s.localizer->size(); })
      .def("__repr__", [](const PyLocalizer& s) {
        return fmt::format("<linecloud.Localizer: {} ({} lines)>", s.source, s.localizer->size());
      });
}

}  // namespace linecloud::python
