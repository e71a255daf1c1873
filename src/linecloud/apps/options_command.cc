// `linecloud options`: the Localizer's option table (localizer_option_table.h),
// the one description the CLI's flags, Python's keyword arguments and the
// service's request fields are made from; docs/options.md is its Markdown.
#include <iostream>
#include <memory>

#include <fmt/format.h>

#include "linecloud/apps/commands.h"
#include "linecloud/pipeline/localizer_option_table.h"

namespace linecloud {
namespace {

std::string OptionsMarkdown() {
  std::string out =
      "| name (Python, HTTP) | flag (CLI) | scope | value | default | what it does |\n"
      "|---|---|---|---|---|---|\n";
  for (const OptionSpec& s : LocalizerOptionTable()) {
    const nlohmann::json d = s.Default();
    const std::string shown = d.is_null()     ? s.null_means
                              : d.is_string() ? d.get<std::string>()
                                              : d.dump();
    out +=
        fmt::format("| `{}` | `{}` | {} | {} | {} | {} |\n", s.name, s.Flag(),
                    s.scope == OptionScope::kMap ? "map" : "request", s.Describe(), shown, s.help);
  }
  return out;
}

}  // namespace

void RegisterOptionsCommand(CLI::App& app) {
  auto json = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "options",
      "The Localizer's options: each one's name (Python keyword, HTTP field), flag, scope (map: "
      "fixed when a map is loaded; request: a default each request may change), range and "
      "default");
  cmd->add_flag("--json", *json, "Print JSON (as Python's linecloud.localizer_options())");
  cmd->callback([json] {
    std::cout << (*json ? LocalizerOptionTableJson().dump(2) + "\n" : OptionsMarkdown());
  });
}

}  // namespace linecloud
