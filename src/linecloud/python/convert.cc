#include "linecloud/python/convert.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "linecloud/io/json_util.h"
#include "linecloud/localize/query_json.h"
#include "linecloud/pipeline/image_query.h"
#include "linecloud/util/error.h"

namespace linecloud::python {
namespace {

// Deep enough for any query or options dict; a self-containing list stops here.
constexpr int kMaxDepth = 32;

nlohmann::json ToJsonAt(py::handle value, const std::string& where, int depth) {
  if (depth > kMaxDepth) Fail("{}: nested deeper than {} levels", where, kMaxDepth);
  if (value.is_none()) return nullptr;
  if (py::isinstance<py::bool_>(value)) return value.cast<bool>();
  if (py::isinstance<py::str>(value)) return value.cast<std::string>();
  if (py::hasattr(value, "__fspath__")) {  // pathlib paths where a string is expected
    return py::str(py::module_::import("os").attr("fspath")(value)).cast<std::string>();
  }
  if (py::isinstance<py::float_>(value)) return value.cast<double>();
  if (py::isinstance<py::array>(value)) {
    return ToJsonAt(value.attr("tolist")(), where, depth + 1);
  }
  if (py::isinstance<py::int_>(value) || py::hasattr(value, "__index__")) {
    const py::int_ integer = py::reinterpret_steal<py::int_>(PyNumber_Index(value.ptr()));
    if (!integer) throw py::error_already_set();
    if (integer < py::int_(0)) {
      if (integer < py::int_(std::numeric_limits<int64_t>::min())) {
        Fail("{}: integer out of range", where);
      }
      return integer.cast<int64_t>();
    }
    if (integer > py::int_(std::numeric_limits<uint64_t>::max())) {
      Fail("{}: integer out of range", where);
    }
    return integer.cast<uint64_t>();
  }
  if (py::isinstance<py::dict>(value)) {
    nlohmann::json j = nlohmann::json::object();
    for (const auto& [key, item] : value.cast<py::dict>()) {
      if (!py::isinstance<py::str>(key)) {
        Fail("{}: dict keys must be strings, got {}", where,
             py::str(py::type::of(key).attr("__name__")).cast<std::string>());
      }
      const std::string name = key.cast<std::string>();
      j[name] = ToJsonAt(item, where + "." + name, depth + 1);
    }
    return j;
  }
  if (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value)) {
    nlohmann::json j = nlohmann::json::array();
    size_t i = 0;
    for (py::handle item : value) {
      j.push_back(ToJsonAt(item, fmt::format("{}[{}]", where, i++), depth + 1));
    }
    return j;
  }
  // numpy scalars of float type are Python floats; other numbers (e.g. Decimal).
  if (py::hasattr(value, "__float__") && !py::isinstance<py::bytes>(value)) {
    return py::reinterpret_borrow<py::object>(value).cast<double>();
  }
  throw py::type_error(
      fmt::format("{}: {} is not a JSON value (dict, list, str, number, bool or None)", where,
                  py::str(py::type::of(value).attr("__name__")).cast<std::string>()));
}

template <typename Json>
py::object FromJsonT(const Json& j) {
  switch (j.type()) {
    case nlohmann::json::value_t::null:
      return py::none();
    case nlohmann::json::value_t::boolean:
      return py::bool_(j.template get<bool>());
    case nlohmann::json::value_t::number_integer:
      return py::int_(j.template get<int64_t>());
    case nlohmann::json::value_t::number_unsigned:
      return py::int_(j.template get<uint64_t>());
    case nlohmann::json::value_t::number_float:
      return py::float_(j.template get<double>());
    case nlohmann::json::value_t::string:
      return py::str(j.template get<std::string>());
    case nlohmann::json::value_t::array: {
      py::list list;
      for (const auto& item : j) list.append(FromJsonT(item));
      return list;
    }
    case nlohmann::json::value_t::object: {
      py::dict dict;
      for (auto it = j.begin(); it != j.end(); ++it) dict[py::str(it.key())] = FromJsonT(*it);
      return dict;
    }
    default:
      return py::none();  // binary and discarded values never come from the library
  }
}

// A 2-D array of `cols` columns (a 1-D one of `cols` values when `cols` is
// the only row), its dtype kind one of `kinds`.
py::array CheckedArray(py::handle value, int cols, const std::string& name, const char* kinds,
                       const char* expected) {
  if (!py::isinstance<py::array>(value)) {
    throw py::type_error(
        fmt::format("{}: expected a numpy array ({}), got {}", name, expected, TypeName(value)));
  }
  const py::array array = py::reinterpret_borrow<py::array>(value);
  const char kind = array.dtype().kind();
  if (std::string_view(kinds).find(kind) == std::string_view::npos) {
    throw py::type_error(fmt::format("{}: expected {}, got dtype {}", name, expected,
                                     py::str(array.dtype()).cast<std::string>()));
  }
  if (array.ndim() != 2 || array.shape(1) != cols) {
    std::string shape = "(";
    for (py::ssize_t d = 0; d < array.ndim(); ++d) {
      shape += (d ? ", " : "") + std::to_string(array.shape(d));
    }
    Fail("{}: expected an N x {} array, got shape {}{})", name, cols, shape,
         array.ndim() == 1 ? "," : "");
  }
  return array;
}

}  // namespace

std::string TypeName(py::handle value) {
  return py::str(py::type::of(value).attr("__name__")).cast<std::string>();
}

nlohmann::json ToJson(py::handle value, const std::string& where) {
  return ToJsonAt(value, where, 0);
}

py::object FromJson(const nlohmann::json& j) { return FromJsonT(j); }
py::object FromJson(const nlohmann::ordered_json& j) { return FromJsonT(j); }

Camera CameraFromDict(py::handle camera, const std::string& where) {
  // [newcomer] The CLI's string ("PINHOLE 1536 1024 fx fy cx cy"), as the
  // CLI, the service and the console take it.
  if (py::isinstance<py::str>(camera)) return ParseCameraString(camera.cast<std::string>(), where);
  // A pycolmap.Camera (or any object with model, width, height and params;
  // the model an enum with a name, or its name).
  if (!py::isinstance<py::dict>(camera) && py::hasattr(camera, "model") &&
      py::hasattr(camera, "width") && py::hasattr(camera, "height") &&
      py::hasattr(camera, "params")) {
    const py::object model = camera.attr("model");
    py::dict d;
    d["model"] = py::hasattr(model, "name") ? model.attr("name") : model;
    d["width"] = camera.attr("width");
    d["height"] = camera.attr("height");
    d["params"] = py::module_::import("builtins").attr("list")(camera.attr("params"));
    return CameraFromJson(ToJson(d, where), where);
  }
  if (!py::isinstance<py::dict>(camera)) {
    throw py::type_error(fmt::format(
        "{}: expected a camera dict {{\"model\", \"width\", \"height\", \"params\"}}, the "
        "CLI's camera string or a pycolmap.Camera, got {}",
        where, TypeName(camera)));
  }
  return CameraFromJson(ToJson(camera, where), where);
}

py::dict CameraToDict(const Camera& camera) {
  py::dict d;
  d["model"] = std::string(CameraModelName(camera.model_id));
  d["width"] = camera.width;
  d["height"] = camera.height;
  d["params"] = camera.params;
  return d;
}

Rigid3d PoseFromDict(py::handle pose, const std::string& where) {
  // A linecloud.Pose (or any object with to_dict()) stands for its dict.
  if (!py::isinstance<py::dict>(pose) && py::hasattr(pose, "to_dict")) {
    return PoseFromDict(pose.attr("to_dict")(), where);
  }
  if (!py::isinstance<py::dict>(pose)) {
    throw py::type_error(
        fmt::format("{}: expected a pose dict {{\"q\": [w, x, y, z], \"t\": "
                    "[x, y, z]}}, got {}",
                    where, TypeName(pose)));
  }
  return JsonPose(ToJson(pose, where), where);
}

py::dict PoseToDict(const Eigen::Quaterniond& q, const Eigen::Vector3d& t) {
  py::dict d;
  d["q"] = py::make_tuple(q.w(), q.x(), q.y(), q.z());
  d["t"] = py::make_tuple(t.x(), t.y(), t.z());
  return d;
}

py::object PoseObject(const Eigen::Quaterniond& q, const Eigen::Vector3d& t, double scale) {
  static const py::handle pose_type =
      py::object(py::module_::import("linecloud.pose").attr("Pose")).release();  // for the process
  return pose_type(py::make_tuple(q.w(), q.x(), q.y(), q.z()), py::make_tuple(t.x(), t.y(), t.z()),
                   scale);
}

std::vector<double> FiniteRows(py::handle value, int cols, const std::string& name, size_t* rows) {
  const py::array array = CheckedArray(value, cols, name, "fiu", "a float or integer array");
  const auto doubles =
      py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
  if (!doubles) throw py::error_already_set();
  *rows = static_cast<size_t>(doubles.shape(0));
  std::vector<double> out(doubles.data(), doubles.data() + doubles.size());
  for (size_t i = 0; i < out.size(); ++i) {
    if (!std::isfinite(out[i])) {
      Fail("{}[{}, {}]: not a finite number ({})", name, i / cols, i % cols, out[i]);
    }
  }
  return out;
}

std::vector<uint8_t> ByteRows(py::handle value, int cols, const std::string& name, size_t* rows) {
  // OpenCV's SIFT gives float32 L2-normalised descriptors: the conversion named.
  constexpr const char* kExpected =
      "uint8 (COLMAP's RootSIFT bytes; OpenCV's float SIFT: linecloud.interop.from_opencv_sift)";
  const py::array array = CheckedArray(value, cols, name, "u", kExpected);
  if (array.dtype().itemsize() != 1) {
    throw py::type_error(fmt::format("{}: expected {}, got dtype {}", name, kExpected,
                                     py::str(array.dtype()).cast<std::string>()));
  }
  const auto bytes = py::array_t<uint8_t, py::array::c_style>::ensure(array);
  if (!bytes) throw py::error_already_set();
  *rows = static_cast<size_t>(bytes.shape(0));
  return std::vector<uint8_t>(bytes.data(), bytes.data() + bytes.size());
}

py::array_t<double> DoubleArray(const double* data, size_t rows, size_t cols) {
  py::array_t<double> out({static_cast<py::ssize_t>(rows), static_cast<py::ssize_t>(cols)});
  std::copy_n(data, rows * cols, out.mutable_data());
  return out;
}

nlohmann::json Options(const py::kwargs& kwargs, std::initializer_list<const char*> allowed,
                       const std::string& function) {
  return Options(kwargs, std::vector<std::string>(allowed.begin(), allowed.end()), function);
}

nlohmann::json Options(const py::kwargs& kwargs, const std::vector<std::string>& allowed,
                       const std::string& function) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [key, value] : kwargs) {
    const std::string name = key.cast<std::string>();
    j[name] = ToJson(value, function + ": " + name);
  }
  CheckKeys(j, allowed, function);
  return j;
}

void CheckKeys(const nlohmann::json& options, std::initializer_list<const char*> allowed,
               const std::string& where) {
  CheckKeys(options, std::vector<std::string>(allowed.begin(), allowed.end()), where);
}

void CheckKeys(const nlohmann::json& options, const std::vector<std::string>& allowed,
               const std::string& where) {
  if (!options.is_object()) Fail("{}: expected a dict", where);
  for (auto it = options.begin(); it != options.end(); ++it) {
    if (std::find(allowed.begin(), allowed.end(), it.key()) != allowed.end()) continue;
    throw py::type_error(
        fmt::format("{}: unknown option '{}' (options: {})", where, it.key(),
                    allowed.empty() ? "none" : fmt::format("{}", fmt::join(allowed, ", "))));
  }
}

namespace {

const nlohmann::json* Present(const nlohmann::json& options, const char* key) {
  const auto it = options.find(key);
  return it == options.end() || it->is_null() ? nullptr : &*it;
}

}  // namespace

std::optional<double> NumberOption(const nlohmann::json& options, const char* key,
                                   const std::string& where) {
  const nlohmann::json* v = Present(options, key);
  if (!v) return std::nullopt;
  if (!v->is_number() || v->is_boolean()) Fail("{}: {} must be a number", where, key);
  return v->get<double>();
}

std::optional<int64_t> IntegerOption(const nlohmann::json& options, const char* key,
                                     const std::string& where) {
  const nlohmann::json* v = Present(options, key);
  if (!v) return std::nullopt;
  if (v->is_number_unsigned() && v->get<uint64_t>() > uint64_t(INT64_MAX)) {
    Fail("{}: {} is out of range", where, key);
  }
  if (!v->is_number_integer()) Fail("{}: {} must be an integer", where, key);
  return v->get<int64_t>();
}

std::optional<bool> BoolOption(const nlohmann::json& options, const char* key,
                               const std::string& where) {
  const nlohmann::json* v = Present(options, key);
  if (!v) return std::nullopt;
  if (!v->is_boolean()) Fail("{}: {} must be True or False", where, key);
  return v->get<bool>();
}

std::optional<std::string> StringOption(const nlohmann::json& options, const char* key,
                                        const std::string& where) {
  const nlohmann::json* v = Present(options, key);
  if (!v) return std::nullopt;
  if (!v->is_string()) Fail("{}: {} must be a string", where, key);
  return v->get<std::string>();
}

}  // namespace linecloud::python
