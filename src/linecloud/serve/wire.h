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

// The deepest nesting of `[` / `{` in `text`, brackets inside strings left
// out; stops counting once `limit` is exceeded (returns limit + 1).
int JsonNestingDepth(std::string_view text, int limit);

// Parses a request body; throws Error naming `what` when it is not JSON or is
// nested deeper than kMaxRequestJsonDepth.
nlohmann::json ParseRequestJson(std::string_view body, std::string_view what);

// JSON text with every invalid UTF-8 sequence replaced (U+FFFD): errors echo
// what a client sent, and a map file's name is whatever bytes the folder has.
std::string DumpJson(const nlohmann::json& j);

}  // namespace linecloud
