#include "linecloud/apps/option_flags.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

namespace linecloud {

void AddOptionFlag(CLI::App* cmd, const OptionDescription& spec,
                   const nlohmann::json& default_value, std::function<void()> on_switch,
                   std::function<void(const std::string&)> on_text) {
  if (spec.type == OptionType::kBool) {
    // A switch off by default turns it on; one on by default is --no-NAME.
    const bool on = default_value.get<bool>();
    cmd->add_flag_function(
           spec.Flag(default_value), [on_switch](std::int64_t) { on_switch(); },
           spec.help + (on ? " (on by default; this flag turns it off)" : ""))
        ->disable_flag_override();  // a switch takes no value: --no-refine=false is an error
    return;
  }
  std::string help = spec.help;
  if (spec.nullable) help += " (default: " + spec.null_means + ")";
  CLI::Option* option =
      cmd->add_option_function<std::string>(spec.Flag(default_value), std::move(on_text), help);
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
    option->default_str(default_value.is_string() ? default_value.get<std::string>()
                                                  : default_value.dump());
  }
}

}  // namespace linecloud
