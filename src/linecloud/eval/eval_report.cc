#include "linecloud/eval/eval_report.h"

#include <cmath>
#include <limits>

#include "linecloud/io/json_util.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using nlohmann::json;
constexpr double kInf = std::numeric_limits<double>::infinity();

// JSON has no infinity or NaN: such a value is written as null.
json FiniteOrNull(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }
json OptionalOrNull(const std::optional<double>& v) { return v ? FiniteOrNull(*v) : json(nullptr); }

using Fields = JsonFields;

json NumbersToJson(const std::vector<double>& v) {
  json a = json::array();
  for (double x : v) a.push_back(FiniteOrNull(x));
  return a;
}

json ToJson(const InitialRefined& e) { return {{"initial", e.initial}, {"refined", e.refined}}; }
InitialRefined InitialRefinedFrom(const Fields& f) {
  return {f.Number("initial"), f.Number("refined")};
}

json ToJson(const ReprojectionErrors& e) {
  return {{"initial", e.initial},
          {"refined", e.refined},
          {"point_initial", e.point_initial},
          {"point_refined", e.point_refined}};
}
ReprojectionErrors ReprojectionFrom(const Fields& f) {
  return {f.Number("initial"), f.Number("refined"), f.Number("point_initial"),
          f.Number("point_refined")};
}

json ToJson(const EvalQueryResult& r) {
  json q = {{"group", r.group},
            {"query", r.query},
            {"correspondences", r.correspondences},
            {"success", r.success},
            {"rotation_deg", ToJson(r.rotation_deg)},
            {"translation", ToJson(r.translation)},
            {"iterations", r.iterations},
            {"inlier_ratio", r.inlier_ratio},
            {"mean_solutions", r.mean_solutions},
            {"solver_us", r.solver_us},
            {"ransac_ms", r.ransac_ms},
            {"refine_ms", r.refine_ms},
            {"reprojection_px", ToJson(r.reprojection_px)}};
  if (r.noise_px) q["noise_px"] = *r.noise_px;
  if (r.rotation_bound_deg) q["rotation_bound_deg"] = FiniteOrNull(*r.rotation_bound_deg);
  if (!r.error.empty()) q["error"] = r.error;
  return q;
}
EvalQueryResult QueryResultFrom(const Fields& f) {
  EvalQueryResult r;
  r.group = f.String("group");
  r.query = f.String("query");
  r.correspondences = f.Int("correspondences");
  r.success = f.Bool("success");
  r.rotation_deg = InitialRefinedFrom(f.Object("rotation_deg"));
  r.translation = InitialRefinedFrom(f.Object("translation"));
  r.iterations = f.Int("iterations");
  r.inlier_ratio = f.Number("inlier_ratio");
  r.mean_solutions = f.Number("mean_solutions");
  r.solver_us = f.Number("solver_us");
  r.ransac_ms = f.Number("ransac_ms");
  r.refine_ms = f.Number("refine_ms");
  r.reprojection_px = ReprojectionFrom(f.Object("reprojection_px"));
  r.noise_px = f.Optional("noise_px", std::numeric_limits<double>::quiet_NaN());
  r.rotation_bound_deg = f.Optional("rotation_bound_deg", kInf);
  r.error = f.StringOr("error", "");
  return r;
}

json ToJson(const EvalMethodReport& m) {
  json per_query = json::array();
  for (const EvalQueryResult& r : m.per_query) per_query.push_back(ToJson(r));
  return {{"queries", m.queries},
          {"localized", m.localized},
          {"median_rotation_deg", m.median_rotation_deg},
          {"median_translation", m.median_translation},
          {"median_rotation_deg_initial", m.median_rotation_deg_initial},
          {"median_translation_initial", m.median_translation_initial},
          {"recall", m.recall},
          {"mean_iterations", m.mean_iterations},
          {"inlier_ratio", m.inlier_ratio},
          {"mean_solutions", m.mean_solutions},
          {"solver_us", m.solver_us},
          {"ransac_ms", m.ransac_ms},
          {"refine_ms", m.refine_ms},
          {"reprojection_px", ToJson(m.reprojection_px)},
          {"median_noise_px", FiniteOrNull(m.median_noise_px)},
          {"median_rotation_bound_deg", FiniteOrNull(m.median_rotation_bound_deg)},
          {"rms_rotation_error_over_bound", OptionalOrNull(m.rms_rotation_error_over_bound)},
          {"per_query", per_query}};
}
EvalMethodReport MethodReportFrom(const Fields& f) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EvalMethodReport m;
  m.queries = f.Int("queries");
  m.localized = f.Int("localized");
  m.median_rotation_deg = f.NumberOrNull("median_rotation_deg", nan);
  m.median_translation = f.NumberOrNull("median_translation", nan);
  m.median_rotation_deg_initial = f.NumberOrNull("median_rotation_deg_initial", nan);
  m.median_translation_initial = f.NumberOrNull("median_translation_initial", nan);
  const Fields recall = f.Object("recall");
  for (const auto& [key, value] : recall.raw().items()) m.recall[key] = recall.Number(key.c_str());
  m.mean_iterations = f.Number("mean_iterations");
  m.inlier_ratio = f.Number("inlier_ratio");
  m.mean_solutions = f.Number("mean_solutions");
  m.solver_us = f.Number("solver_us");
  m.ransac_ms = f.Number("ransac_ms");
  m.refine_ms = f.Number("refine_ms");
  m.reprojection_px = ReprojectionFrom(f.Object("reprojection_px"));
  m.median_noise_px = f.NumberOrNull("median_noise_px", nan);
  m.median_rotation_bound_deg = f.NumberOrNull("median_rotation_bound_deg", kInf);
  if (!f.At("rms_rotation_error_over_bound").is_null())
    m.rms_rotation_error_over_bound = f.Number("rms_rotation_error_over_bound");
  const json& rows = f.Array("per_query");
  for (size_t i = 0; i < rows.size(); ++i)
    m.per_query.push_back(
        QueryResultFrom(Fields(rows[i], f.Where(fmt::format("per_query[{}]", i)))));
  return m;
}

json ToJson(const DirectMatchingAttempt& a) {
  json row = json::object();
  if (a.attempted) {
    row["ransac_ms"] = a.ransac_ms;
    row["iterations"] = a.iterations;
    row["uniform_iterations"] = a.uniform_iterations;
    row["inliers"] = a.inliers;
    row["success"] = a.success;
    if (!a.camera_inliers.empty()) row["camera_inliers"] = a.camera_inliers;
    row["stop_reason"] = a.stop_reason;
    if (a.sigma_px) row["sigma_px"] = *a.sigma_px;
    if (a.sigma_rotation_deg) row["sigma_rotation_deg"] = *a.sigma_rotation_deg;
    if (a.sigma_position) row["sigma_position"] = *a.sigma_position;
  }
  row["rotation_deg"] = a.rotation_deg;
  row["translation"] = a.translation;
  if (!a.failure.empty()) row["failure"] = a.failure;
  return row;
}
DirectMatchingAttempt AttemptFrom(const Fields& f) {
  DirectMatchingAttempt a;
  a.attempted = f.Has("success");
  if (a.attempted) {
    a.ransac_ms = f.Number("ransac_ms");
    a.iterations = f.Int("iterations");
    a.uniform_iterations = f.Int("uniform_iterations");
    a.inliers = f.Int("inliers");
    a.success = f.Bool("success");
    if (f.Has("camera_inliers")) {
      for (double n : f.Numbers("camera_inliers")) a.camera_inliers.push_back(static_cast<int>(n));
    }
    a.stop_reason = f.String("stop_reason");
    a.sigma_px = f.Optional("sigma_px", std::numeric_limits<double>::quiet_NaN());
    if (f.Has("sigma_rotation_deg")) a.sigma_rotation_deg = f.Number("sigma_rotation_deg");
    if (f.Has("sigma_position")) a.sigma_position = f.Number("sigma_position");
  }
  a.rotation_deg = f.Number("rotation_deg");
  a.translation = f.Number("translation");
  a.failure = f.StringOr("failure", "");
  return a;
}

// Rows hold their own fields and one object per method, keyed by its name.
void AddAttempts(const std::map<std::string, DirectMatchingAttempt>& methods, json* row) {
  for (const auto& [name, a] : methods) (*row)[name] = ToJson(a);
}
std::map<std::string, DirectMatchingAttempt> AttemptsFrom(
    const Fields& f, std::initializer_list<const char*> own_fields) {
  std::map<std::string, DirectMatchingAttempt> methods;
  for (const auto& [key, value] : f.raw().items()) {
    bool own = false;
    for (const char* o : own_fields) own = own || key == o;
    if (!own) methods[key] = AttemptFrom(f.Object(key.c_str()));
  }
  return methods;
}

json ToJson(const DirectMatchingPhoto& p) {
  json row = {{"group", p.group},     {"image", p.image},           {"features", p.features},
              {"matches", p.matches}, {"extract_ms", p.extract_ms}, {"match_ms", p.match_ms}};
  AddAttempts(p.methods, &row);
  return row;
}
DirectMatchingPhoto PhotoFrom(const Fields& f) {
  DirectMatchingPhoto p;
  p.group = f.String("group");
  p.image = f.String("image");
  p.features = f.Int("features");
  p.matches = f.Int("matches");
  p.extract_ms = f.Number("extract_ms");
  p.match_ms = f.Number("match_ms");
  p.methods = AttemptsFrom(f, {"group", "image", "features", "matches", "extract_ms", "match_ms"});
  return p;
}

json ToJson(const DirectMatchingRig& r) {
  json row = {
      {"group", r.group},
      {"images", r.images},
      {"matches", r.matches},
      {"rig_error",
       {{"rotation_deg", r.rig_error_rotation_deg}, {"translation", r.rig_error_translation}}}};
  AddAttempts(r.methods, &row);
  return row;
}
DirectMatchingRig RigFrom(const Fields& f) {
  DirectMatchingRig r;
  r.group = f.String("group");
  r.images = f.Strings("images");
  r.matches = f.Int("matches");
  const Fields e = f.Object("rig_error");
  r.rig_error_rotation_deg = e.Number("rotation_deg");
  r.rig_error_translation = e.Number("translation");
  r.methods = AttemptsFrom(f, {"group", "images", "matches", "rig_error"});
  return r;
}

json ToJson(const DirectMatchingSummary& m) {
  return {{"queries", m.queries},
          {"localized", m.localized},
          {"median_rotation_deg", m.median_rotation_deg},
          {"median_translation", m.median_translation},
          {"mean_ms",
           {{"extract", m.mean_ms.extract},
            {"match", m.mean_ms.match},
            {"ransac", m.mean_ms.ransac},
            {"refine", m.mean_ms.refine}}},
          {"mean_ransac_ms",
           {{"solver", m.mean_solver_ms},
            {"scoring", m.mean_scoring_ms},
            {"local_optimization", m.mean_local_optimization_ms}}},
          {"mean_iterations", m.mean_iterations}};
}
DirectMatchingSummary SummaryFrom(const Fields& f) {
  DirectMatchingSummary m;
  m.queries = f.Int("queries");
  m.localized = f.Int("localized");
  m.median_rotation_deg = f.Number("median_rotation_deg");
  m.median_translation = f.Number("median_translation");
  const Fields t = f.Object("mean_ms");
  m.mean_ms = {t.Number("extract"), t.Number("match"), t.Number("ransac"), t.Number("refine")};
  const Fields r = f.Object("mean_ransac_ms");
  m.mean_solver_ms = r.Number("solver");
  m.mean_scoring_ms = r.Number("scoring");
  m.mean_local_optimization_ms = r.Number("local_optimization");
  m.mean_iterations = f.Number("mean_iterations");
  return m;
}

json SweepValues(const std::map<std::string, std::vector<double>>& by_method) {
  json j = json::object();
  for (const auto& [name, values] : by_method) j[name] = NumbersToJson(values);
  return j;
}
std::map<std::string, std::vector<double>> SweepValuesFrom(const Fields& f, size_t levels) {
  std::map<std::string, std::vector<double>> out;
  for (const auto& [name, value] : f.raw().items()) {
    out[name] = f.Numbers(name.c_str());
    if (out[name].size() != levels)
      Fail("{}: {} values for {} levels", f.Where(name), out[name].size(), levels);
  }
  return out;
}

// Fig. 7's sweep is keyed "dropped" and "median_translation", Fig. 8's "noise_px",
// "queries_per_level" and "median_translation_relative".
json DensityToJson(const EvalSweep& s) {
  return {{"dropped", s.levels},
          {"median_rotation_deg", SweepValues(s.median_rotation_deg)},
          {"median_translation", SweepValues(s.median_translation)}};
}
json NoiseToJson(const EvalSweep& s) {
  return {{"noise_px", s.levels},
          {"queries_per_level", s.queries_per_level},
          {"median_rotation_deg", SweepValues(s.median_rotation_deg)},
          {"median_translation_relative", SweepValues(s.median_translation)}};
}
EvalSweep SweepFrom(const Fields& f, const char* levels, const char* translation) {
  EvalSweep s;
  s.levels = f.Numbers(levels);
  s.median_rotation_deg = SweepValuesFrom(f.Object("median_rotation_deg"), s.levels.size());
  s.median_translation = SweepValuesFrom(f.Object(translation), s.levels.size());
  if (f.Has("queries_per_level")) s.queries_per_level = f.Int("queries_per_level");
  return s;
}

}  // namespace

std::optional<EvalReport::GroundTruth> EvalReport::ground_truth() const {
  if (!reconstruction.is_object() || !reconstruction.contains("ground_truth")) return std::nullopt;
  const Fields g(reconstruction["ground_truth"], "reconstruction.ground_truth");
  return GroundTruth{g.Int("aligned_on"), g.Number("max_rotation_deg"), g.Number("max_position_m")};
}

json ToJson(const DirectMatchingReport& d) {
  json methods = json::object(), per_query = json::array(), per_rig = json::array();
  for (const auto& [name, m] : d.methods) methods[name] = ToJson(m);
  for (const DirectMatchingPhoto& p : d.per_query) per_query.push_back(ToJson(p));
  for (const DirectMatchingRig& r : d.per_rig) per_rig.push_back(ToJson(r));
  return {
      {"thresholds", {{"rotation_deg", d.max_rotation_deg}, {"translation", d.max_translation}}},
      {"features", d.features},
      {"methods", methods},
      {"per_query", per_query},
      {"per_rig", per_rig}};
}

DirectMatchingReport DirectMatchingReportFromJson(const json& j, const std::string& where) {
  const Fields f(j, where);
  DirectMatchingReport d;
  const Fields t = f.Object("thresholds");
  d.max_rotation_deg = t.Number("rotation_deg");
  d.max_translation = t.Number("translation");
  d.features = f.String("features");
  const Fields methods = f.Object("methods");
  for (const auto& [name, value] : methods.raw().items())
    d.methods[name] = SummaryFrom(methods.Object(name.c_str()));
  const json& photos = f.Array("per_query");
  for (size_t i = 0; i < photos.size(); ++i)
    d.per_query.push_back(PhotoFrom(Fields(photos[i], f.Where(fmt::format("per_query[{}]", i)))));
  const json& rigs = f.Array("per_rig");
  for (size_t i = 0; i < rigs.size(); ++i)
    d.per_rig.push_back(RigFrom(Fields(rigs[i], f.Where(fmt::format("per_rig[{}]", i)))));
  return d;
}

json ToJson(const EvalReport& r) {
  json methods = json::object();
  for (const auto& [name, m] : r.methods) methods[name] = ToJson(m);
  json j = {{"dataset", r.dataset},
            {"units", r.units},
            {"threshold_px", r.threshold_px},
            {"sparsify", r.sparsify},
            {"lifting", r.lifting},
            {"noise_px", r.noise_px},
            {"seed", r.seed},
            {"gravity_source", r.gravity_source},
            {"reconstruction", r.reconstruction},
            {"methods", methods}};
  if (r.direct_matching) j["direct_matching"] = ToJson(*r.direct_matching);
  if (r.density) j["density"] = DensityToJson(*r.density);
  if (r.noise) j["noise"] = NoiseToJson(*r.noise);
  return j;
}

EvalReport EvalReportFromJson(const json& j, const std::string& where) {
  const Fields f(j, where);
  EvalReport r;
  r.dataset = f.String("dataset");
  r.units = f.String("units");
  r.threshold_px = f.Number("threshold_px");
  r.sparsify = f.Number("sparsify");
  r.lifting = f.String("lifting");
  r.noise_px = f.Number("noise_px");
  if (!f.At("seed").is_number_unsigned()) Fail("{}: not a seed (an integer >= 0)", f.Where("seed"));
  r.seed = f.At("seed").get<uint64_t>();
  r.gravity_source = f.String("gravity_source");
  r.reconstruction = f.At("reconstruction");
  const Fields methods = f.Object("methods");
  for (const auto& [name, value] : methods.raw().items())
    r.methods[name] = MethodReportFrom(methods.Object(name.c_str()));
  if (f.Has("direct_matching"))
    r.direct_matching =
        DirectMatchingReportFromJson(f.At("direct_matching"), f.Where("direct_matching"));
  if (f.Has("density")) r.density = SweepFrom(f.Object("density"), "dropped", "median_translation");
  if (f.Has("noise"))
    r.noise = SweepFrom(f.Object("noise"), "noise_px", "median_translation_relative");
  return r;
}

EvalReport ReadEvalReport(const std::string& path) {
  return EvalReportFromJson(ReadJsonFile(path), path);
}

}  // namespace linecloud
