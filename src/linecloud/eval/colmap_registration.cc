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
std::optional<std::map<std::string, OursOnImage>> OursFor(const DirectMatchingReport* ours,
                                                          const std::string& image) {
  if (!ours) return std::nullopt;
  std::map<std::string, OursOnImage> by_method;
  for (const DirectMatchingPhoto& row : ours->per_query) {
    if (row.image != image) continue;
    for (const char* method : {"p6L", "p3P"}) {
      const DirectMatchingAttempt* a = FindIn(row.methods, method);
      const DirectMatchingSummary* m = FindIn(ours->methods, method);
      if (!a || !m) continue;
      const double ms = row.extract_ms + row.match_ms + m->mean_ms.ransac + m->mean_ms.refine;
      by_method[method] = {{a->rotation_deg, a->translation}, ms / 1000};
    }
    if (!by_method.empty()) return by_method;
  }
  return std::nullopt;  // the image is not in the report, or has neither method
}

std::string ErrorCell(const std::optional<RegistrationError>& e) {
  return e ? fmt::format("{:.4f}° / {:.4f}", e->rotation_deg, e->translation)
           : std::string("not registered");
}

ojson ToJson(const RegistrationError& e) {
  return {{"rotation_deg", e.rotation_deg}, {"translation", e.translation}};
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
RegistrationImage ImageRow(const EvalGroup& g, const EvalImage& im, const GroupRegistration& r,
                           const DirectMatchingReport* ours) {
  RegistrationImage row;
  row.group = g.name;
  row.image = im.name;
  ColmapOnImage& c = row.colmap;
  c.extract_s = r.extract_s.at(im.name);
  c.match_s = r.match_s / g.images.size();
  c.register_s = r.register_s / g.images.size();
  c.seconds = c.extract_s + c.match_s + c.register_s;
  for (const auto& [id, image] : r.model.images) {
    if (image.name != im.name) continue;
    const LocalizationError e =
        CompareLocalization(ToSim3(image.cam_from_world), ToSim3(im.cam_from_world));
    c.error = RegistrationError{e.rotation_rad * kDeg, e.position};
  }
  row.ours = OursFor(ours, im.name);
  return row;
}

RegistrationSummary Summary(const std::vector<RegistrationImage>& images) {
  std::vector<double> c_rot, c_pos, c_sec, p_rot, p_pos, p_sec;
  RegistrationSummary s;
  for (const RegistrationImage& row : images) {
    const ColmapOnImage& c = row.colmap;
    s.colmap_registered += c.error.has_value();
    c_rot.push_back(c.error ? c.error->rotation_deg : 180);
    c_pos.push_back(c.error ? c.error->translation : 1e9);
    c_sec.push_back(c.seconds);
    if (row.ours && row.ours->count("p6L")) {
      const OursOnImage& p = row.ours->at("p6L");
      p_rot.push_back(p.rotation_deg);
      p_pos.push_back(p.translation);
      p_sec.push_back(p.seconds);
    }
  }
  s.images = static_cast<int>(c_rot.size());
  s.colmap_median_rotation_deg = Median(c_rot);
  s.colmap_median_translation = Median(c_pos);
  s.colmap_mean_seconds = Mean(c_sec);
  if (!p_rot.empty()) {
    s.p6l_median_rotation_deg = Median(p_rot);
    s.p6l_median_translation = Median(p_pos);
    s.p6l_mean_seconds = Mean(p_sec);
  }
  return s;
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

ColmapRegistrationReport RunColmapRegistration(const ColmapRegistrationOptions& o) {
  o.Check();
  const EvalWork work = ReadPreparedWork(o.work_dir);
  std::optional<DirectMatchingReport> ours;
  if (!o.ours.empty()) {
    const EvalReport report = ReadEvalReport(o.ours);
    // Checked before COLMAP runs: another dataset's figures would sit beside these images.
    if (report.dataset != work.dataset) {
      Fail("{}: a report of dataset '{}', not of {} ('{}')", o.ours, report.dataset, o.work_dir,
           work.dataset);
    }
    ours = report.direct_matching;
    if (!ours)
      Fail("{}: no direct_matching section (run eval run without --no-direct-matching)", o.ours);
    // Every query photo of the work, in its group: another run's photos (renamed, regrouped,
    // fewer) would leave these images without figures or give them another run's.
    size_t missing = 0;
    std::string first;
    for (const EvalGroup& g : work.groups) {
      for (const EvalImage& im : g.images) {
        const bool found = std::any_of(
            ours->per_query.begin(), ours->per_query.end(),
            [&](const DirectMatchingPhoto& p) { return p.group == g.name && p.image == im.name; });
        if (!found && missing++ == 0) first = g.name + "/" + im.name;
      }
    }
    if (missing > 0) {
      Fail(
          "{}: {} of {}'s query photos have no direct-matching row (first: {}): not a report of "
          "this work",
          o.ours, missing, o.work_dir, first);
    }
  }
  CreateDirectories(o.out_dir);
  ColmapOptions colmap = o.colmap;
  colmap.num_threads = 1;  // one core, as linecloud's figures
  ColmapRegistrationReport report{work.dataset, ColmapVersion(o.work_dir), work.units, {}, {}};
  for (const EvalGroup& g : work.groups) {
    const GroupRegistration r = RegisterGroup(o.work_dir, g, JoinPaths(work.dataset_dir, "images"),
                                              JoinPaths(o.out_dir, g.name), colmap);
    for (const EvalImage& im : g.images)
      report.images.push_back(ImageRow(g, im, r, ours ? &*ours : nullptr));
    LogProgress("[eval colmap] group {}: {} images, match {:.1f} s, register {:.1f} s", g.name,
                g.images.size(), r.match_s, r.register_s);
  }
  report.summary = Summary(report.images);
  WriteFileAtomically(JoinPaths(o.out_dir, "colmap_registration.json"),
                      [&](std::ostream& out) { out << ToJson(report).dump(2) << "\n"; });
  WriteFileAtomically(JoinPaths(o.out_dir, "colmap_registration.md"),
                      [&](std::ostream& out) { out << ColmapRegistrationMarkdown(report); });
  return report;
}

ojson ToJson(const ColmapRegistrationReport& r) {
  ojson images = ojson::array();
  for (const RegistrationImage& row : r.images) {
    const ColmapOnImage& c = row.colmap;
    ojson colmap = {{"extract_s", c.extract_s},
                    {"match_s", c.match_s},
                    {"register_s", c.register_s},
                    {"seconds", c.seconds},
                    {"error", c.error ? ToJson(*c.error) : ojson(nullptr)}};
    ojson ours = nullptr;
    if (row.ours) {
      ours = ojson::object();
      for (const auto& [method, f] : *row.ours) {
        ours[method] = {{"rotation_deg", f.rotation_deg},
                        {"translation", f.translation},
                        {"seconds", f.seconds}};
      }
    }
    images.push_back(
        {{"group", row.group}, {"image", row.image}, {"colmap", colmap}, {"ours", ours}});
  }
  const RegistrationSummary& s = r.summary;
  ojson summary = {{"images", s.images},
                   {"colmap_registered", s.colmap_registered},
                   {"colmap_median_rotation_deg", s.colmap_median_rotation_deg},
                   {"colmap_median_translation", s.colmap_median_translation},
                   {"colmap_mean_seconds", s.colmap_mean_seconds}};
  if (s.p6l_median_rotation_deg) {
    summary["p6L_median_rotation_deg"] = *s.p6l_median_rotation_deg;
    summary["p6L_median_translation"] = *s.p6l_median_translation;
    summary["p6L_mean_seconds"] = *s.p6l_mean_seconds;
  }
  return {{"dataset", r.dataset},
          {"colmap_version", r.colmap_version},
          {"units", r.units},
          {"summary", summary},
          {"images", images}};
}

RegistrationSummary RegistrationSummaryFromJson(const nlohmann::json& report,
                                                const std::string& where) {
  const JsonFields s = JsonFields(report, where).Object("summary");
  RegistrationSummary out;
  out.images = s.Int("images");
  out.colmap_registered = s.Int("colmap_registered");
  out.colmap_median_rotation_deg = s.Number("colmap_median_rotation_deg");
  out.colmap_median_translation = s.Number("colmap_median_translation");
  out.colmap_mean_seconds = s.Number("colmap_mean_seconds");
  if (s.Has("p6L_median_rotation_deg")) {
    out.p6l_median_rotation_deg = s.Number("p6L_median_rotation_deg");
    out.p6l_median_translation = s.Number("p6L_median_translation");
    out.p6l_mean_seconds = s.Number("p6L_mean_seconds");
  }
  return out;
}

std::string ColmapRegistrationMarkdown(const ColmapRegistrationReport& r) {
  std::string md = fmt::format(
      "# COLMAP {} registering the left-out images — {}\n\nPer group: the dataset's database "
      "without the group's images, then `feature_extractor` (each image, its known camera), "
      "`exhaustive_matcher` (new pairs) and `image_registrator` on the group's map, one thread. "
      "Errors against the ground truth as in `eval run`; seconds per image (COLMAP: the group's "
      "matching and registration shared among its images).\n\n",
      r.colmap_version, r.dataset);
  md +=
      "| image | COLMAP error | COLMAP s (extract + match + register) | linecloud p6L error | "
      "p6L s | linecloud p3P error | p3P s |\n|---|---|---|---|---|---|---|\n";
  for (const RegistrationImage& row : r.images) {
    const ColmapOnImage& c = row.colmap;
    std::string line =
        fmt::format("| {} | {} | {:.2f} ({:.2f} + {:.2f} + {:.2f}) |", row.image,
                    ErrorCell(c.error), c.seconds, c.extract_s, c.match_s, c.register_s);
    for (const char* m : {"p6L", "p3P"}) {
      if (!row.ours || !row.ours->count(m)) {
        line += " – | – |";
        continue;
      }
      const OursOnImage& o = row.ours->at(m);
      line += fmt::format(" {} | {:.2f} |", ErrorCell(RegistrationError(o)), o.seconds);
    }
    md += line + "\n";
  }
  const RegistrationSummary& s = r.summary;
  md += fmt::format("\nCOLMAP: {} / {} registered, median {:.4f}° / {:.4f}, {:.2f} s per image.",
                    s.colmap_registered, s.images, s.colmap_median_rotation_deg,
                    s.colmap_median_translation, s.colmap_mean_seconds);
  if (s.p6l_median_rotation_deg) {
    md += fmt::format(
        " linecloud p6L: median {:.4f}° / {:.4f} ({:.2f}× COLMAP's rotation error), "
        "{:.2f} s per image ({:.2f}× COLMAP's time).",
        *s.p6l_median_rotation_deg, *s.p6l_median_translation,
        *s.p6l_median_rotation_deg / s.colmap_median_rotation_deg, *s.p6l_mean_seconds,
        *s.p6l_mean_seconds / s.colmap_mean_seconds);
  }
  return md + "\n";
}

}  // namespace linecloud
