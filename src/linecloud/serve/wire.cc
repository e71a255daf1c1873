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

size_t JsonValueBound(std::string_view text) {
  size_t values = 1;
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
    } else if (c == '[' || c == '{' || c == ',') {
      ++values;
    }
  }
  return values;
}

nlohmann::json ParseRequestJson(std::string_view body, std::string_view what) {
  if (JsonNestingDepth(body, kMaxRequestJsonDepth) > kMaxRequestJsonDepth) {
    Fail("{}: JSON nested deeper than {} levels", what, kMaxRequestJsonDepth);
  }
  if (JsonValueBound(body) > kMaxRequestJsonValues) {
    Fail("{}: more than {} JSON values (arrays, numbers, strings, ...)", what,
         kMaxRequestJsonValues);
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
