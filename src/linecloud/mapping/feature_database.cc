#include "linecloud/mapping/feature_database.h"

#include <sqlite3.h>

#include <cmath>
#include <cstring>

#include <fmt/format.h>

#include "linecloud/io/colmap_database.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

class Stmt {
 public:
  Stmt(sqlite3* db, const std::string& path, const char* sql) : db_(db), path_(path) {
    if (sqlite3_prepare_v2(db, sql, -1, &stmt_, nullptr) != SQLITE_OK) {
      Fail("{}: cannot write the COLMAP database ({})", path_, sqlite3_errmsg(db));
    }
  }
  ~Stmt() { sqlite3_finalize(stmt_); }
  Stmt(const Stmt&) = delete;
  Stmt& operator=(const Stmt&) = delete;
  void Int(int i, int64_t v) { sqlite3_bind_int64(stmt_, i, v); }
  void Real(int i, double v) { sqlite3_bind_double(stmt_, i, v); }
  void Null(int i) { sqlite3_bind_null(stmt_, i); }
  void Text(int i, const std::string& v) {
    sqlite3_bind_text(stmt_, i, v.c_str(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
  }
  void Blob(int i, const void* data, size_t bytes) {
    sqlite3_bind_blob64(stmt_, i, data, bytes, SQLITE_TRANSIENT);
  }
  bool Step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    Fail("{}: cannot write the COLMAP database ({})", path_, sqlite3_errmsg(db_));
  }
  int64_t Col(int i) const { return sqlite3_column_int64(stmt_, i); }
  const void* ColBlob(int i, size_t* bytes) const {
    *bytes = static_cast<size_t>(sqlite3_column_bytes(stmt_, i));
    return sqlite3_column_blob(stmt_, i);
  }

 private:
  sqlite3* db_;
  const std::string& path_;
  sqlite3_stmt* stmt_ = nullptr;
};

}  // namespace

FeatureDatabaseWriter::FeatureDatabaseWriter(const std::string& path) : path_(path) {
  ColmapDatabase check(path);  // names the file when it is none (or lacks the tables)
  if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READWRITE, nullptr) != SQLITE_OK) {
    const std::string message = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    db_ = nullptr;
    Fail("{}: cannot open the COLMAP database for writing ({})", path, message);
  }
  sqlite3_busy_timeout(db_, 10000);
}

FeatureDatabaseWriter::~FeatureDatabaseWriter() { sqlite3_close(db_); }

void FeatureDatabaseWriter::Exec(const char* sql) {
  char* message = nullptr;
  if (sqlite3_exec(db_, sql, nullptr, nullptr, &message) != SQLITE_OK) {
    const std::string text = message ? message : "unknown error";
    sqlite3_free(message);
    Fail("{}: cannot write the COLMAP database ({})", path_, text);
  }
}

uint32_t FeatureDatabaseWriter::FindOrAddCamera(const Camera& camera, bool prior_focal_length) {
  {
    Stmt find(db_, path_,
              "SELECT camera_id, params FROM cameras WHERE model=? AND width=? AND height=?");
    find.Int(1, static_cast<int>(camera.model_id));
    find.Int(2, static_cast<int64_t>(camera.width));
    find.Int(3, static_cast<int64_t>(camera.height));
    while (find.Step()) {
      size_t bytes = 0;
      const void* data = find.ColBlob(1, &bytes);
      if (bytes == camera.params.size() * sizeof(double) &&
          (bytes == 0 || std::memcmp(data, camera.params.data(), bytes) == 0)) {
        return static_cast<uint32_t>(find.Col(0));
      }
    }
  }
  Stmt add(db_, path_,
           "INSERT INTO cameras(model, width, height, params, prior_focal_length) "
           "VALUES(?, ?, ?, ?, ?)");
  add.Int(1, static_cast<int>(camera.model_id));
  add.Int(2, static_cast<int64_t>(camera.width));
  add.Int(3, static_cast<int64_t>(camera.height));
  add.Blob(4, camera.params.data(), camera.params.size() * sizeof(double));
  add.Int(5, prior_focal_length ? 1 : 0);
  add.Step();
  return static_cast<uint32_t>(sqlite3_last_insert_rowid(db_));
}

std::optional<uint32_t> FeatureDatabaseWriter::FindImage(const std::string& name) const {
  Stmt find(db_, path_, "SELECT image_id FROM images WHERE name=?");
  find.Text(1, name);
  if (!find.Step()) return std::nullopt;
  return static_cast<uint32_t>(find.Col(0));
}

bool FeatureDatabaseWriter::HasFeatures(uint32_t image_id) const {
  Stmt find(db_, path_,
            "SELECT (SELECT rows FROM keypoints WHERE image_id=?1), (SELECT rows FROM "
            "descriptors WHERE image_id=?1)");
  find.Int(1, image_id);
  if (!find.Step()) return false;
  return find.Col(0) > 0 && find.Col(0) == find.Col(1);
}

uint32_t FeatureDatabaseWriter::AddImage(const std::string& name, uint32_t camera_id,
                                         const std::optional<Eigen::Vector3d>& gps) {
  if (const auto id = FindImage(name)) return *id;
  Stmt add(
      db_, path_,
      "INSERT INTO images(name, camera_id, prior_tx, prior_ty, prior_tz) VALUES(?, ?, ?, ?, ?)");
  add.Text(1, name);
  add.Int(2, camera_id);
  for (int k = 0; k < 3; ++k) {
    if (gps) {
      add.Real(3 + k, (*gps)[k]);
    } else {
      add.Null(3 + k);
    }
  }
  add.Step();
  return static_cast<uint32_t>(sqlite3_last_insert_rowid(db_));
}

uint32_t FeatureDatabaseWriter::WriteImage(const std::string& name, uint32_t camera_id,
                                           const SiftFeatures& features,
                                           const std::optional<Eigen::Vector3d>& gps) {
  Exec("BEGIN IMMEDIATE");
  try {
    const std::optional<uint32_t> id = AddImage(name, camera_id, gps);
    // COLMAP's SIFT keypoints: x, y and the affine shape a11 a12 a21 a22 of
    // the scale and orientation (FeatureKeypoint(x, y, scale, orientation)).
    std::vector<float> kp(6 * features.size());
    for (size_t i = 0; i < features.size(); ++i) {
      const SiftKeypoint& k = features.keypoints[i];
      const float c = std::cos(k.orientation), s = std::sin(k.orientation);
      float* row = kp.data() + 6 * i;
      row[0] = k.x;
      row[1] = k.y;
      row[2] = k.scale * c;
      row[3] = -k.scale * s;
      row[4] = k.scale * s;
      row[5] = k.scale * c;
    }
    for (const char* table : {"keypoints", "descriptors"}) {
      const bool keypoints = table[0] == 'k';
      Stmt put(db_, path_,
               keypoints ? "INSERT OR REPLACE INTO keypoints(image_id, rows, cols, data) "
                           "VALUES(?, ?, ?, ?)"
                         : "INSERT OR REPLACE INTO descriptors(image_id, rows, cols, data) "
                           "VALUES(?, ?, ?, ?)");
      put.Int(1, *id);
      put.Int(2, static_cast<int64_t>(features.size()));
      put.Int(3, keypoints ? 6 : 128);
      if (keypoints) {
        put.Blob(4, kp.data(), kp.size() * sizeof(float));
      } else {
        put.Blob(4, features.descriptors.data(), features.descriptors.size());
      }
      put.Step();
    }
    Exec("COMMIT");
    return *id;
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    throw;
  }
}

void FeatureDatabaseWriter::ClearMatches() {
  Exec("DELETE FROM matches; DELETE FROM two_view_geometries;");
}

void FeatureDatabaseWriter::ClearMatchesOf(const std::vector<uint32_t>& image_ids) {
  Exec("BEGIN IMMEDIATE");
  try {
    for (uint32_t id : image_ids) {
      for (const char* sql : {"DELETE FROM matches WHERE pair_id / 2147483647 = ?1 OR pair_id % "
                              "2147483647 = ?1",
                              "DELETE FROM two_view_geometries WHERE pair_id / 2147483647 = ?1 OR "
                              "pair_id % 2147483647 = ?1"}) {
        Stmt del(db_, path_, sql);
        del.Int(1, id);
        del.Step();
      }
    }
    Exec("COMMIT");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    throw;
  }
}

}  // namespace linecloud
