// Reading linecloud's JSON inputs with errors that name the file and field.
#pragma once

#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "linecloud/geometry/plucker.h"
#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// Parses a JSON file; throws Error naming the path on read or syntax errors and on an object
// with a key twice.
nlohmann::json ReadJsonFile(const std::string& path);

// Parses JSON text like nlohmann::json::parse (its exceptions on a syntax error), but refuses an
// object that has a key twice with an Error naming `where` and the key. (The parser would keep the
// last value: {"max_seconds": 1, "max_seconds": 900} would mean 900 here and 1 to another reader.)
nlohmann::json ParseJsonUniqueKeys(std::string_view text, const std::string& where);

// A value or name as an error message shows what a client sent: JSON text
// (escaped: no raw NUL, line break or invalid UTF-8), at most ~80 characters.
std::string ShownInMessage(const nlohmann::json& value);

// Refuses an object field not in `known` (it would be ignored): "WHERE: unknown field "x"
// (known, ...)"; without `where`, "unknown field ...".
void RefuseUnknownFields(const nlohmann::json& object,
                         std::initializer_list<std::string_view> known, std::string_view where);

// Field accessors: `where` names the file and field path in errors
// ("problem.json: bearings[2]").
Eigen::Vector3d JsonVector3(const nlohmann::json& j, const std::string& where);
std::vector<Eigen::Vector3d> JsonVector3List(const nlohmann::json& j, const std::string& where);
std::vector<PluckerLine> JsonLineList(const nlohmann::json& j, const std::string& where);
// {"q": [w, x, y, z], "t": [x, y, z]}; the quaternion is normalised; any other field is refused.
Rigid3d JsonPose(const nlohmann::json& j, const std::string& where);

// An object's fields, read with errors that name the source and the field's path
// ("report.json.methods.p6L.queries: missing"); for typed reports read back (ToJson's inverse).
// The object must outlive this view.
class JsonFields {
 public:
  JsonFields(const nlohmann::json& j, std::string where);  // throws Error unless an object
  bool Has(const char* key) const { return j_.contains(key); }
  std::string Where(const std::string& key) const { return where_ + "." + key; }
  const nlohmann::json& At(const char* key) const;  // present, any type
  double Number(const char* key) const;
  double NumberOrNull(const char* key, double if_null) const;  // null: a non-finite value
  std::optional<double> Optional(const char* key, double if_null) const;  // absent: nullopt
  int Int(const char* key) const;
  size_t Count(const char* key) const;        // an integer >= 0
  double Share(const char* key) const;        // a number in [0, 1]
  double NonNegative(const char* key) const;  // a finite number >= 0
  bool Bool(const char* key) const;
  std::string String(const char* key) const;
  std::string StringOr(const char* key, const std::string& otherwise) const;
  JsonFields Object(const char* key) const;
  const nlohmann::json& Array(const char* key) const;
  std::vector<double> Numbers(const char* key) const;  // null entries: NaN
  std::vector<std::string> Strings(const char* key) const;
  const nlohmann::json& raw() const { return j_; }
  const std::string& where() const { return where_; }

 private:
  const nlohmann::json& j_;
  std::string where_;
};

nlohmann::json PoseToJson(const Eigen::Quaterniond& q, const Eigen::Vector3d& t);

}  // namespace linecloud
