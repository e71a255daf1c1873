// The command line's flags made from an option table (io/option_table.h):
// a switch (--NAME, or --no-NAME for an option on by default) or a flag with
// a value, parsed and checked by the table, so the flag takes what the
// Python keyword and the HTTP field take.
#pragma once

#include <functional>
#include <map>
#include <set>
#include <span>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "linecloud/io/option_table.h"

namespace linecloud {

// Adds `option`'s flag to `cmd`: `on_switch` when a bool option's flag is
// given, `on_text` with a value flag's argument as typed.
void AddOptionFlag(CLI::App* cmd, const OptionDescription& option,
                   const nlohmann::json& default_value, std::function<void()> on_switch,
                   std::function<void(const std::string&)> on_text);

// `Field`: OptionField<Options>, or a type derived from it (the Localizer's OptionSpec).
template <typename Field>
class OptionFlags {
 public:
  using Options = typename Field::OptionsType;

  // One flag per option of `table` (those `include` accepts, when given).
  void Add(CLI::App* cmd, std::span<const Field> table,
           const std::function<bool(const Field&)>& include = nullptr) {
    table_ = table;
    for (const Field& f : table) {
      if (include && !include(f)) continue;
      const std::string name = f.name;
      AddOptionFlag(
          cmd, f, f.Default(), [this, name] { switches_.insert(name); },
          [this, name](const std::string& v) { text_[name] = v; });
    }
  }
  // Sets the options given on the command line, in the table's order; a bad
  // value fails naming its flag.
  void Apply(Options* options) const {
    for (const Field& f : table_) {
      if (switches_.count(f.name)) {
        SetOption(options, f, !f.Default().template get<bool>(), f.Flag());
      } else if (const auto it = text_.find(f.name); it != text_.end()) {
        SetOption(options, f, ParseOptionText(f, it->second, f.Flag()), f.Flag());
      }
    }
  }

 private:
  std::span<const Field> table_;
  std::map<std::string, std::string> text_;  // option name → argument as typed
  std::set<std::string> switches_;           // bool options whose flag was given
};

}  // namespace linecloud
