#include "linecloud/apps/localizer_flags.h"

#include <algorithm>

namespace linecloud {

void LocalizerFlags::Add(CLI::App* cmd, std::span<const OptionScope> scopes,
                         const std::set<std::string>& skip) {
  // Applied in the table's order (exact_matching after approximate_from, as everywhere).
  flags_.Add(cmd, std::span(LocalizerOptionTable()), [&](const OptionSpec& spec) {
    return !skip.count(spec.name) &&
           std::find(scopes.begin(), scopes.end(), spec.scope) != scopes.end();
  });
}

}  // namespace linecloud
