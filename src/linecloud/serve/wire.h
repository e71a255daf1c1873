// What the service reads from and writes to the wire, whoever sends it:
// bounded JSON parsing and JSON that is always valid UTF-8.
#pragma once

#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace linecloud {

// Deepest nesting of arrays and objects a request body may have. Parsing is
// iterative, but copying and comparing a parsed value recurse: 150 000 levels
// overflowed the stack (a SIGSEGV, found by an outsider's review).
constexpr int kMaxRequestJsonDepth = 64;

// Values (numbers, strings, arrays, ...) a request body may hold: a parsed
// value costs ~50-100 bytes, so 16 MB of `[[],[],...]` (5.5 M values) took
// 400 MB to parse (an outsider's find); a features body of 100 000 keypoints
// holds ~300 000.
constexpr size_t kMaxRequestJsonValues = 400'000;

// Keys one object of a request body may have: the API's objects have a
// handful; an object of 60 000 keys cost ~50 ms of parsing a request, and an
// attacker's stream of them the other clients' latency (the soak's p99 6.5×).
constexpr size_t kMaxRequestJsonKeys = 1000;

// What a request body's text says of its parsed size, brackets, commas and
// colons inside strings left out: the deepest nesting of `[` / `{`, an upper
// bound on its values (brackets, commas and colons, plus one) and on the keys
// of its largest object (its colons).
struct JsonShape {
  int depth = 0;
  size_t values = 1;
  size_t max_keys = 0;
};
JsonShape ScanJsonShape(std::string_view text);

// Parses a request body; throws Error naming `what` when it is not JSON, is
// nested deeper than kMaxRequestJsonDepth, holds more than
// kMaxRequestJsonValues values or an object of more than kMaxRequestJsonKeys
// keys (all found by a scan of the text, before parsing).
nlohmann::json ParseRequestJson(std::string_view body, std::string_view what);

// JSON text with every invalid UTF-8 sequence replaced (U+FFFD): errors echo
// what a client sent, and a map file's name is whatever bytes the folder has.
std::string DumpJson(const nlohmann::json& j);

}  // namespace linecloud
