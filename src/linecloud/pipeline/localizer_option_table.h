// One description of every option a Localizer and its requests take. The
// command line's flags (`--max-ratio`, `--no-refine`), Python's keyword
// arguments (`max_ratio=`, `refine=False`) and the service's request fields
// (`"max_ratio"`, a multipart part `max_ratio`) are all made from this table,
// so the three accept the same names, types, ranges and defaults
// (docs/architecture.md: how to add an option).
#pragma once

#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "linecloud/io/option_table.h"
#include "linecloud/pipeline/localizer.h"

namespace linecloud {

enum class OptionScope {
  kMap,      // fixed when the Localizer is made: SIFT, matching, the index, threads
  kRequest,  // the Localizer holds a default; each request may change it (RANSAC, success)
};

// A Localizer's option, and its scope.
struct OptionSpec : OptionField<LocalizerOptions> {
  OptionScope scope = OptionScope::kRequest;
};

// Every option, in the order the help lists them.
const std::vector<OptionSpec>& LocalizerOptionTable();
// The option named `name`, or nullptr.
const OptionSpec* FindLocalizerOption(std::string_view name);
// The names of the options of `scopes`, in the table's order (error messages).
std::vector<std::string> LocalizerOptionNames(std::span<const OptionScope> scopes);

// Checks `value` (type, range, choices; errors "WHERE: NAME must be ...,
// got ...") and sets it on `options` (ParseOptionText in io/option_table.h reads text).
void SetLocalizerOption(LocalizerOptions* options, const OptionSpec& spec,
                        const nlohmann::json& value, std::string_view where);
// Sets every option of the JSON object `fields` whose scope is in `scopes`;
// a key of another scope or no option at all fails naming it (unless listed
// in `other_keys`, the caller's own fields, which are skipped here).
void SetLocalizerOptions(LocalizerOptions* options, const nlohmann::json& fields,
                         std::span<const OptionScope> scopes, std::string_view where,
                         std::span<const std::string_view> other_keys = {});
// Every option's value (name → JSON), e.g. a Localizer's effective options.
nlohmann::json LocalizerOptionsToJson(const LocalizerOptions& options);
// The table itself (name, type, scope, default, range, choices, help): what
// `linecloud options --json` prints and Python's `localizer_options()` returns.
nlohmann::json LocalizerOptionTableJson();

}  // namespace linecloud
