#include "linecloud/util/log.h"
#include "linecloud/eval/colmap_registration.h"

#include <sqlite3.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <optional>

#include <fmt/format.h>

#include "linecloud/eval/eval_run.h"
#include "linecloud/util/statistics.h"
#include "linecloud/io/json_util.h"
#include "linecloud/synthetic/localization_instances.h"
#include "linecloud/util/clock.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

using ojson = nlohmann::ordered_json;
constexpr double kDeg = 180.0 / std::numbers::pi;
constexpr int64_t kMaxNumImages = 2147483647;  // COLMAP's pair id = id1 * this + id2

void Exec(sqlite3* db, const std::string& sql, const std::string& path) {
  char* message = nullptr;
  if (sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &message) != SQLITE_OK) {
    const std::string what = message ? message : "unknown error";
    sqlite3_free(message);
    Fail("{}: {} ({})", path, what, sql);
  }
}

// A copy of `source` (read through SQLite, so a pending WAL is included)
// without the images `names`: their rows, features and every pair with them.
// Returns the removed images' camera ids by name.
std::map<std::string, int64_t> DatabaseWithout(const std::string& source, const std::string& target,
                                               const std::vector<std::string>& names) {
  std::filesystem::remove(target);
  sqlite3 *src = nullptr, *dst = nullptr;
  if (sqlite3_open_v2(source.c_str(), &src, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK ||
      sqlite3_open_v2(target.c_str(), &dst, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr) !=
          SQLITE_OK) {
    sqlite3_close(src);
    sqlite3_close(dst);
    Fail("{}: cannot copy the COLMAP database to {}", source, target);
  }
  sqlite3_backup* backup = sqlite3_backup_init(dst, "main", src, "main");
  const bool copied = backup && sqlite3_backup_step(backup, -1) == SQLITE_DONE;
  sqlite3_backup_finish(backup);
  sqlite3_close(src);
  std::map<std::string, int64_t> cameras;
  try {
    if (!copied) Fail("{}: copying the COLMAP database to {} failed", source, target);
    for (const std::string& name : names) {
      sqlite3_stmt* stmt = nullptr;
      sqlite3_prepare_v2(dst, "SELECT image_id, camera_id FROM images WHERE name = ?", -1, &stmt,
                         nullptr);
      sqlite3_bind_text(stmt, 1, name.c_str(), -1, SQLITE_TRANSIENT);
      int64_t id = -1, camera = -1;
      if (sqlite3_step(stmt) == SQLITE_ROW) {
        id = sqlite3_column_int64(stmt, 0);
        camera = sqlite3_column_int64(stmt, 1);
      }
      sqlite3_finalize(stmt);
      if (id < 0) Fail("{}: image {} is not in COLMAP's database", source, name);
      cameras[name] = camera;
      for (const char* table : {"keypoints", "descriptors", "images"}) {
        Exec(dst, fmt::format("DELETE FROM {} WHERE image_id = {}", table, id), target);
      }
      for (const char* table : {"matches", "two_view_geometries"}) {
        Exec(dst,
             fmt::format("DELETE FROM {} WHERE pair_id / {} = {} OR pair_id % {} = {}", table,
                         kMaxNumImages, id, kMaxNumImages, id),
             target);
      }
    }
  } catch (...) {
    sqlite3_close(dst);
    throw;
  }
  sqlite3_close(dst);
  return cameras;
}

Reconstruction ReadRegistered(const std::string& dir) {
  return FileExists(JoinPaths(dir, "images.bin")) ? ReadColmapModel(dir) : Reconstruction{};
}

// linecloud's figures for an image from an `eval run` report (direct matching).
ojson OursFor(const DirectMatchingReport* ours, const std::string& image) {
  if (!ours) return nullptr;
  for (const DirectMatchingPhoto& row : ours->per_query) {
    if (row.image != image) continue;
    ojson j;
    for (const char* method : {"p6L", "p3P"}) {
      const DirectMatchingAttempt* a = FindIn(row.methods, method);
      const DirectMatchingSummary* m = FindIn(ours->methods, method);
      if (!a || !m) continue;
      const double ms = row.extract_ms + row.match_ms + m->mean_ms.ransac + m->mean_ms.refine;
      j[method] = {{"rotation_deg", a->rotation_deg},
                   {"translation", a->translation},
                   {"seconds", ms / 1000}};
    }
    return j;
  }
  return nullptr;
}

std::string Markdown(const ojson& r) {
  std::string md = fmt::format(
      "# COLMAP {} registering the left-out images — {}\n\nPer group: the dataset's database "
      "without the group's images, then `feature_extractor` (each image, its known camera), "
      "`exhaustive_matcher` (new pairs) and `image_registrator` on the group's map, one thread. "
      "Errors against the ground truth as in `eval run`; seconds per image (COLMAP: the group's "
      "matching and registration shared among its images).\n\n",
      r["colmap_version"].get<std::string>(), r["dataset"].get<std::string>());
  md +=
      "| image | COLMAP error | COLMAP s (extract + match + register) | linecloud p6L error | "
      "p6L s | linecloud p3P error | p3P s |\n|---|---|---|---|---|---|---|\n";
  auto err = [](const ojson& j) {
    return j.is_null() ? std::string("not registered")
                       : fmt::format("{:.4f}° / {:.4f}", j["rotation_deg"].get<double>(),
                                     j["translation"].get<double>());
  };
  for (const ojson& row : r["images"]) {
    const ojson& c = row["colmap"];
    std::string line = fmt::format("| {} | {} | {:.2f} ({:.2f} + {:.2f} + {:.2f}) |",
                                   row["image"].get<std::string>(), err(c["error"]),
                                   c["seconds"].get<double>(), c["extract_s"].get<double>(),
                                   c["match_s"].get<double>(), c["register_s"].get<double>());
    for (const char* m : {"p6L", "p3P"}) {
      if (row["ours"].is_null() || !row["ours"].contains(m)) {
        line += " – | – |";
        continue;
      }
      const ojson& o = row["ours"][m];
      line += fmt::format(" {} | {:.2f} |", err(o), o["seconds"].get<double>());
    }
    md += line + "\n";
  }
  const ojson& s = r["summary"];
  md += fmt::format("\nCOLMAP: {} / {} registered, median {:.4f}° / {:.4f}, {:.2f} s per image.",
                    s["colmap_registered"].get<int>(), s["images"].get<int>(),
                    s["colmap_median_rotation_deg"].get<double>(),
                    s["colmap_median_translation"].get<double>(),
                    s["colmap_mean_seconds"].get<double>());
  if (s.contains("p6L_median_rotation_deg")) {
    md += fmt::format(
        " linecloud p6L: median {:.4f}° / {:.4f} ({:.2f}× COLMAP's rotation error), "
        "{:.2f} s per image ({:.2f}× COLMAP's time).",
        s["p6L_median_rotation_deg"].get<double>(), s["p6L_median_translation"].get<double>(),
        s["p6L_median_rotation_deg"].get<double>() / s["colmap_median_rotation_deg"].get<double>(),
        s["p6L_mean_seconds"].get<double>(),
        s["p6L_mean_seconds"].get<double>() / s["colmap_mean_seconds"].get<double>());
  }
  return md + "\n";
}

// COLMAP's registration of one group's images: per image the registered
// pose's error (null when not registered) and its share of the time.
struct GroupRegistration {
  std::map<std::string, double> extract_s;
  double match_s = 0, register_s = 0;
  Reconstruction model;  // the map with the registered images
};

GroupRegistration RegisterGroup(const std::string& work_dir, const EvalGroup& g,
                                const std::string& images_dir, const std::string& dir,
                                const ColmapOptions& colmap) {
  CreateDirectories(dir);
  std::vector<std::string> names;
  for (const EvalImage& im : g.images) names.push_back(im.name);
  const std::string db = JoinPaths(dir, "database.db");
  const auto cameras = DatabaseWithout(JoinPaths(work_dir, "colmap/database.db"), db, names);
  GroupRegistration r;
  for (const std::string& name : names) {
    const std::string list = JoinPaths(dir, "image_list.txt");
    WriteFileAtomically(list, [&](std::ostream& out) { out << name << "\n"; });
    const auto t0 = std::chrono::steady_clock::now();
    RunColmapCommand({colmap.executable, "feature_extractor", "--database_path", db, "--image_path",
                      images_dir, "--image_list_path", list, "--ImageReader.existing_camera_id",
                      std::to_string(cameras.at(name)), "--SiftExtraction.use_gpu", "0",
                      "--SiftExtraction.num_threads", "1"},
                     JoinPaths(dir, "feature_extractor.log"), colmap);
    r.extract_s[name] = SecondsSince(t0);
  }
  auto t0 = std::chrono::steady_clock::now();
  RunColmapCommand({colmap.executable, "exhaustive_matcher", "--database_path", db,
                    "--SiftMatching.use_gpu", "0", "--SiftMatching.num_threads", "1"},
                   JoinPaths(dir, "exhaustive_matcher.log"), colmap);
  r.match_s = SecondsSince(t0);
  const std::string out_model = JoinPaths(dir, "model");
  CreateDirectories(out_model);
  t0 = std::chrono::steady_clock::now();
  RunColmapCommand(
      {colmap.executable, "image_registrator", "--database_path", db, "--input_path",
       JoinPaths(work_dir, g.map_dir), "--output_path", out_model, "--Mapper.num_threads", "1",
       "--Mapper.ba_refine_focal_length", "0", "--Mapper.ba_refine_principal_point", "0",
       "--Mapper.ba_refine_extra_params", "0"},
      JoinPaths(dir, "image_registrator.log"), colmap);
  r.register_s = SecondsSince(t0);
  r.model = ReadRegistered(out_model);
  return r;
}

// One image's row: COLMAP's error and time, linecloud's beside.
ojson ImageRow(const EvalGroup& g, const EvalImage& im, const GroupRegistration& r,
               const DirectMatchingReport* ours) {
  const double shared = (r.match_s + r.register_s) / g.images.size();
  ojson c = {{"extract_s", r.extract_s.at(im.name)},
             {"match_s", r.match_s / g.images.size()},
             {"register_s", r.register_s / g.images.size()},
             {"seconds", r.extract_s.at(im.name) + shared},
             {"error", nullptr}};
  for (const auto& [id, image] : r.model.images) {
    if (image.name != im.name) continue;
    const LocalizationError e =
        CompareLocalization(ToSim3(image.cam_from_world), ToSim3(im.cam_from_world));
    c["error"] = {{"rotation_deg", e.rotation_rad * kDeg}, {"translation", e.position}};
  }
  return {{"group", g.name}, {"image", im.name}, {"colmap", c}, {"ours", OursFor(ours, im.name)}};
}

ojson Summary(const ojson& images) {
  std::vector<double> c_rot, c_pos, c_sec, p_rot, p_pos, p_sec;
  int registered = 0;
  for (const ojson& row : images) {
    const ojson& c = row["colmap"];
    registered += !c["error"].is_null();
    c_rot.push_back(c["error"].is_null() ? 180 : c["error"]["rotation_deg"].get<double>());
    c_pos.push_back(c["error"].is_null() ? 1e9 : c["error"]["translation"].get<double>());
    c_sec.push_back(c["seconds"].get<double>());
    if (!row["ours"].is_null() && row["ours"].contains("p6L")) {
      p_rot.push_back(row["ours"]["p6L"]["rotation_deg"].get<double>());
      p_pos.push_back(row["ours"]["p6L"]["translation"].get<double>());
      p_sec.push_back(row["ours"]["p6L"]["seconds"].get<double>());
    }
  }
  auto mean = [](const std::vector<double>& v) {
    double s = 0;
    for (const double x : v) s += x;
    return v.empty() ? 0.0 : s / v.size();
  };
  ojson summary = {{"images", static_cast<int>(c_rot.size())},
                   {"colmap_registered", registered},
                   {"colmap_median_rotation_deg", Median(c_rot)},
                   {"colmap_median_translation", Median(c_pos)},
                   {"colmap_mean_seconds", mean(c_sec)}};
  if (!p_rot.empty()) {
    summary["p6L_median_rotation_deg"] = Median(p_rot);
    summary["p6L_median_translation"] = Median(p_pos);
    summary["p6L_mean_seconds"] = mean(p_sec);
  }
  return summary;
}

// The version line COLMAP printed when `eval prepare` ran it.
std::string ColmapVersion(const std::string& work_dir) {
  const std::string log = JoinPaths(work_dir, "colmap/colmap_version.log");
  if (!FileExists(log)) return "(version unknown)";
  const std::string text = ReadFileToString(log);
  const size_t at = text.find("COLMAP ");
  if (at == std::string::npos) return "(version unknown)";
  return text.substr(at + 7, text.find_first_of(" \n", at + 7) - at - 7);
}

}  // namespace

void ColmapRegistrationOptions::Check() const {
  if (work_dir.empty()) Fail("--work: empty");
  if (out_dir.empty()) Fail("--out: empty");
  colmap.Check();
}

ojson RunColmapRegistration(const ColmapRegistrationOptions& o) {
  o.Check();
  const EvalWork work = ReadPreparedWork(o.work_dir);
  std::optional<DirectMatchingReport> ours;
  if (!o.ours.empty()) {
    ours = ReadEvalReport(o.ours).direct_matching;
    if (!ours)
      Fail("{}: no direct_matching section (run eval run without --no-direct-matching)", o.ours);
  }
  CreateDirectories(o.out_dir);
  ColmapOptions colmap = o.colmap;
  colmap.num_threads = 1;  // one core, as linecloud's figures
  ojson images = ojson::array();
  for (const EvalGroup& g : work.groups) {
    const GroupRegistration r = RegisterGroup(o.work_dir, g, JoinPaths(work.dataset_dir, "images"),
                                              JoinPaths(o.out_dir, g.name), colmap);
    for (const EvalImage& im : g.images)
      images.push_back(ImageRow(g, im, r, ours ? &*ours : nullptr));
    LogProgress("[eval colmap] group {}: {} images, match {:.1f} s, register {:.1f} s", g.name,
                g.images.size(), r.match_s, r.register_s);
  }
  const ojson report = {{"dataset", work.dataset},
                        {"colmap_version", ColmapVersion(o.work_dir)},
                        {"units", work.units},
                        {"summary", Summary(images)},
                        {"images", images}};
  WriteFileAtomically(JoinPaths(o.out_dir, "colmap_registration.json"),
                      [&](std::ostream& out) { out << report.dump(2) << "\n"; });
  WriteFileAtomically(JoinPaths(o.out_dir, "colmap_registration.md"),
                      [&](std::ostream& out) { out << Markdown(report); });
  return report;
}

}  // namespace linecloud
