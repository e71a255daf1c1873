// lc.map: photos to a served map, from Python (mapping/map_project.h).
#include <filesystem>
#include <thread>

#include <pybind11/stl.h>

#include "linecloud/mapping/map_project.h"
#include "linecloud/python/bindings.h"
#include "linecloud/python/convert.h"
#include "linecloud/util/error.h"

namespace linecloud::python {
namespace {

std::string PathString(py::handle p) {
  return py::str(py::module_::import("os").attr("fspath")(p));
}

// One path or a list of them.
std::vector<std::string> Paths(py::handle value, const char* what) {
  if (py::isinstance<py::str>(value) || py::hasattr(value, "__fspath__"))
    return {PathString(value)};
  if (!py::isinstance<py::sequence>(value)) Fail("map: {}: a path or a list of paths", what);
  std::vector<std::string> out;
  for (py::handle item : value.cast<py::sequence>()) out.push_back(PathString(item));
  return out;
}

py::dict Map(py::handle photos, py::handle project, py::handle camera, py::handle out, bool update,
             const py::kwargs& kwargs) {
  MapOptions o;
  o.photos = Paths(photos, "photos");
  o.project_dir = PathString(project);
  if (!camera.is_none()) {
    if (py::isinstance<py::str>(camera)) {
      o.cameras = {camera.cast<std::string>()};
    } else {
      o.cameras = camera.cast<std::vector<std::string>>();
    }
  }
  if (!out.is_none()) o.out = PathString(out);
  o.update = update;
  o.sfm.threads = int(std::max(1u, std::thread::hardware_concurrency()));
  for (const auto& [key, value] : kwargs) {
    const std::string k = py::str(key);
    if (k == "pairs") {
      o.sfm.pairs = ParsePairSelection(value.cast<std::string>(), "map: pairs");
    } else if (k == "threads") {
      o.sfm.threads = value.cast<int>();
    } else if (k == "key_store") {
      o.key_store = PathString(value);
    } else if (k == "key_file") {
      o.key_file = PathString(value);
    } else if (k == "ground_truth") {
      o.ground_truth = PathString(value);
    } else if (k == "stereo") {
      o.stereo = value.cast<std::string>();
    } else if (k == "audit") {
      o.audit = value.cast<bool>();
    } else if (k == "seed") {
      o.sfm.seed = value.cast<uint64_t>();
    } else if (k == "colmap") {
      o.sfm.colmap.executable = PathString(value);
    } else {
      Fail(
          "map: unknown option '{}' (pairs, threads, key_store, key_file, ground_truth, stereo, "
          "audit, seed, colmap)",
          k);
    }
  }
  nlohmann::ordered_json report;
  {
    GilReleased release;
    report = BuildMap(o).ToJson();
  }
  return FromJson(report).cast<py::dict>();
}

}  // namespace

void BindMapping(py::module_& m) {
  m.def("map", &Map, py::arg("photos"), py::arg("project"), py::arg("camera") = py::none(),
        py::arg("out") = py::none(), py::arg("update") = false,
        "Photos to a served map, as `linecloud map`: SIFT, pairs, COLMAP's mapper, lift under the "
        "project's key, audit; out='MAPS_DIR/ID' writes ID.lcm, ID.json, ID.audit.json. photos: "
        "files or folders; camera: COLMAP's 'MODEL W H PARAMS...' (or a list, one per photo size). "
        "A run interrupted before continues from its last finished stage. update=True registers "
        "new photos into the released map (every released point keeps its line). Options: pairs "
        "('auto', 'exhaustive', 'vocab-tree', 'sequential'), threads, key_store, key_file, "
        "ground_truth (images.txt of survey poses), stereo ('A,B,METRES': a rig's baseline, the "
        "map in metres), audit (bool), seed, colmap. Returns the "
        "report (report.json's content).");
}

}  // namespace linecloud::python
