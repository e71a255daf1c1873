// LineCloud, lift and read_colmap_model: maps in and out of Python.
#include <filesystem>
#include <optional>

#include <fmt/format.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "linecloud/io/colmap_model.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/io/lift_model.h"
#include "linecloud/io/track_descriptors.h"
#include "linecloud/lifting/sparsify.h"
#include "linecloud/privacy/lift_option_table.h"
#include "linecloud/privacy/map_lifting.h"
#include "linecloud/io/line_cloud_info.h"
#include "linecloud/lifting/line_cloud.h"
#include "linecloud/python/bindings.h"
#include "linecloud/python/convert.h"
#include "linecloud/util/error.h"

namespace linecloud::python {
namespace {

py::array_t<double> Lines(const LineCloud& cloud) {
  py::array_t<double> out({static_cast<py::ssize_t>(cloud.size()), py::ssize_t{6}});
  double* row = out.mutable_data();
  for (const PluckerLine& line : cloud.lines) {
    for (int k = 0; k < 3; ++k) row[k] = line.v[k];
    for (int k = 0; k < 3; ++k) row[3 + k] = line.w[k];
    row += 6;
  }
  return out;
}

py::object Descriptors(const LineCloud& cloud) {
  if (!cloud.has_descriptors()) return py::none();
  py::array_t<uint8_t> out(
      {static_cast<py::ssize_t>(cloud.size()), static_cast<py::ssize_t>(cloud.descriptor_dim)});
  std::copy(cloud.descriptors.begin(), cloud.descriptors.end(), out.mutable_data());
  return out;
}

// A cloud from arrays: lines N x 6 (v unit, w = X x v), ids N (unique), and
// optionally descriptors N x D uint8. Checked as a file's content would be.
LineCloud MakeCloud(ArrayArg lines, ArrayArg ids, VectorArg descriptors) {
  LineCloud cloud;
  size_t n = 0;
  const std::vector<double> rows = FiniteRows(lines, 6, "lines", &n);
  cloud.lines.resize(n);
  for (size_t i = 0; i < n; ++i) {
    cloud.lines[i] =
        PluckerLine(Eigen::Vector3d(rows[6 * i], rows[6 * i + 1], rows[6 * i + 2]),
                    Eigen::Vector3d(rows[6 * i + 3], rows[6 * i + 4], rows[6 * i + 5]));
  }
  const auto id_array = py::array::ensure(ids);
  if (!id_array || id_array.ndim() != 1 ||
      (id_array.dtype().kind() != 'u' && id_array.dtype().kind() != 'i')) {
    throw py::type_error("ids: expected a 1-D integer array");
  }
  const auto u64 =
      py::array_t<uint64_t, py::array::c_style | py::array::forcecast>::ensure(id_array);
  if (id_array.dtype().kind() == 'i' && py::bool_(id_array.attr("__lt__")(0).attr("any")())) {
    Fail("ids: negative id");
  }
  cloud.ids.assign(u64.data(), u64.data() + u64.size());
  if (cloud.ids.size() != n) Fail("ids: {} ids for {} lines", cloud.ids.size(), n);
  if (!descriptors.is_none()) {
    const auto array = py::array::ensure(descriptors);
    if (!array || array.ndim() != 2) throw py::type_error("descriptors: expected an N x D array");
    size_t rows_d = 0;
    cloud.descriptor_dim = static_cast<int>(array.shape(1));
    cloud.descriptors = ByteRows(array, cloud.descriptor_dim, "descriptors", &rows_d);
    if (rows_d != n) Fail("descriptors: {} rows for {} lines", rows_d, n);
    cloud.descriptor_type = "colmap-sift-uint8";
    cloud.descriptor_aggregation = "given";
  }
  cloud.Check("LineCloud");
  return cloud;
}

// `lift` with the CLI's options (lift_option_table.h; the same use case: LiftModelWith).
LineCloud Lift(const std::filesystem::path& model_dir, const py::kwargs& kwargs) {
  LiftSettings s;
  const nlohmann::json paths =
      SetFromTable(kwargs, std::span(LiftOptionTable()),
                   {"database", "out", "key_store", "key_file"}, "lift", &s);
  s.options.model_dir = model_dir.string();
  s.options.database = StringOption(paths, "database", "lift").value_or("");
  s.options.out_path = StringOption(paths, "out", "lift").value_or("");
  s.options.key_store = StringOption(paths, "key_store", "lift").value_or("");
  s.options.key_file = StringOption(paths, "key_file", "lift").value_or("");
  GilReleased release;
  return LiftModelWith(s.options, s.lifting).cloud;
}

py::dict ModelToDict(const Reconstruction& model) {
  py::dict cameras;
  for (const auto& [id, camera] : model.cameras) cameras[py::int_(id)] = CameraToDict(camera);
  py::dict images;
  for (const auto& [id, image] : model.images) {
    py::dict d;
    d["name"] = image.name;
    d["camera_id"] = image.camera_id;
    d["cam_from_world"] =
        PoseToDict(image.cam_from_world.rotation, image.cam_from_world.translation);
    std::vector<double> xy;
    py::array_t<int64_t> ids(static_cast<py::ssize_t>(image.points2D.size()));
    for (size_t k = 0; k < image.points2D.size(); ++k) {
      xy.push_back(image.points2D[k].xy.x());
      xy.push_back(image.points2D[k].xy.y());
      const uint64_t id = image.points2D[k].point3D_id;
      ids.mutable_data()[k] = id == kInvalidPoint3DId ? -1 : static_cast<int64_t>(id);
    }
    d["points2D"] = DoubleArray(xy.data(), image.points2D.size(), 2);
    d["point3D_ids"] = ids;
    images[py::int_(id)] = d;
  }
  const std::vector<uint64_t> ids = model.SortedPoint3DIds();
  std::vector<double> xyz;
  py::array_t<uint64_t> id_array(static_cast<py::ssize_t>(ids.size()));
  py::array_t<uint8_t> colors({static_cast<py::ssize_t>(ids.size()), py::ssize_t{3}});
  py::array_t<double> errors(static_cast<py::ssize_t>(ids.size()));
  for (size_t k = 0; k < ids.size(); ++k) {
    const Point3D& p = model.points3D.at(ids[k]);
    for (int c = 0; c < 3; ++c) {
      xyz.push_back(p.xyz[c]);
      colors.mutable_data()[3 * k + c] = p.color[c];
    }
    id_array.mutable_data()[k] = ids[k];
    errors.mutable_data()[k] = p.error;
  }
  py::dict points;
  points["ids"] = id_array;
  points["xyz"] = DoubleArray(xyz.data(), ids.size(), 3);
  points["colors"] = colors;
  points["errors"] = errors;
  py::dict out;
  out["cameras"] = cameras;
  out["images"] = images;
  out["points3D"] = points;
  return out;
}

}  // namespace

void BindLineCloud(py::module_& m) {
  py::class_<LineCloud>(m, "LineCloud",
                        "A line-cloud map: lines (Pluecker v, w), their ids and optional "
                        "descriptors, and nothing that could hold a point.")
      .def(py::init(&MakeCloud), py::arg("lines"), py::arg("ids"),
           py::arg("descriptors") = py::none(),
           "A cloud from arrays: lines N x 6 (v unit, w = X x v), ids N, descriptors N x D "
           "uint8 or None.")
      .def_static(
          "read",
          [](const std::filesystem::path& path) {
            const std::string p = path.string();
            GilReleased release;
            return ReadLineCloud(p);
          },
          py::arg("path"), "Read a .lcm file (checked: magic, version, checksum, content).")
      .def(
          "write",
          [](const LineCloud& cloud, const std::filesystem::path& path) {
            const std::string p = path.string();
            GilReleased release;
            WriteLineCloud(cloud, p);
          },
          py::arg("path"), "Write a .lcm file (atomically: a reader sees the old or the new).")
      .def("__len__", &LineCloud::size)
      .def_property_readonly("lines", &Lines, "N x 6 float64: direction v, moment w (a copy)")
      .def_property_readonly(
          "ids",
          [](const LineCloud& c) {
            return py::array_t<uint64_t>(static_cast<py::ssize_t>(c.ids.size()), c.ids.data());
          },
          "N uint64 line ids (a copy)")
      .def_property_readonly("descriptors", &Descriptors, "N x D uint8, or None (a copy)")
      .def_property_readonly(
          "encoding", [](const LineCloud& c) { return std::string(LineEncodingName(c.encoding)); })
      .def_property_readonly("gravity",
                             [](const LineCloud& c) -> py::object {
                               if (!c.gravity) return py::none();
                               return py::make_tuple(c.gravity->x(), c.gravity->y(),
                                                     c.gravity->z());
                             })
      .def(
          "info", [](const LineCloud& c) { return FromJson(LineCloudInfo(c)); },
          "What `linecloud info --json` says of the map (without the file fields).")
      .def("__repr__", [](const LineCloud& c) {
        return fmt::format("<linecloud.LineCloud: {} lines, {}, {}>", c.size(),
                           LineEncodingName(c.encoding),
                           c.has_descriptors() ? fmt::format("{}-D descriptors", c.descriptor_dim)
                                               : std::string("no descriptors"));
      });

  m.def(
      "lift",
      [](ModelArg model, PathArg database, PathArg out, PathArg key_store, PathArg key_file,
         FlagArg compact, FlagArg force, py::kwargs kwargs) -> LineCloud {
        // The positional parameters of SPEC's lift(model_dir, database, out, key_store,
        // key_file, compact, force); the rest keywords of LiftOptionTable.
        const std::pair<const char*, py::handle> given[] = {
            {"database", database}, {"out", out},         {"key_store", key_store},
            {"key_file", key_file}, {"compact", compact}, {"force", force}};
        for (const auto& [name, value] : given) {
          if (!value.is_none()) kwargs[name] = value;
        }
        // A pycolmap.Reconstruction (or any object that writes a COLMAP model
        // into a folder: .write(path)): written to a temporary folder, lifted
        // from there (the key store knows a model by its tracks, not its path).
        const bool path = py::isinstance<py::str>(model) || py::hasattr(model, "__fspath__");
        if (path) return Lift(py::cast<std::filesystem::path>(model), kwargs);
        if (py::hasattr(model, "write")) {
          py::object folder =
              py::module_::import("tempfile")
                  .attr("TemporaryDirectory")(py::arg("prefix") = "linecloud-model-");
          const std::string folder_path = py::str(folder.attr("name"));
          std::optional<LineCloud> result;
          try {
            model.attr("write")(folder_path);
            result.emplace(Lift(folder_path, kwargs));
          } catch (...) {
            folder.attr("cleanup")();
            throw;
          }
          folder.attr("cleanup")();
          return std::move(*result);
        }
        throw py::type_error(
            fmt::format("lift: model_dir must be a COLMAP model's folder (str or os.PathLike) or a "
                        "pycolmap.Reconstruction, got {}",
                        TypeName(model)));
      },
      py::arg("model_dir"), py::arg("database") = py::none(), py::arg("out") = py::none(),
      py::arg("key_store") = py::none(), py::arg("key_file") = py::none(),
      py::arg("compact") = py::none(), py::arg("force") = py::none(),
      "Lift a COLMAP model (a folder, or a pycolmap.Reconstruction) to a line cloud under the "
      "model's one key (the CLI's `lift`, its "
      "key-store rules and options: one point, one line). database: descriptors from COLMAP's "
      "database; out: also write the .lcm; key_store: the store's folder (default "
      "LINECLOUD_KEY_STORE or ~/.local/share/linecloud/keys); key_file: the model's key file. "
      "Keywords: those of lift_options() (descriptor, compact, force, gravity, sparsify, "
      "sparsify_mode, resist_attack, same_place, allow_shared_key), as `linecloud lift` takes "
      "them.");
  m.def(
      "lift_options", [] { return FromJson(OptionTableJson(std::span(LiftOptionTable()))); },
      "lift's options (name, flag, type, default, range, help), as lift and `linecloud lift` "
      "take them.");

  m.def(
      "read_colmap_model",
      [](const std::filesystem::path& path) {
        Reconstruction model;
        {
          const std::string p = path.string();
          GilReleased release;
          model = ReadColmapModel(p);
        }
        return ModelToDict(model);
      },
      py::arg("path"),
      "A COLMAP model folder (text or binary) as {\"cameras\": {id: camera}, \"images\": {id: "
      "{name, camera_id, cam_from_world, points2D, point3D_ids}}, \"points3D\": {ids, xyz, "
      "colors, errors}}; point3D_ids are -1 where a keypoint has no point.");
}

}  // namespace linecloud::python
