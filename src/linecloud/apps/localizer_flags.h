// The command line's flags of the Localizer's options, made from
// localizer_option_table.h: `localize` takes every option, `serve` the ones
// that are a map's or a request's default.
#pragma once

#include <map>
#include <set>
#include <span>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "linecloud/apps/option_flags.h"
#include "linecloud/pipeline/localizer_option_table.h"

namespace linecloud {

class LocalizerFlags {
 public:
  // One flag per option of `scopes` not in `skip` (the command's own flags).
  void Add(CLI::App* cmd, std::span<const OptionScope> scopes,
           const std::set<std::string>& skip = {});
  // Sets the options given on the command line on `options`, in the table's
  // order; a bad value fails naming its flag.
  void Apply(LocalizerOptions* options) const { flags_.Apply(options); }

 private:
  OptionFlags<OptionSpec> flags_;
};

}  // namespace linecloud
