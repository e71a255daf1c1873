// `linecloud options`: the Localizer's option table (localizer_option_table.h) and
// lift's, the attack's and audit's (lift_option_table.h, attack_option_table.h):
// the one description the CLI's flags, Python's keyword arguments and the
// service's request fields are made from; docs/options.md is its Markdown.
#include <iostream>
#include <memory>
#include <span>

#include <fmt/format.h>

#include "linecloud/apps/commands.h"
#include "linecloud/pipeline/localizer_option_table.h"
#include "linecloud/privacy/attack_option_table.h"
#include "linecloud/privacy/lift_option_table.h"

namespace linecloud {
namespace {

// attack / audit: the same columns without the scope.
template <typename Options>
std::string TableMarkdown(std::span<const OptionField<Options>> table) {
  std::string out =
      "| name (Python) | flag (CLI) | value | default | what it does |\n"
      "|---|---|---|---|---|\n";
  for (const OptionField<Options>& s : table) {
    const nlohmann::json d = s.Default();
    out += fmt::format("| `{}` | `{}` | {} | {} | {} |\n", s.name, s.Flag(), s.Describe(),
                       d.is_string() ? d.get<std::string>() : d.dump(), s.help);
  }
  return out;
}

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
  auto table = std::make_shared<std::string>("localizer");
  CLI::App* cmd = app.add_subcommand(
      "options",
      "An option table: each option's name (Python keyword, HTTP field), flag, range and default. "
      "The Localizer's (with its scope — map: fixed when a map is loaded; request: a default "
      "each request may change), lift's, the density attack's or the audit's");
  cmd->add_flag("--json", *json,
                "Print JSON (as Python's linecloud.localizer_options(), lift_options(), "
                "attack_options(), audit_options())");
  cmd->add_option("--table", *table, "Which table")
      ->check(CLI::IsMember({"localizer", "lift", "attack", "audit"}))
      ->capture_default_str();
  cmd->callback([json, table] {
    if (*table == "lift") {
      std::cout << (*json ? OptionTableJson(std::span(LiftOptionTable())).dump(2) + "\n"
                          : TableMarkdown(std::span(LiftOptionTable())));
    } else if (*table == "attack") {
      std::cout << (*json ? OptionTableJson(std::span(AttackOptionTable())).dump(2) + "\n"
                          : TableMarkdown(std::span(AttackOptionTable())));
    } else if (*table == "audit") {
      std::cout << (*json ? OptionTableJson(std::span(AuditOptionTable())).dump(2) + "\n"
                          : TableMarkdown(std::span(AuditOptionTable())));
    } else {
      std::cout << (*json ? LocalizerOptionTableJson().dump(2) + "\n" : OptionsMarkdown());
    }
  });
}

}  // namespace linecloud
