// Reading linecloud's JSON inputs with errors that name the file and field.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "linecloud/geometry/plucker.h"
#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// Parses a JSON file; throws Error naming the path on read or syntax errors.
nlohmann::json ReadJsonFile(const std::string& path);

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
