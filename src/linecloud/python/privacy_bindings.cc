// attack and audit: what a line cloud gives away, from Python.
#include <filesystem>

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "linecloud/io/lcm_format.h"
#include "linecloud/privacy/audit.h"
#include "linecloud/privacy/density_attack.h"
#include "linecloud/python/bindings.h"
#include "linecloud/python/convert.h"
#include "linecloud/util/error.h"

namespace linecloud::python {
namespace {

void SetAttackOptions(const nlohmann::json& o, const std::string& where, DensityAttackOptions* a) {
  auto integer = [&](const char* key, int* out) {
    if (auto v = IntegerOption(o, key, where)) {
      if (*v < 0 || *v > 1 << 30) Fail("{}: {} must be in [0, 2^30], got {}", where, key, *v);
      *out = static_cast<int>(*v);
    }
  };
  integer("neighbours", &a->line_neighbours);
  integer("refine_rounds", &a->refine_rounds);
  integer("refine_neighbours", &a->refine_neighbours);
  integer("min_shared", &a->min_shared);
  integer("threads", &a->threads);
  if (auto v = NumberOption(o, "max_seconds", where)) a->max_seconds = *v;
  a->Check();
}

constexpr std::initializer_list<const char*> kAttackKeys = {
    "neighbours", "refine_rounds", "refine_neighbours", "min_shared", "threads", "max_seconds"};

// A LineCloud or a .lcm path.
LineCloud CloudOf(py::handle cloud, std::string* name) {
  if (py::isinstance<LineCloud>(cloud)) {
    *name = "LineCloud";
    return cloud.cast<LineCloud>();
  }
  *name = py::str(py::module_::import("os").attr("fspath")(cloud));
  GilReleased release;
  return ReadLineCloud(*name);
}

py::array_t<double> Attack(py::handle cloud_or_path, const py::kwargs& kwargs) {
  const nlohmann::json o = Options(kwargs, kAttackKeys, "attack");
  DensityAttackOptions options;
  SetAttackOptions(o, "attack", &options);
  std::string name;
  const LineCloud cloud = CloudOf(cloud_or_path, &name);
  DensityAttackResult r;
  {
    GilReleased release;
    r = RunDensityAttack(cloud, options);
  }
  std::vector<double> xyz;
  xyz.reserve(3 * r.points.size());
  for (const Eigen::Vector3d& p : r.points) xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
  return DoubleArray(xyz.data(), r.points.size(), 3);
}

py::dict Audit(py::handle cloud_or_path, const std::filesystem::path& model_dir,
               const py::kwargs& kwargs) {
  const nlohmann::json o =
      Options(kwargs,
              {"neighbours", "refine_rounds", "refine_neighbours", "min_shared", "threads",
               "max_seconds", "other", "out", "key_file", "key_store", "metric_scale",
               "density_attack", "crossing_tolerance", "recovered_within"},
              "audit");
  AuditOptions options;
  nlohmann::json attack = nlohmann::json::object();
  for (const char* key : kAttackKeys) {
    if (o.contains(key)) attack[key] = o[key];
  }
  SetAttackOptions(attack, "audit", &options.attack);
  options.model_dir = model_dir.string();
  options.other_map_path = StringOption(o, "other", "audit").value_or("");
  options.out_dir = StringOption(o, "out", "audit").value_or("");
  options.key_file = StringOption(o, "key_file", "audit").value_or("");
  options.key_store = StringOption(o, "key_store", "audit").value_or("");
  options.metric_scale = NumberOption(o, "metric_scale", "audit").value_or(0);
  options.skip_density_attack = !BoolOption(o, "density_attack", "audit").value_or(true);
  options.crossing_tolerance =
      NumberOption(o, "crossing_tolerance", "audit").value_or(options.crossing_tolerance);
  options.recovered_within =
      NumberOption(o, "recovered_within", "audit").value_or(options.recovered_within);
  const LineCloud cloud = CloudOf(cloud_or_path, &options.map_path);
  nlohmann::ordered_json report;
  {
    GilReleased release;
    report = ToJson(RunAudit(cloud, options));
  }
  return FromJson(report).cast<py::dict>();
}

}  // namespace

void BindPrivacy(py::module_& m) {
  m.def("attack", &Attack, py::arg("cloud"),
        "The density attack of Chelani, Kahl and Sattler (CVPR 2021) on a LineCloud or .lcm "
        "path: one recovered point per line (N x 3, in the cloud's order). Options: neighbours, "
        "refine_rounds, refine_neighbours, min_shared, threads, max_seconds.");
  m.def("audit", &Audit, py::arg("cloud"), py::arg("model_dir"),
        "The map owner's audit: the attacks run on the map and scored against the secret model's "
        "points (found through the model's key). Options: those of attack, and other (a second "
        "lifting's .lcm: the two-key attack), out (a folder for report.json, recovered.ply, "
        "audit.png), key_file, key_store, metric_scale, density_attack (False: skip it), "
        "crossing_tolerance and recovered_within (the pairing attacks' shares of the scene "
        "diagonal). Returns report.json's content.");
}

}  // namespace linecloud::python
