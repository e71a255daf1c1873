// Fuzzes linecloud's JSON inputs past the JSON syntax: QUERY.json
// (localize --query), PROBLEM.json (solve) and prepared.json (eval run); the
// first byte picks the reader. Every failure must be linecloud::Error naming
// the file and field: any other exception escapes and is a finding.
#include <cstddef>
#include <cstdint>

#include <nlohmann/json.hpp>

#include "linecloud/eval/eval_work.h"
#include "linecloud/io/problem_json.h"
#include "linecloud/localize/query_json.h"
#include "linecloud/util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const nlohmann::json j =
      nlohmann::json::parse(data + 1, data + size, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) return 0;  // not JSON: ReadJsonFile reports it
  try {
    switch (data[0] % 3) {
      case 0:
        linecloud::ParseQueryJson(j, "query.json");
        break;
      case 1:
        linecloud::ParseProblemJson(j, "problem.json");
        break;
      case 2:
        linecloud::EvalWorkFromJson(j, "prepared.json");
        break;
    }
  } catch (const linecloud::Error&) {
  }
  return 0;
}
