#include "linecloud/mapping/map_project.h"

#include <fcntl.h>
#include <sodium.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <map>
#include <set>

#include <fmt/format.h>

#include "linecloud/geometry/line_grid.h"
#include "linecloud/geometry/similarity_fit.h"
#include "linecloud/io/colmap_database.h"
#include "linecloud/io/geo.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/io/lift_model.h"
#include "linecloud/lifting/key.h"
#include "linecloud/privacy/audit.h"
#include "linecloud/util/clock.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"
#include "linecloud/util/log.h"

namespace linecloud {
namespace fs = std::filesystem;
using ojson = nlohmann::ordered_json;
namespace {

constexpr char kFormat[] = "linecloud map project";

std::string Hash(const std::string& text) {
  InputFingerprint fp;
  fp.Add(text);
  return fp.Hex();
}

bool Inside(const fs::path& a, const fs::path& b) {  // a == b or a under b
  const fs::path ra = fs::weakly_canonical(a), rb = fs::weakly_canonical(b);
  auto ia = ra.begin(), ib = rb.begin();
  for (; ib != rb.end() && !ib->empty(); ++ia, ++ib) {
    if (ia == ra.end() || *ia != *ib) return false;
  }
  return true;
}

// The project folder: project.json (its id, its photos by name and content
// hash, the released model), and a stamp per finished stage.
class Project {
 public:
  explicit Project(std::string dir) : dir_(std::move(dir)) {}
  ~Project() {
    if (lock_fd_ >= 0) ::close(lock_fd_);
  }
  Project(const Project&) = delete;
  Project& operator=(const Project&) = delete;
  // One run at a time: a second `map` on the project is refused at once (two
  // would write one database and one model).
  void Lock() {
    const std::string path = Path(".lock");
    lock_fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0600);
    if (lock_fd_ < 0) Fail("{}: cannot open the project's lock ({})", path, std::strerror(errno));
    while (::flock(lock_fd_, LOCK_EX | LOCK_NB) != 0) {
      if (errno == EINTR) continue;
      Fail(
          "{}: another `linecloud map` is working on this project; wait for it to end (or stop "
          "it: the same command then continues where it was)",
          dir_);
    }
  }
  std::string Path(const std::string& rel) const { return JoinPaths(dir_, rel); }
  const std::string& dir() const { return dir_; }
  ojson& manifest() { return manifest_; }
  std::string id() const { return manifest_.value("id", ""); }
  uint64_t Salt() const {  // the identity salt: the id's first 8 bytes
    uint64_t s = 0;
    for (size_t i = 0; i < 16 && i < id().size(); ++i) {
      s = (s << 4) | uint64_t(std::stoi(id().substr(i, 1), nullptr, 16));
    }
    return s | 1;
  }
  void Save() const {
    WriteFileAtomically(Path("project.json"),
                        [&](std::ostream& o) { o << manifest_.dump(1) << "\n"; });
  }
  void Load() {
    const std::string path = Path("project.json");
    try {
      manifest_ = ojson::parse(ReadFileToString(path));
    } catch (const nlohmann::json::exception& e) {
      Fail("{}: not a readable project file ({})", path, e.what());
    }
    if (!manifest_.is_object() || manifest_.value("format", "") != kFormat ||
        !manifest_.contains("photos") || !manifest_["photos"].is_array()) {
      Fail("{}: not a linecloud map project file", path);
    }
  }

  // A finished stage: its stamp holds the fingerprint its inputs had.
  std::optional<ojson> Finished(const std::string& stage, const std::string& fingerprint) const {
    const std::string path = Path("stages/" + stage + ".json");
    if (!FileExists(path)) return std::nullopt;
    try {
      ojson j = ojson::parse(ReadFileToString(path));
      if (j.value("fingerprint", "") == fingerprint) return j["details"];
    } catch (const nlohmann::json::exception&) {
    }
    return std::nullopt;
  }
  void Finish(const std::string& stage, const std::string& fingerprint,
              const ojson& details) const {
    CreateDirectories(Path("stages"));
    WriteFileAtomically(Path("stages/" + stage + ".json"), [&](std::ostream& o) {
      o << ojson{{"fingerprint", fingerprint}, {"details", details}}.dump(1) << "\n";
    });
  }

 private:
  std::string dir_;
  ojson manifest_;
  int lock_fd_ = -1;
};

// A folder with nothing but a run's lock in it counts as empty.
bool EmptyBesidesLock(const std::string& dir) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (e.path().filename() != ".lock") return false;
  }
  return true;
}

ojson PhotoEntry(const Photo& p) {
  ojson e = {{"name", p.name},
             {"path", fs::absolute(p.path).string()},
             {"bytes", p.bytes},
             {"blake2b", p.blake2b}};
  if (p.gps) e["gps"] = {p.gps->x(), p.gps->y(), p.gps->z()};
  return e;
}

std::string CameraText(const Camera& c) {
  std::string s = fmt::format("{} {} {}", CameraModelName(c.model_id), c.width, c.height);
  for (double v : c.params) s += fmt::format(" {:.17g}", v);
  return s;
}

// Runs a stage unless a run before finished it with the same inputs.
class Stages {
 public:
  Stages(const Project& project, MapReport* report) : project_(project), report_(report) {}
  // `work` returns the stage's details (kept in its stamp).
  ojson Run(const std::string& name, const std::string& fingerprint,
            const std::function<ojson()>& work) {
    const auto t0 = std::chrono::steady_clock::now();
    MapStage stage;
    stage.name = name;
    if (auto done = project_.Finished(name, fingerprint)) {
      stage.reused = true;
      stage.details = *done;
      LogProgress("[map] {}: finished by an earlier run, kept", name);
    } else {
      LogProgress("[map] {} ...", name);
      stage.details = work();
      project_.Finish(name, fingerprint, stage.details);
    }
    stage.seconds = SecondsSince(t0);
    if (!stage.reused) LogProgress("[map] {}: done in {:.1f} s", name, stage.seconds);
    report_->stages.push_back(stage);
    return stage.details;
  }

 private:
  const Project& project_;
  MapReport* report_;
};

// Per photo, why the mapper left it out.
std::vector<std::pair<std::string, std::string>> WhyUnregistered(
    const std::vector<std::string>& names, const Reconstruction& model, const std::string& database,
    const std::string& sparse_dir) {
  std::set<std::string> registered;
  for (const auto& [id, im] : model.images) registered.insert(im.name);
  const ColmapDatabase db(database);
  std::map<std::string, uint32_t> id_of;
  for (const DatabaseImage& im : db.ReadImages()) id_of[im.name] = im.image_id;
  std::map<uint32_t, int> verified;
  for (const TwoViewGeometry& g : db.ReadTwoViewGeometries()) {
    if (g.inlier_matches.rows() == 0) continue;
    verified[g.image_id1]++;
    verified[g.image_id2]++;
  }
  std::map<std::string, size_t> other_model;  // name -> photos of the other model it is in
  if (IsDirectory(sparse_dir)) {
    for (const auto& e : fs::directory_iterator(sparse_dir)) {
      if (!e.is_directory()) continue;
      const Reconstruction r = ReadColmapModel(e.path().string());
      if (r.images.size() >= model.images.size()) continue;
      for (const auto& [id, im] : r.images) other_model[im.name] = r.images.size();
    }
  }
  std::vector<std::pair<std::string, std::string>> out;
  for (const std::string& n : names) {
    if (registered.count(n)) continue;
    const uint32_t id = id_of.count(n) ? id_of[n] : 0;
    const size_t features = id ? size_t(db.ReadKeypoints(id).rows()) : 0;
    std::string why;
    if (features == 0) {
      why = "no features (a blank or featureless photo)";
    } else if (!verified.count(id)) {
      why = fmt::format("{} features, but no other photo shares enough of them (no verified pair)",
                        features);
    } else if (other_model.count(n)) {
      why = fmt::format(
          "in a separate model of {} photos: mapping split; add photos between the "
          "two parts",
          other_model[n]);
    } else {
      why = fmt::format("{} verified pairs, yet the mapper could not place it", verified[id]);
    }
    out.emplace_back(n, why);
  }
  return out;
}

void Describe(const Reconstruction& model, MapReport* r) {
  r->registered = model.images.size();
  r->points = model.points3D.size();
  r->mean_track_length = model.MeanTrackLength();
  double sum = 0, n = 0;
  for (const auto& [id, p] : model.points3D) {
    if (p.error < 0) continue;
    sum += p.error * p.track.size();
    n += p.track.size();
  }
  r->mean_reprojection_error_px = n > 0 ? sum / n : 0;
}

// The map frame on the Earth from the photos' GPS: a similarity from the
// registered cameras' centres to their GPS positions in east-north-up metres
// (robust: GPS errs by metres, some photos by much more). Nullopt when fewer
// than three photos with GPS agree.
std::optional<GeoAnchor> AnchorFromGps(const Reconstruction& model,
                                       const std::map<std::string, Eigen::Vector3d>& gps,
                                       std::string* note) {
  std::vector<Eigen::Vector3d> centres, geo;
  for (const auto& [id, im] : model.images) {
    if (const auto it = gps.find(im.name); it != gps.end()) {
      centres.push_back(im.cam_from_world.Center());
      geo.push_back(it->second);
    }
  }
  if (geo.size() < 3) {
    *note = gps.empty() ? "no photo carries GPS: no geo_anchor"
                        : fmt::format("{} registered photos carry GPS (3 needed): no geo_anchor",
                                      geo.size());
    return std::nullopt;
  }
  GeoAnchor a;
  for (const Eigen::Vector3d& g : geo) {
    a.lat_deg += g.x() / geo.size();
    a.lon_deg += g.y() / geo.size();
    a.h_m += g.z() / geo.size();
  }
  std::vector<Eigen::Vector3d> enu;
  for (const Eigen::Vector3d& g : geo) {
    enu.push_back(EnuFromGeodetic(a.lat_deg, a.lon_deg, a.h_m, g.x(), g.y(), g.z()));
  }
  const RobustSimilarityFit fit = FitSimilarityRobust(centres, enu, 10.0);
  if (fit.inliers.size() < 3 || !(fit.dst_from_src.scale > 0)) {
    *note = fmt::format(
        "the GPS of {} photos does not fit the model (fewer than 3 agree within "
        "10 m): no geo_anchor",
        geo.size());
    return std::nullopt;
  }
  a.enu_from_map = fit.dst_from_src;
  *note = fmt::format("geo_anchor from the GPS of {} photos ({} agree within 10 m)", geo.size(),
                      fit.inliers.size());
  return a;
}

// The model's camera centres against survey poses after a similarity
// (Umeyama) on the images both have: errors in the survey's units and as a
// share of the scene's extent (the diagonal of the points' robust box).
ojson CompareWithGroundTruth(const Reconstruction& model, const std::string& path) {
  Reconstruction gt;
  ParseImagesText(ReadFileToString(path), path, &gt);
  std::map<std::string, Rigid3d> truth;
  for (const auto& [id, im] : gt.images) truth[im.name] = im.cam_from_world;
  std::vector<Eigen::Vector3d> ours, theirs;
  std::vector<Eigen::Quaterniond> q_ours, q_theirs;
  for (const auto& [id, im] : model.images) {
    const auto it = truth.find(im.name);
    if (it == truth.end()) continue;
    ours.push_back(im.cam_from_world.Center());
    theirs.push_back(it->second.Center());
    q_ours.push_back(im.cam_from_world.rotation);
    q_theirs.push_back(it->second.rotation);
  }
  if (ours.size() < 3) Fail("{}: fewer than 3 of its images are in the model", path);
  const Sim3d gt_from_model = FitSimilarity(ours, theirs);
  std::vector<Eigen::Vector3d> points;
  for (const auto& [id, p] : model.points3D) points.push_back(gt_from_model * p.xyz);
  const double extent = RobustBox(points).diagonal().norm();
  double max_centre = 0, max_rotation = 0;
  for (size_t k = 0; k < ours.size(); ++k) {
    max_centre = std::max(max_centre, (gt_from_model * ours[k] - theirs[k]).norm());
    // world_from_cam in the survey's frame: R_gt_from_model * R_model_from_cam.
    const Eigen::Quaterniond aligned = gt_from_model.rotation * q_ours[k].inverse();
    max_rotation = std::max(max_rotation, aligned.angularDistance(q_theirs[k].inverse()));
  }
  return {{"file", path},
          {"images", ours.size()},
          {"scene_extent", extent},
          {"max_centre_error", max_centre},
          {"max_centre_error_extent_percent", 100 * max_centre / extent},
          {"max_rotation_error_deg", max_rotation * 180 / M_PI}};
}

struct StereoBaseline {
  std::string a, b;
  double metres = 0;
};

StereoBaseline ParseStereo(const std::string& text) {
  StereoBaseline s;
  const size_t c1 = text.find(','), c2 = text.find(',', c1 == std::string::npos ? 0 : c1 + 1);
  if (c1 == std::string::npos || c2 == std::string::npos) {
    Fail("--stereo {}: expected A,B,METRES (e.g. _c0,_c1,0.110)", text);
  }
  s.a = text.substr(0, c1);
  s.b = text.substr(c1 + 1, c2 - c1 - 1);
  try {
    s.metres = std::stod(text.substr(c2 + 1));
  } catch (const std::exception&) {
    s.metres = 0;
  }
  if (s.a.empty() || s.b.empty() || s.a == s.b || !(s.metres > 0) || !std::isfinite(s.metres)) {
    Fail("--stereo {}: expected two different name parts and a baseline in metres > 0", text);
  }
  return s;
}

// Scales `model` to metres from the rig's simultaneous pairs: the median of
// baseline / distance between the pair's centres.
ojson ScaleToStereoBaseline(const StereoBaseline& s, Reconstruction* model) {
  std::map<std::string, Eigen::Vector3d> centre;
  for (const auto& [id, im] : model->images) centre[im.name] = im.cam_from_world.Center();
  std::vector<double> ratios;
  for (const auto& [name, c] : centre) {
    const size_t at = name.find(s.a);
    if (at == std::string::npos) continue;
    std::string other = name;
    other.replace(at, s.a.size(), s.b);
    const auto it = centre.find(other);
    if (it == centre.end()) continue;
    const double d = (it->second - c).norm();
    if (d > 0) ratios.push_back(s.metres / d);
  }
  if (ratios.size() < 3) {
    Fail("--stereo: {} registered pairs of photos named *{}* / *{}* (3 needed for the scale)",
         ratios.size(), s.a, s.b);
  }
  std::sort(ratios.begin(), ratios.end());
  const double scale = ratios[ratios.size() / 2];
  std::vector<double> dev;
  for (double r : ratios) dev.push_back(std::abs(r / scale - 1));
  std::sort(dev.begin(), dev.end());
  for (auto& [id, p] : model->points3D) p.xyz *= scale;
  for (auto& [id, im] : model->images) im.cam_from_world.translation *= scale;
  return {{"pairs", ratios.size()},
          {"metres_per_unit", scale},
          {"median_relative_spread", dev[dev.size() / 2]}};
}

// Released lines the new version keeps, lines it adds, released lines it
// withdraws: by line id (the key's permutation of the point ids, which
// COLMAP keeps for the points of a model it extends).
struct LineChanges {
  size_t kept = 0, added = 0, withdrawn = 0;
};

LineChanges CompareLines(const LineCloud& released, const LineCloud& next) {
  const std::set<uint64_t> before(released.ids.begin(), released.ids.end());
  const std::set<uint64_t> after(next.ids.begin(), next.ids.end());
  LineChanges c;
  for (uint64_t id : after) (before.count(id) ? c.kept : c.added)++;
  c.withdrawn = before.size() - c.kept;
  return c;
}

void CheckMapId(const std::string& out) {
  const std::string id = fs::path(out).filename().string();
  const bool ok =
      !id.empty() && id.size() <= 64 && std::all_of(id.begin(), id.end(), [](unsigned char c) {
        return std::isalnum(c) || c == '_' || c == '-';
      });
  if (!ok) {
    Fail(
        "--out {}: the map's id '{}' must be 1 to 64 letters, digits, '_' or '-' (MAPS_DIR/ID, "
        "no extension)",
        out, id);
  }
}

}  // namespace

void MapOptions::Check() const {
  if (project_dir.empty()) Fail("--project: no project folder given");
  if (!stereo.empty()) ParseStereo(stereo);
  if (!out.empty()) {
    CheckMapId(out);
    const fs::path maps_dir =
        fs::path(out).parent_path().empty() ? fs::path(".") : fs::path(out).parent_path();
    if (Inside(maps_dir, project_dir) || Inside(project_dir, maps_dir)) {
      Fail(
          "--out {}: the served folder and the project folder {} must be apart (the project "
          "holds the point model and the photos; nothing of it goes where maps are served)",
          out, project_dir);
    }
  }
  sfm.Check();
}

ojson MapReport::ToJson() const {
  ojson stages_json = ojson::array();
  for (const MapStage& s : stages) {
    stages_json.push_back(
        {{"name", s.name}, {"reused", s.reused}, {"seconds", s.seconds}, {"details", s.details}});
  }
  ojson why = ojson::array();
  for (const auto& [name, reason] : unregistered) why.push_back({{"name", name}, {"why", reason}});
  return {{"project", project},
          {"project_id", project_id},
          {"update", update},
          {"photos", photos},
          {"registered", registered},
          {"unregistered", why},
          {"models", models},
          {"points", points},
          {"mean_track_length", mean_track_length},
          {"mean_reprojection_error_px", mean_reprojection_error_px},
          {"lines", lines},
          {"lines_kept", lines_kept},
          {"lines_new", lines_new},
          {"lines_withdrawn", lines_withdrawn},
          {"map", map},
          {"map_json", map_json},
          {"map_audit", map_audit},
          {"ground_truth", ground_truth},
          {"stages", stages_json}};
}

namespace {

// The served folder's three files, before any work: each absent or a
// regular file (a symbolic link there would have its target replaced, a
// folder there would fail the publish half-way).
void CheckServedFolder(const std::string& out) {
  if (out.empty()) return;
  const fs::path dir =
      fs::path(out).parent_path().empty() ? fs::path(".") : fs::path(out).parent_path();
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec)) {
    Fail("--out {}: {} is not a folder", out, dir.string());
  }
  for (const char* ext : {".lcm", ".json", ".audit.json"}) {
    const fs::path f = out + ext;
    const fs::file_status st = fs::symlink_status(f, ec);
    if (fs::is_symlink(st))
      Fail("{}: a symbolic link; the served files are written there only as files", f.string());
    if (fs::exists(st) && !fs::is_regular_file(st)) Fail("{}: not a file", f.string());
  }
}

// A stereo baseline whose name parts pair no photos would fail after hours.
void CheckStereoPairs(const StereoBaseline& s, const PhotoSet& set) {
  std::set<std::string> names;
  for (const Photo& p : set.photos) names.insert(p.name);
  size_t pairs = 0;
  for (const std::string& n : names) {
    const size_t at = n.find(s.a);
    if (at == std::string::npos) continue;
    std::string other = n;
    other.replace(at, s.a.size(), s.b);
    pairs += names.count(other);
  }
  if (pairs < 3) {
    Fail("--stereo {},{},{}: {} pairs of photos named *{}* / *{}* (3 needed for the scale)", s.a,
         s.b, s.metres, pairs, s.a, s.b);
  }
}

// An update's photos of a size the project has no camera for, whose camera
// would be a guess (no --camera, no EXIF focal length): refused, as a first
// run refuses photos of several sizes without cameras.
void RefuseGuessedCamerasOfNewSizes(Project& project, const PhotoSet& fresh) {
  std::set<std::pair<uint64_t, uint64_t>> sizes;
  for (const auto& p : project.manifest()["photos"]) {
    sizes.insert({p.value("width", uint64_t{0}), p.value("height", uint64_t{0})});
  }
  for (const Photo& p : fresh.photos) {
    const PhotoCamera& c = fresh.cameras[p.camera];
    if (c.given || c.prior_focal_length || sizes.count({p.width, p.height})) continue;
    Fail(
        "{}: {}x{} pixels and no EXIF focal length, a size none of the project's photos has; give "
        "its camera (--camera \"MODEL W H PARAMS...\")",
        p.path, p.width, p.height);
  }
}

// The photos stage: checks, the project's identity and its photo list.
// Returns the photos to work on (all of them; for an update, the new ones).
PhotoSet OpenProject(const MapOptions& o, Project* project, MapReport* report) {
  PhotoSet set = ReadPhotoSet(o.photos, o.cameras, o.update ? 1 : 2);
  CheckServedFolder(o.out);
  std::error_code ec;
  if (fs::exists(o.project_dir, ec) && !fs::is_directory(o.project_dir, ec)) {
    Fail("--project {}: not a folder", o.project_dir);
  }
  if (!o.stereo.empty()) CheckStereoPairs(ParseStereo(o.stereo), set);
  const bool exists = FileExists(project->Path("project.json"));
  if (!exists && fs::exists(o.project_dir, ec) && !EmptyBesidesLock(o.project_dir)) {
    Fail(
        "{}: a folder with other files and no project.json; name an empty or new folder for "
        "the project",
        o.project_dir);
  }
  if (o.update && !exists) {
    Fail("{}: no project to update (no project.json); map the first photos without --update",
         o.project_dir);
  }
  CreateDirectories(o.project_dir);
  project->Lock();
  if (exists) project->Load();
  std::map<std::string, std::string> known;  // name -> hash
  if (exists) {
    for (const auto& p : project->manifest()["photos"])
      known[p.value("name", "")] = p.value("blake2b", "");
  }
  if (exists && !o.update) {
    bool same = known.size() == set.photos.size();
    for (size_t k = 0; same && k < set.photos.size(); ++k) {
      same = known.count(set.photos[k].name) && known[set.photos[k].name] == set.photos[k].blake2b;
    }
    if (!same) {
      Fail(
          "{}: the project of other photos ({} photos, {} now); name a new folder for another "
          "map, or add photos to this one with --update",
          project->Path("project.json"), known.size(), set.photos.size());
    }
  }
  PhotoSet fresh;
  fresh.cameras = set.cameras;
  for (size_t k = 0; k < set.photos.size(); ++k) {
    const auto it = known.find(set.photos[k].name);
    if (it != known.end() && it->second != set.photos[k].blake2b) {
      Fail("{}: another photo than the project's {} of the same name; rename it",
           set.photos[k].path, set.photos[k].name);
    }
    if (!o.update || it == known.end()) fresh.photos.push_back(set.photos[k]);
  }
  if (o.update) RefuseGuessedCamerasOfNewSizes(*project, fresh);
  if (!exists) {
    CreateDirectories(o.project_dir);
    std::array<uint8_t, 16> id;
    randombytes_buf(id.data(), id.size());
    ojson photos = ojson::array();
    for (size_t k = 0; k < set.photos.size(); ++k) photos.push_back(PhotoEntry(set.photos[k]));
    project->manifest() = {{"format", kFormat}, {"version", 1}, {"id", ToHex(id)},
                           {"photos", photos},  {"model", ""},  {"versions", ojson::array()}};
    project->Save();
  }
  // The mapper reads photos by name from one folder: links to them.
  CreateDirectories(project->Path("images"));
  for (const Photo& p : set.photos) {
    const fs::path link = project->Path("images/" + p.name);
    fs::remove(link, ec);
    fs::create_symlink(fs::absolute(p.path), link);
  }
  report->project = o.project_dir;
  report->project_id = project->id();
  report->photos = set.photos.size();
  return fresh;
}

std::string PhotosFingerprint(const PhotoSet& photos) {
  InputFingerprint fp;
  for (const PhotoCamera& c : photos.cameras)
    fp.Add(CameraText(c.camera) + (c.given ? " given" : ""));
  for (const Photo& p : photos.photos) {
    fp.Add(p.name);
    fp.Add(std::to_string(p.camera));
    fp.Add(p.blake2b);
  }
  return fp.Hex();
}

bool AllGiven(const PhotoSet& photos) {
  return std::all_of(photos.cameras.begin(), photos.cameras.end(),
                     [](const PhotoCamera& c) { return c.given; });
}

void WriteModelAtomically(const Reconstruction& model, const std::string& dir) {
  const std::string tmp = dir + ".partial";
  fs::remove_all(tmp);
  CreateDirectories(tmp);
  WriteColmapModel(model, tmp, ModelFormat::kBinary);
  fs::remove_all(dir);
  fs::rename(tmp, dir);
}

// features → matches → mapper for a new map; returns the model's folder.
std::string BuildModel(const MapOptions& o, const PhotoSet& photos, Project& project,
                       Stages& stages, MapReport* report, std::string* fingerprint) {
  const std::string db = project.Path("database.db");
  const std::string fp_features = Hash(
      PhotosFingerprint(photos) + ColmapVersion(o.sfm.colmap, project.dir()) + o.sfm.Describe());
  stages.Run("features", fp_features, [&] {
    const size_t n = ExtractFeatures(photos, db, o.sfm, [](size_t done, size_t total) {
      if (done % 10 == 0 || done == total)
        LogProgress("[map]   features: {} / {} photos", done, total);
    });
    return ojson{{"photos", photos.photos.size()}, {"features", n}};
  });
  const std::string fp_matches = Hash(fp_features + "matches");
  stages.Run("matches", fp_matches, [&] {
    const MatchSummary m =
        MatchPhotos(photos, db, project.Path("matching"), o.sfm, {}, [](size_t done, size_t total) {
          if (done % 50 == 0 || done == total)
            LogProgress("[map]   matching: {} / {} pairs", done, total);
        });
    return ojson{{"selection", m.selection},
                 {"pairs", m.pairs},
                 {"verified", m.verified},
                 {"raw_matches", m.raw_matches}};
  });
  const bool fixed = AllGiven(photos);
  *fingerprint = Hash(fp_matches + (fixed ? "mapper fixed" : "mapper refined") + o.stereo);
  stages.Run("mapper", *fingerprint, [&] {
    Reconstruction model =
        RunMapper(db, project.Path("images"), project.Path("sparse"), fixed, o.sfm);
    ojson metric;
    if (!o.stereo.empty() && model.images.size() >= 2) {
      metric = ScaleToStereoBaseline(ParseStereo(o.stereo), &model);
      LogProgress("[map]   metric scale from the stereo baseline: {}", metric.dump());
    }
    if (model.images.size() < 2) {
      Fail("COLMAP's mapper could not build a model from these photos (log {}): {}",
           project.Path("mapper.log"),
           "they may not overlap enough; take photos with more overlap, or give the camera");
    }
    WriteModelAtomically(model, project.Path("model"));
    size_t models = 0;
    for (const auto& e : fs::directory_iterator(project.Path("sparse"))) models += e.is_directory();
    return ojson{{"registered", model.images.size()},
                 {"points", model.points3D.size()},
                 {"models", models},
                 {"intrinsics", fixed ? "fixed (given)" : "refined"},
                 {"metric_scale", metric}};
  });
  report->models = report->stages.back().details.value("models", size_t{1});
  project.manifest()["model"] = "model";
  project.Save();
  return project.Path("model");
}

// New photos registered into the released model; returns the new model's folder.
std::string UpdateModel(const MapOptions& o, const PhotoSet& fresh, Project& project,
                        Stages& stages, std::string* fingerprint) {
  const std::string released = project.Path(project.manifest().value("model", "model"));
  if (!IsDirectory(released)) Fail("{}: the released model is missing", released);
  const std::string tag = Hash(PhotosFingerprint(fresh) + released).substr(0, 12);
  const std::string dir = project.Path("updates/" + tag);
  const std::string db = project.Path("database.db");
  const std::string fp_features =
      Hash(tag + ColmapVersion(o.sfm.colmap, project.dir()) + o.sfm.Describe());
  stages.Run("update-features", fp_features, [&] {
    const size_t n = ExtractFeatures(fresh, db, o.sfm);
    return ojson{{"photos", fresh.photos.size()}, {"features", n}};
  });
  // Pairs: every new photo with every photo of the project.
  PhotoSet all = fresh;
  all.photos.clear();
  for (const auto& p : project.manifest()["photos"]) {
    Photo q;
    q.name = p.value("name", "");
    all.photos.push_back(q);
  }
  std::vector<std::string> fresh_names;
  for (const Photo& p : fresh.photos) {
    fresh_names.push_back(p.name);
    all.photos.push_back(p);
  }
  std::sort(all.photos.begin(), all.photos.end(),
            [](const Photo& a, const Photo& b) { return a.name < b.name; });
  const std::string fp_matches = Hash(fp_features + "matches");
  stages.Run("update-matches", fp_matches, [&] {
    const MatchSummary m = MatchPhotos(all, db, JoinPaths(dir, "matching"), o.sfm, fresh_names);
    return ojson{{"selection", m.selection}, {"pairs", m.pairs}, {"verified", m.verified}};
  });
  *fingerprint = Hash(fp_matches + "register");
  stages.Run("update-register", *fingerprint, [&] {
    const std::string reg = JoinPaths(dir, "registered"), tri = JoinPaths(dir, "triangulated");
    const std::string model = JoinPaths(dir, "model");
    for (const std::string& d : {reg, tri, model}) {
      fs::remove_all(d);
      CreateDirectories(d);
    }
    const std::string seed = std::to_string(o.sfm.seed);
    const std::string threads = std::to_string(o.sfm.threads);
    RunColmapCommand(
        {o.sfm.colmap.executable, "image_registrator", "--database_path", db, "--input_path",
         released, "--output_path", reg, "--random_seed", seed, "--Mapper.num_threads", threads},
        JoinPaths(dir, "image_registrator.log"), o.sfm.colmap);
    RunColmapCommand({o.sfm.colmap.executable, "point_triangulator", "--database_path", db,
                      "--image_path", project.Path("images"), "--input_path", reg, "--output_path",
                      tri, "--random_seed", seed, "--Mapper.num_threads", threads},
                     JoinPaths(dir, "point_triangulator.log"), o.sfm.colmap);
    const bool fixed = AllGiven(fresh);
    std::vector<std::string> ba = {o.sfm.colmap.executable, "bundle_adjuster",
                                   "--input_path",          tri,
                                   "--output_path",         model,
                                   "--random_seed",         seed};
    if (fixed) {
      for (const char* f :
           {"--BundleAdjustment.refine_focal_length", "--BundleAdjustment.refine_principal_point",
            "--BundleAdjustment.refine_extra_params"}) {
        ba.push_back(f);
        ba.push_back("0");
      }
    }
    RunColmapCommand(ba, JoinPaths(dir, "bundle_adjuster.log"), o.sfm.colmap);
    const Reconstruction r = ReadColmapModel(model);
    return ojson{{"registered", r.images.size()}, {"points", r.points3D.size()}};
  });
  return JoinPaths(dir, "model");
}

void LiftStage(const MapOptions& o, Project& project, const std::string& model_dir,
               const std::string& fingerprint, Stages& stages, MapReport* report,
               std::string* key_path) {
  const ojson d =
      stages.Run("lift", Hash(fingerprint + "lift" + o.key_store + "\n" + o.key_file), [&] {
        LiftModelOptions lift;
        lift.model_dir = model_dir;
        lift.out_path = project.Path("map.lcm");
        lift.key_store = o.key_store;
        lift.key_file = o.key_file;
        lift.database = project.Path("database.db");
        lift.identity_salt = project.Salt();
        lift.force = true;  // the project's own staging file, replaced by each version
        const LiftModelResult r = LiftModel(lift);
        const IdentityResult& id = r.identity;
        return ojson{{"lines", r.cloud.size()},
                     {"from_observations", id.from_observations},
                     {"from_released_place", id.from_released_place},
                     {"from_same_place", id.from_same_place},
                     {"fresh", id.fresh},
                     {"key", r.key_path},
                     {"key_source", r.key_source},
                     {"georeferenced", r.georeferenced}};
      });
  *key_path = d.value("key", "");
  report->lines = d.value("lines", size_t{0});
}

ojson AuditStage(Project& project, const std::string& model_dir, const std::string& key_path,
                 Stages& stages) {
  InputFingerprint fp;
  fp.AddFile(project.Path("map.lcm"));
  fp.Add(model_dir);
  return stages.Run("audit", fp.Hex(), [&] {
    AuditOptions a;
    a.map_path = project.Path("map.lcm");
    a.model_dir = model_dir;
    a.out_dir = project.Path("audit");
    a.key_file = key_path;
    const AuditReport r = RunAudit(a);
    return ojson(ToJson(r));
  });
}

void Publish(const MapOptions& o, Project& project, const Reconstruction& model,
             const std::map<std::string, Eigen::Vector3d>& gps, const ojson& audit,
             MapReport* report) {
  const std::string base = o.out;
  CreateDirectories(fs::path(base).parent_path().empty() ? "."
                                                         : fs::path(base).parent_path().string());
  const std::string lcm = base + ".lcm";
  const std::string staged = ReadFileToString(project.Path("map.lcm"));
  if (FileExists(lcm)) {
    const LineCloud there = ReadLineCloud(lcm);
    const LineCloud ours = ParseLineCloud(staged, project.Path("map.lcm"));
    if (there.key_fingerprint != ours.key_fingerprint) {
      Fail(
          "{}: a map lifted with another key (another project or owner) is served there; "
          "choose another --out",
          lcm);
    }
  }
  std::string note;
  const std::optional<GeoAnchor> anchor = AnchorFromGps(model, gps, &note);
  LogProgress("[map] publish: {}", note);
  ojson info = anchor ? GeoAnchorToJson(*anchor) : ojson::object();
  // The served audit names no private path.
  ojson served_audit = audit;
  served_audit["model"] = "(private)";
  served_audit["map"] = fs::path(lcm).filename().string();
  CheckServedFolder(base);
  WriteFileAtomically(lcm, [&](std::ostream& out) { out << staged; });
  WriteFileAtomically(base + ".json", [&](std::ostream& out) { out << info.dump(1) << "\n"; });
  if (!audit.is_null()) {
    WriteFileAtomically(base + ".audit.json",
                        [&](std::ostream& out) { out << served_audit.dump(1) << "\n"; });
    report->map_audit = base + ".audit.json";
  }
  report->map = lcm;
  report->map_json = base + ".json";
}

}  // namespace

namespace {

// The model of this run: a new map's, or the released one with new photos.
std::string ModelStages(const MapOptions& o, const PhotoSet& photos, Project& project,
                        Stages& stages, MapReport* report, std::string* fingerprint) {
  if (!o.update) return BuildModel(o, photos, project, stages, report, fingerprint);
  if (!photos.photos.empty()) return UpdateModel(o, photos, project, stages, fingerprint);
  LogProgress("[map] every photo is already in the project; nothing to add");
  const std::string model_dir = project.Path(project.manifest().value("model", "model"));
  *fingerprint = Hash(model_dir);
  return model_dir;
}

// Every photo of the project by name, and the GPS of those that carry it.
struct ProjectPhotos {
  std::vector<std::string> names;
  std::map<std::string, Eigen::Vector3d> gps;
};

ProjectPhotos PhotosOf(Project& project, const PhotoSet& fresh) {
  ProjectPhotos out;
  for (const auto& p : project.manifest()["photos"]) {
    out.names.push_back(p.value("name", ""));
    if (p.contains("gps") && p["gps"].is_array() && p["gps"].size() == 3) {
      out.gps[out.names.back()] = {p["gps"][0].get<double>(), p["gps"][1].get<double>(),
                                   p["gps"][2].get<double>()};
    }
  }
  for (const Photo& p : fresh.photos) {
    if (std::find(out.names.begin(), out.names.end(), p.name) == out.names.end()) {
      out.names.push_back(p.name);
    }
    if (p.gps) out.gps[p.name] = *p.gps;
  }
  return out;
}

// What the model holds, which photos it left out and why, and (when given)
// how far its cameras are from the survey's.
void ReportModel(const MapOptions& o, const Reconstruction& model,
                 const std::vector<std::string>& names, Project& project, MapReport* report) {
  Describe(model, report);
  report->unregistered =
      WhyUnregistered(names, model, project.Path("database.db"), project.Path("sparse"));
  LogProgress(
      "[map] model: {} of {} photos registered, {} points, mean track length {:.2f}, "
      "mean reprojection error {:.2f} px",
      report->registered, names.size(), report->points, report->mean_track_length,
      report->mean_reprojection_error_px);
  for (const auto& [name, why] : report->unregistered) {
    LogProgress("[map]   not registered: {}: {}", name, why);
  }
  if (o.ground_truth.empty()) return;
  report->ground_truth = CompareWithGroundTruth(model, o.ground_truth);
  LogProgress(
      "[map] against {}: camera centres within {:.3f} % of the scene's extent, rotations "
      "within {:.3f} deg ({} images)",
      o.ground_truth, report->ground_truth["max_centre_error_extent_percent"].get<double>(),
      report->ground_truth["max_rotation_error_deg"].get<double>(),
      report->ground_truth["images"].get<size_t>());
}

void ReportLineChanges(Project& project, MapReport* report) {
  const std::string released = project.Path("released.lcm");
  if (!FileExists(released)) return;
  const LineChanges c =
      CompareLines(ReadLineCloud(released), ReadLineCloud(project.Path("map.lcm")));
  report->lines_kept = c.kept;
  report->lines_new = c.added;
  report->lines_withdrawn = c.withdrawn;
  LogProgress("[map] lines: {} released lines kept, {} new, {} withdrawn", c.kept, c.added,
              c.withdrawn);
}

// Once everything is done: the project's photos and released model, the
// released lines (what the next update is compared with), the report.
void FinishProject(const MapOptions& o, const PhotoSet& fresh, const std::string& model_dir,
                   Project& project, const MapReport& report) {
  if (o.update && !fresh.photos.empty()) {
    for (const Photo& p : fresh.photos) project.manifest()["photos"].push_back(PhotoEntry(p));
    project.manifest()["versions"].push_back(
        {{"model", project.manifest().value("model", "model")},
         {"lines", project.manifest().value("lines", size_t{0})}});
    project.manifest()["model"] = fs::relative(model_dir, project.dir()).string();
  }
  project.manifest()["lines"] = report.lines;
  project.Save();
  const std::string staged = ReadFileToString(project.Path("map.lcm"));
  WriteFileAtomically(project.Path("released.lcm"), [&](std::ostream& out) { out << staged; });
  WriteFileAtomically(project.Path("report.json"),
                      [&](std::ostream& out) { out << report.ToJson().dump(1) << "\n"; });
}

}  // namespace

MapReport BuildMap(const MapOptions& o) {
  o.Check();
  MapReport report;
  report.update = o.update;
  Project project(o.project_dir);
  const auto t0 = std::chrono::steady_clock::now();
  const PhotoSet photos = OpenProject(o, &project, &report);
  report.stages.push_back({"photos",
                           false,
                           SecondsSince(t0),
                           {{"photos", report.photos},
                            {"new", photos.photos.size()},
                            {"cameras", photos.cameras.size()}}});
  for (const PhotoCamera& c : photos.cameras) {
    LogProgress("[map] camera {}: {}", CameraText(c.camera), c.source);
  }
  Stages stages(project, &report);
  std::string fingerprint;
  const std::string model_dir = ModelStages(o, photos, project, stages, &report, &fingerprint);
  const Reconstruction model = ReadColmapModel(model_dir);
  const ProjectPhotos all = PhotosOf(project, photos);
  ReportModel(o, model, all.names, project, &report);
  std::string key_path;
  LiftStage(o, project, model_dir, fingerprint, stages, &report, &key_path);
  if (o.update) ReportLineChanges(project, &report);
  const ojson audit = o.audit ? AuditStage(project, model_dir, key_path, stages) : ojson();
  if (!o.out.empty()) Publish(o, project, model, all.gps, audit, &report);
  FinishProject(o, photos, model_dir, project, report);
  return report;
}

}  // namespace linecloud
