#include "linecloud/serve/wire.h"

#include <algorithm>
#include <vector>

#include "linecloud/io/json_util.h"
#include "linecloud/util/error.h"

namespace linecloud {

JsonShape ScanJsonShape(std::string_view text) {
  JsonShape shape;
  int depth = 0;
  bool in_string = false, escaped = false;
  // Colons of each open object (arrays hold a placeholder), up to the depth that is refused.
  std::vector<size_t> keys;
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
      shape.depth = std::max(shape.depth, ++depth);
      ++shape.values;
      if (depth <= kMaxRequestJsonDepth + 1) keys.push_back(0);
    } else if (c == ']' || c == '}') {
      if (depth-- <= kMaxRequestJsonDepth + 1 && !keys.empty()) keys.pop_back();
    } else if (c == ',') {
      ++shape.values;
    } else if (c == ':') {  // a key is a value too (its string)
      ++shape.values;
      if (!keys.empty()) shape.max_keys = std::max(shape.max_keys, ++keys.back());
    }
  }
  return shape;
}

nlohmann::json ParseRequestJson(std::string_view body, std::string_view what) {
  const JsonShape shape = ScanJsonShape(body);
  if (shape.depth > kMaxRequestJsonDepth) {
    Fail("{}: JSON nested deeper than {} levels", what, kMaxRequestJsonDepth);
  }
  if (shape.values > kMaxRequestJsonValues) {
    Fail("{}: more than {} JSON values (arrays, numbers, strings, ...)", what,
         kMaxRequestJsonValues);
  }
  if (shape.max_keys > kMaxRequestJsonKeys) {
    Fail("{}: an object of more than {} keys", what, kMaxRequestJsonKeys);
  }
  try {
    return ParseJsonUniqueKeys(body, std::string(what));
  } catch (const nlohmann::json::exception& e) {
    // The parser's own words without its library's tag ("[json.exception.parse_error.101] ").
    std::string_view message = e.what();
    if (message.rfind("[json.exception.", 0) == 0 && message.find("] ") != std::string_view::npos) {
      message.remove_prefix(message.find("] ") + 2);
    }
    Fail("{}: not JSON ({})", what, message);
  }
}

std::string DumpJson(const nlohmann::json& j) {
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace linecloud
