// Python values to and from the library's types, for the bindings of
// `import linecloud`. Dicts cross as JSON (nlohmann): cameras, poses, queries
// and options are parsed by the same functions that read the CLI's files, so
// a dict is checked field by field exactly as QUERY.json is. Arrays are numpy:
// shapes, dtypes and finiteness are checked here, naming the argument.
#pragma once

#include <algorithm>
#include <cstdint>
#include <initializer_list>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>
#include <pybind11/pybind11.h>

#include "linecloud/geometry/camera.h"
#include "linecloud/io/option_table.h"
#include "linecloud/geometry/rigid3.h"

namespace linecloud::python {

namespace py = pybind11;

// Any JSON-like Python value (dict with str keys, list, tuple, str, bool,
// int, float, None, numpy scalars and arrays) as JSON; ValueError naming
// `where` otherwise.
nlohmann::json ToJson(py::handle value, const std::string& where);
// JSON as Python (dicts keep the order of ordered_json).
py::object FromJson(const nlohmann::json& j);
py::object FromJson(const nlohmann::ordered_json& j);

// {"model", "width", "height", "params"} (COLMAP's names and parameter order).
Camera CameraFromDict(py::handle camera, const std::string& where);
py::dict CameraToDict(const Camera& camera);
// {"q": [w, x, y, z], "t": [x, y, z]} (+ "scale" when given).
Rigid3d PoseFromDict(py::handle pose, const std::string& where);
// The Python type's name of `value` (for messages: "got int").
std::string TypeName(py::handle value);
py::dict PoseToDict(const Eigen::Quaterniond& q, const Eigen::Vector3d& t);
// A linecloud.Pose (target_from_source; its q with w >= 0), as PoseLib returns its pose type.
py::object PoseObject(const Eigen::Quaterniond& q, const Eigen::Vector3d& t, double scale = 1.0);

// A 2-D numeric array of `cols` columns (any float or integer dtype, any
// strides) as row-major doubles, every value finite. `rows` receives N.
std::vector<double> FiniteRows(py::handle array, int cols, const std::string& name, size_t* rows);
// A 2-D uint8 array of `cols` columns, row-major (copied when strided).
std::vector<uint8_t> ByteRows(py::handle array, int cols, const std::string& name, size_t* rows);

// Row-major doubles as an N x cols float64 array (a copy the caller owns).
py::array_t<double> DoubleArray(const double* data, size_t rows, size_t cols);

// The keyword arguments of a call as a JSON object, refusing names not in
// `allowed` (a typo is an error, not a silently ignored option).
nlohmann::json Options(const py::kwargs& kwargs, std::initializer_list<const char*> allowed,
                       const std::string& function);
nlohmann::json Options(const py::kwargs& kwargs, const std::vector<std::string>& allowed,
                       const std::string& function);

// Typed values of an options object (Options() or a dict argument); nullopt
// when absent or None, ValueError naming `where` and the key when mistyped.
std::optional<double> NumberOption(const nlohmann::json& options, const char* key,
                                   const std::string& where);
std::optional<int64_t> IntegerOption(const nlohmann::json& options, const char* key,
                                     const std::string& where);
std::optional<bool> BoolOption(const nlohmann::json& options, const char* key,
                               const std::string& where);
std::optional<std::string> StringOption(const nlohmann::json& options, const char* key,
                                        const std::string& where);
// Refuses keys of a dict argument not in `allowed`.
void CheckKeys(const nlohmann::json& options, std::initializer_list<const char*> allowed,
               const std::string& where);
void CheckKeys(const nlohmann::json& options, const std::vector<std::string>& allowed,
               const std::string& where);

// Keyword arguments set through an option table (io/option_table.h): the
// CLI's flags by their Python names; None keeps the default of a
// non-nullable option and is null ("not set") for a nullable one. `own`: the
// function's other keywords, returned as they came.
template <typename T>
nlohmann::json SetFromTable(const py::kwargs& kwargs, std::span<const OptionField<T>> table,
                            std::initializer_list<const char*> own, const std::string& where,
                            T* options) {
  std::vector<std::string> allowed(own.begin(), own.end());
  for (const OptionField<T>& f : table) allowed.push_back(f.name);
  const nlohmann::json all = Options(kwargs, allowed, where);
  nlohmann::json own_values = nlohmann::json::object(), table_values = nlohmann::json::object();
  for (const auto& [key, value] : all.items()) {
    const bool is_own = std::find(own.begin(), own.end(), key) != own.end();
    if (is_own) {
      own_values[key] = value;
    } else if (!value.is_null() || FindOption(table, key)->nullable) {
      table_values[key] = value;
    }
  }
  SetOptions(options, table, table_values, where);
  return own_values;
}

}  // namespace linecloud::python
