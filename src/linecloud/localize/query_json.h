// QUERY.json of `linecloud localize` (../shared/SPEC.md) and its result JSON.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "linecloud/localize/localize.h"

namespace linecloud {

// Throws Error naming `source` and the field on any malformed entry.
Query ParseQueryJson(const nlohmann::json& j, const std::string& source);
Query ReadQueryJson(const std::string& path);

nlohmann::json QueryToJson(const Query& query);

// {"method", "success", "q", "t", "scale", "inliers", "stats": {...}}.
nlohmann::json LocalizeResultToJson(const MethodInfo& method, const LocalizeResult& result);

}  // namespace linecloud
