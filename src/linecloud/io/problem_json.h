// PROBLEM.json of `linecloud solve` (SPEC.md): one minimal problem — the
// method and its sample (bearings, points or lines, local points, cameras).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "linecloud/solvers/minimal_problem.h"

namespace linecloud {

struct MinimalProblem {
  const MethodInfo* method = nullptr;
  MinimalSample sample;  // bearings normalised; checked with CheckSample
};

// Throws Error naming `source` and the field on anything malformed.
MinimalProblem ParseProblemJson(const nlohmann::json& j, const std::string& source);

}  // namespace linecloud
