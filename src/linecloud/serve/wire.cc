#include "linecloud/serve/wire.h"

#include "linecloud/util/error.h"

namespace linecloud {

int JsonNestingDepth(std::string_view text, int limit) {
  int depth = 0, deepest = 0;
  bool in_string = false, escaped = false;
  for (const char c : text) {
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        in_string = false;
      }
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > deepest) deepest = depth;
      if (deepest > limit) return limit + 1;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return deepest;
}

nlohmann::json ParseRequestJson(std::string_view body, std::string_view what) {
  if (JsonNestingDepth(body, kMaxRequestJsonDepth) > kMaxRequestJsonDepth) {
    Fail("{}: JSON nested deeper than {} levels", what, kMaxRequestJsonDepth);
  }
  try {
    return nlohmann::json::parse(body);
  } catch (const nlohmann::json::exception& e) {
    Fail("{}: not JSON ({})", what, e.what());
  }
}

std::string DumpJson(const nlohmann::json& j) {
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace linecloud
