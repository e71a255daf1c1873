// attack and audit: what a line cloud gives away, from Python.
#include <filesystem>

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "linecloud/io/lcm_format.h"
#include "linecloud/privacy/attack_option_table.h"
#include "linecloud/privacy/audit.h"
#include "linecloud/privacy/density_attack.h"
#include "linecloud/python/bindings.h"
#include "linecloud/python/convert.h"
#include "linecloud/util/error.h"

namespace linecloud::python {
namespace {

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

py::array_t<double> Attack(CloudArg cloud_or_path, const py::kwargs& kwargs) {
  DensityAttackOptions options;
  SetFromTable(kwargs, std::span(AttackOptionTable()), {}, "attack", &options);
  options.Check();
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

py::dict Audit(CloudArg cloud_or_path, const std::filesystem::path& model_dir,
               const py::kwargs& kwargs) {
  AuditOptions options;
  const nlohmann::json o =
      SetFromTable(kwargs, std::span(AuditOptionTable()), {"other", "out", "key_file", "key_store"},
                   "audit", &options);
  options.model_dir = model_dir.string();
  options.other_map_path = StringOption(o, "other", "audit").value_or("");
  options.out_dir = StringOption(o, "out", "audit").value_or("");
  options.key_file = StringOption(o, "key_file", "audit").value_or("");
  options.key_store = StringOption(o, "key_store", "audit").value_or("");
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
        "path: one recovered point per line (N x 3, in the cloud's order). Options: those of "
        "attack_options() (neighbours, refine_rounds, refine_neighbours, min_shared, threads, "
        "max_seconds).");
  m.def("audit", &Audit, py::arg("cloud"), py::arg("model_dir"),
        "The map owner's audit: the attacks run on the map and scored against the secret model's "
        "points (found through the model's key). Options: those of audit_options() (the "
        "attack's, metric_scale, density_attack, crossing_tolerance, recovered_within), and "
        "other (a second lifting's .lcm: the two-key attack), out (a folder for report.json, "
        "recovered.ply, audit.png), key_file, key_store. Returns report.json's content.");
  m.def(
      "attack_options", [] { return FromJson(OptionTableJson(std::span(AttackOptionTable()))); },
      "The density attack's options (name, flag, type, default, range, help), as attack and "
      "`linecloud attack` take them.");
  m.def(
      "audit_options", [] { return FromJson(OptionTableJson(std::span(AuditOptionTable()))); },
      "The audit's options (name, flag, type, default, range, help), as audit and `linecloud "
      "audit` take them.");
}

}  // namespace linecloud::python
