// The tokens the service's tests share: alice reads map "synth", bob "other",
// slow may use every map once a minute, root is an admin.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "linecloud/serve/tokens.h"
#include "linecloud/util/file.h"

namespace linecloud {

inline void WriteTestTokens(const std::string& path) {
  const nlohmann::json tokens = {
      {"tokens",
       {{{"id", "alice"}, {"sha256", TokenSha256Hex("alice-secret")}, {"maps", {"synth"}}},
        {{"id", "bob"}, {"sha256", TokenSha256Hex("bob-secret")}, {"maps", {"other"}}},
        {{"id", "slow"},
         {"sha256", TokenSha256Hex("slow-secret")},
         {"maps", {"*"}},
         {"requests_per_minute", 1}},
        {{"id", "root"},
         {"sha256", TokenSha256Hex("root-secret")},
         {"maps", {"*"}},
         {"admin", true}}}}};
  WriteFileAtomically(path, [&](std::ostream& os) { os << tokens.dump(); });
}

}  // namespace linecloud
