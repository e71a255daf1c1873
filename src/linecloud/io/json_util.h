// Reading linecloud's JSON inputs with errors that name the file and field.
#pragma once

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

// Field accessors: `where` names the file and field path in errors
// ("problem.json: bearings[2]").
Eigen::Vector3d JsonVector3(const nlohmann::json& j, const std::string& where);
std::vector<Eigen::Vector3d> JsonVector3List(const nlohmann::json& j, const std::string& where);
std::vector<PluckerLine> JsonLineList(const nlohmann::json& j, const std::string& where);
// {"q": [w, x, y, z], "t": [x, y, z]}; the quaternion is normalised.
Rigid3d JsonPose(const nlohmann::json& j, const std::string& where);

nlohmann::json PoseToJson(const Eigen::Quaterniond& q, const Eigen::Vector3d& t);

}  // namespace linecloud
