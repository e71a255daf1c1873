#include "linecloud/apps/localizer_flags.h"

#include <algorithm>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "linecloud/util/error.h"

namespace linecloud {

void LocalizerFlags::Add(CLI::App* cmd, std::span<const OptionScope> scopes,
                         const std::set<std::string>& skip) {
  for (const OptionSpec& spec : LocalizerOptionTable()) {
    if (skip.count(spec.name) ||
        std::find(scopes.begin(), scopes.end(), spec.scope) == scopes.end()) {
      continue;
    }
    const std::string name = spec.name;
    if (spec.type == OptionType::kBool) {
      // A switch off by default turns it on; one on by default is --no-NAME.
      const bool on = spec.Default().get<bool>();
      cmd->add_flag_function(
             spec.Flag(), [this, name](std::int64_t) { switches_.insert(name); },
             spec.help + (on ? " (on by default; this flag turns it off)" : ""))
          ->disable_flag_override();  // a switch takes no value: --no-refine=false is an error
      continue;
    }
    std::string help = spec.help;
    if (spec.nullable) help += " (default: " + spec.null_means + ")";
    CLI::Option* option = cmd->add_option_function<std::string>(
        spec.Flag(), [this, name](const std::string& v) { text_[name] = v; }, help);
    switch (spec.type) {
      case OptionType::kInteger:
        option->type_name("INT");
        break;
      case OptionType::kNumber:
        option->type_name("NUMBER");
        break;
      case OptionType::kChoice:
        option->type_name(fmt::format("{{{}}}", fmt::join(spec.choices, ",")));
        break;
      default:
        option->type_name("X,Y,Z");
    }
    if (!spec.nullable) {
      const nlohmann::json d = spec.Default();
      option->default_str(d.is_string() ? d.get<std::string>() : d.dump());
    }
  }
}

void LocalizerFlags::Apply(LocalizerOptions* options) const {
  // In the table's order (exact_matching after approximate_from, as everywhere).
  for (const OptionSpec& spec : LocalizerOptionTable()) {
    if (switches_.count(spec.name)) {
      SetLocalizerOption(options, spec, !spec.Default().get<bool>(), spec.Flag());
    } else if (const auto it = text_.find(spec.name); it != text_.end()) {
      SetLocalizerOption(options, spec, ParseOptionText(spec, it->second, spec.Flag()),
                         spec.Flag());
    }
  }
}

}  // namespace linecloud
