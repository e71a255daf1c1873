#include "linecloud/io/colmap_database.h"

#include <sqlite3.h>

#include <cctype>
#include <cstring>
#include <filesystem>
#include <tuple>

#include <fmt/format.h>

#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

constexpr uint64_t kMaxNumImages = 2147483647;

// RAII wrapper over a prepared statement; every failure names the database.
class Statement {
 public:
  Statement(sqlite3* db, const std::string& path, const char* sql) : db_(db), path_(path) {
    if (sqlite3_prepare_v2(db, sql, -1, &stmt_, nullptr) != SQLITE_OK) {
      Fail("{}: cannot query COLMAP database ({})", path_, sqlite3_errmsg(db));
    }
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  void BindInt64(int index, int64_t value) { sqlite3_bind_int64(stmt_, index, value); }
  void BindText(int index, const char* text) {
    sqlite3_bind_text(stmt_, index, text, -1, SQLITE_TRANSIENT);
  }

  // True while a row is available.
  bool Step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    Fail("{}: corrupt or unreadable COLMAP database ({})", path_, sqlite3_errmsg(db_));
  }

  int64_t Int64(int col) const { return sqlite3_column_int64(stmt_, col); }
  std::string Text(int col) const {
    const unsigned char* text = sqlite3_column_text(stmt_, col);
    return text ? reinterpret_cast<const char*>(text) : "";
  }
  bool IsNull(int col) const { return sqlite3_column_type(stmt_, col) == SQLITE_NULL; }
  const void* Blob(int col, size_t* bytes) const {
    const void* data = sqlite3_column_blob(stmt_, col);
    *bytes = static_cast<size_t>(sqlite3_column_bytes(stmt_, col));
    return data;
  }

 private:
  sqlite3* db_;
  const std::string& path_;
  sqlite3_stmt* stmt_ = nullptr;
};

template <typename Matrix>
Matrix ReadBlobMatrix(const Statement& stmt, int rows_col, int cols_col, int data_col,
                      const std::string& path, const std::string& what) {
  using Scalar = typename Matrix::Scalar;
  const int64_t rows = stmt.Int64(rows_col);
  const int64_t cols = stmt.Int64(cols_col);
  if (rows < 0 || cols < 0 ||
      (Matrix::ColsAtCompileTime != Eigen::Dynamic && cols != Matrix::ColsAtCompileTime)) {
    Fail("{}: {}: invalid shape {}x{}", path, what, rows, cols);
  }
  size_t bytes = 0;
  const void* data = stmt.Blob(data_col, &bytes);
  // rows x cols x sizeof must not wrap around (a row count of 2^62 + 1 would
  // "match" a small blob and then ask for exabytes).
  size_t expected = 0;
  if (__builtin_mul_overflow(static_cast<uint64_t>(rows), static_cast<uint64_t>(cols), &expected) ||
      __builtin_mul_overflow(expected, sizeof(Scalar), &expected)) {
    Fail("{}: {}: shape {}x{} is too large for any blob", path, what, rows, cols);
  }
  if (bytes != expected) {
    Fail("{}: {}: blob has {} bytes, expected {} for {}x{} values", path, what, bytes, expected,
         rows, cols);
  }
  Matrix m(rows, cols);
  if (expected > 0) std::memcpy(m.data(), data, expected);
  return m;
}

Eigen::Matrix3d ReadMatrix3d(const Statement& stmt, int col) {
  size_t bytes = 0;
  const void* data = stmt.Blob(col, &bytes);
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> m =
      Eigen::Matrix<double, 3, 3, Eigen::RowMajor>::Zero();
  if (bytes == 9 * sizeof(double)) std::memcpy(m.data(), data, bytes);
  return m;
}

}  // namespace

uint64_t ImagePairToPairId(uint32_t image_id1, uint32_t image_id2) {
  if (image_id1 > image_id2) std::swap(image_id1, image_id2);
  return kMaxNumImages * image_id1 + image_id2;
}

std::pair<uint32_t, uint32_t> PairIdToImagePair(uint64_t pair_id) {
  const uint32_t image_id2 = static_cast<uint32_t>(pair_id % kMaxNumImages);
  const uint32_t image_id1 = static_cast<uint32_t>((pair_id - image_id2) / kMaxNumImages);
  return {image_id1, image_id2};
}

ColmapDatabase::ColmapDatabase(const std::string& path) : path_(path) {
  if (!FileExists(path)) Fail("{}: database file not found", path);
  if (IsDirectory(path)) Fail("{}: is a directory, expected a COLMAP database", path);
  // Reading must not write: a database in WAL mode (as COLMAP leaves them)
  // opened read-only still gets -shm / -wal files created beside it, and fails
  // on read-only media. Opened as immutable it gets none — unless a non-empty
  // write-ahead log holds data COLMAP has not checkpointed, which only a normal
  // (read-only) open reads.
  std::error_code ec;
  const bool pending_wal = std::filesystem::exists(path + "-wal", ec) &&
                           std::filesystem::file_size(path + "-wal", ec) > 0;
  std::string uri = "file:";
  for (const char c : std::filesystem::absolute(path, ec).string()) {
    const bool plain = std::isalnum(static_cast<unsigned char>(c)) || c == '/' || c == '.' ||
                       c == '-' || c == '_' || c == '~';
    uri += plain ? std::string(1, c) : fmt::format("%{:02X}", static_cast<unsigned char>(c));
  }
  uri += pending_wal ? "?mode=ro" : "?mode=ro&immutable=1";
  if (sqlite3_open_v2(uri.c_str(), &db_, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI, nullptr) !=
      SQLITE_OK) {
    const std::string message = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    db_ = nullptr;
    Fail("{}: cannot open database ({})", path, message);
  }
  try {
    for (const char* table :
         {"cameras", "images", "keypoints", "descriptors", "matches", "two_view_geometries"}) {
      Statement stmt(db_, path_,
                     "SELECT count(*) FROM sqlite_master WHERE type='table' "
                     "AND name=?");
      stmt.BindText(1, table);
      if (!stmt.Step() || stmt.Int64(0) == 0) {
        Fail("{}: not a COLMAP database (table '{}' is missing)", path, table);
      }
    }
  } catch (...) {
    sqlite3_close(db_);
    db_ = nullptr;
    throw;
  }
}

ColmapDatabase::~ColmapDatabase() { sqlite3_close(db_); }

size_t ColmapDatabase::ImagesWithPositionPriors() const {
  const auto count = [&](const char* sql) {
    Statement stmt(db_, path_, sql);
    return stmt.Step() ? static_cast<size_t>(std::max<int64_t>(stmt.Int64(0), 0)) : size_t{0};
  };
  if (count("SELECT COUNT(*) FROM sqlite_master WHERE type = 'table' AND name = 'pose_priors'")) {
    return count("SELECT COUNT(*) FROM pose_priors");
  }
  if (!count("SELECT COUNT(*) FROM pragma_table_info('images') WHERE name = 'prior_tx'")) return 0;
  return count(
      "SELECT COUNT(*) FROM images WHERE prior_tx IS NOT NULL AND prior_ty IS NOT NULL AND "
      "prior_tz IS NOT NULL AND (prior_tx != 0 OR prior_ty != 0 OR prior_tz != 0)");
}

std::vector<Camera> ColmapDatabase::ReadCameras() const {
  std::vector<Camera> cameras;
  Statement stmt(db_, path_,
                 "SELECT camera_id, model, width, height, params FROM cameras "
                 "ORDER BY camera_id");
  while (stmt.Step()) {
    Camera camera;
    camera.camera_id = static_cast<uint32_t>(stmt.Int64(0));
    const int64_t model = stmt.Int64(1);
    camera.model_id = CameraModelFromInt(static_cast<int>(model));
    camera.width = static_cast<uint64_t>(stmt.Int64(2));
    camera.height = static_cast<uint64_t>(stmt.Int64(3));
    size_t bytes = 0;
    const void* data = stmt.Blob(4, &bytes);
    if (bytes % sizeof(double) != 0) {
      Fail("{}: cameras: camera {} params blob has {} bytes", path_, camera.camera_id, bytes);
    }
    camera.params.resize(bytes / sizeof(double));
    if (bytes > 0) std::memcpy(camera.params.data(), data, bytes);
    if (camera.model_id == CameraModelId::kInvalid) {
      Fail("{}: cameras: camera {} has unsupported model id {}", path_, camera.camera_id, model);
    }
    camera.Check(path_ + ": cameras");
    cameras.push_back(std::move(camera));
  }
  return cameras;
}

std::vector<DatabaseImage> ColmapDatabase::ReadImages() const {
  std::vector<DatabaseImage> images;
  Statement stmt(db_, path_,
                 "SELECT image_id, name, camera_id FROM images ORDER BY "
                 "image_id");
  while (stmt.Step()) {
    DatabaseImage image;
    image.image_id = static_cast<uint32_t>(stmt.Int64(0));
    image.name = stmt.Text(1);
    image.camera_id = static_cast<uint32_t>(stmt.Int64(2));
    images.push_back(std::move(image));
  }
  return images;
}

FeatureKeypoints ColmapDatabase::ReadKeypoints(uint32_t image_id) const {
  Statement stmt(db_, path_, "SELECT rows, cols, data FROM keypoints WHERE image_id=?");
  stmt.BindInt64(1, image_id);
  if (!stmt.Step()) return FeatureKeypoints();
  FeatureKeypoints kp = ReadBlobMatrix<FeatureKeypoints>(
      stmt, 0, 1, 2, path_, "keypoints of image " + std::to_string(image_id));
  if (kp.rows() > 0 && kp.cols() != 2 && kp.cols() != 4 && kp.cols() != 6) {
    Fail("{}: keypoints of image {}: expected 2, 4 or 6 columns, got {}", path_, image_id,
         kp.cols());
  }
  return kp;
}

FeatureDescriptors ColmapDatabase::ReadDescriptors(uint32_t image_id) const {
  Statement stmt(db_, path_, "SELECT rows, cols, data FROM descriptors WHERE image_id=?");
  stmt.BindInt64(1, image_id);
  if (!stmt.Step()) return FeatureDescriptors();
  return ReadBlobMatrix<FeatureDescriptors>(stmt, 0, 1, 2, path_,
                                            "descriptors of image " + std::to_string(image_id));
}

FeatureMatches ColmapDatabase::ReadMatches(uint32_t image_id1, uint32_t image_id2) const {
  Statement stmt(db_, path_, "SELECT rows, cols, data FROM matches WHERE pair_id=?");
  stmt.BindInt64(1, static_cast<int64_t>(ImagePairToPairId(image_id1, image_id2)));
  if (!stmt.Step()) return FeatureMatches();
  FeatureMatches m = ReadBlobMatrix<FeatureMatches>(
      stmt, 0, 1, 2, path_, fmt::format("matches of images {}-{}", image_id1, image_id2));
  if (image_id1 > image_id2) m.col(0).swap(m.col(1));
  return m;
}

std::vector<ImagePairMatches> ColmapDatabase::ReadAllMatches() const {
  std::vector<ImagePairMatches> all;
  Statement stmt(db_, path_,
                 "SELECT pair_id, rows, cols, data FROM matches WHERE rows > 0 "
                 "ORDER BY pair_id");
  while (stmt.Step()) {
    ImagePairMatches pair;
    std::tie(pair.image_id1, pair.image_id2) =
        PairIdToImagePair(static_cast<uint64_t>(stmt.Int64(0)));
    pair.matches = ReadBlobMatrix<FeatureMatches>(
        stmt, 1, 2, 3, path_,
        fmt::format("matches of images {}-{}", pair.image_id1, pair.image_id2));
    all.push_back(std::move(pair));
  }
  return all;
}

std::vector<TwoViewGeometry> ColmapDatabase::ReadTwoViewGeometries() const {
  std::vector<TwoViewGeometry> all;
  Statement stmt(db_, path_,
                 "SELECT pair_id, rows, cols, data, config, F, E, H FROM "
                 "two_view_geometries ORDER BY pair_id");
  while (stmt.Step()) {
    TwoViewGeometry g;
    std::tie(g.image_id1, g.image_id2) = PairIdToImagePair(static_cast<uint64_t>(stmt.Int64(0)));
    g.inlier_matches = ReadBlobMatrix<FeatureMatches>(
        stmt, 1, 2, 3, path_,
        fmt::format("two-view geometry of images {}-{}", g.image_id1, g.image_id2));
    g.config = static_cast<int>(stmt.Int64(4));
    g.F = ReadMatrix3d(stmt, 5);
    g.E = ReadMatrix3d(stmt, 6);
    g.H = ReadMatrix3d(stmt, 7);
    all.push_back(std::move(g));
  }
  return all;
}

}  // namespace linecloud
