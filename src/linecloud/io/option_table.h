// Options described once — name, type, range or choices, default, help, and
// the member they read and write — so that the command line's flags,
// Python's keyword arguments and the service's fields are made from one
// description and cannot drift (docs/architecture.md: how to add an option).
// An `OptionField<Options>` describes one option of the struct `Options`; a
// table is a vector of them (pipeline/localizer_option_table.h for the
// Localizer, privacy/attack_option_table.h for the density attack).
#pragma once

#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace linecloud {

enum class OptionType {
  kBool,
  kInteger,    // a whole number within [min, max]
  kNumber,     // a finite number within the range
  kChoice,     // one of `choices`
  kDirection,  // a finite non-zero 3-vector: [x, y, z], or "x,y,z" as text
};

// 2^53: the largest whole number exact in a double and in JSON.
constexpr double kMaxInteger = 9007199254740992.0;

struct OptionDescription {
  std::string name;  // snake_case; the flag is --name-with-dashes
  OptionType type = OptionType::kNumber;
  std::string help;
  double min = 0, max = 0;           // kInteger, kNumber
  bool min_open = false;             // kNumber: (min, max] instead of [min, max]
  bool max_open = false;             // kNumber: [min, max) (or (min, max))
  std::vector<std::string> choices;  // kChoice
  // null is a value: "not set" (the map's gravity, the method's inlier count).
  bool nullable = false;
  std::string null_means;  // what null stands for, in the help

  // --max-ratio; a switch on by default is turned off by --no-NAME.
  std::string Flag(const nlohmann::json& default_value) const;
  // "a number in (0, 1]", "one of colmap, opencv", ...
  std::string Describe() const;
};

// `value` checked (type, range, choices; errors "WHERE: NAME must be ..., got ...") and
// normalised (booleans, whole numbers, a direction as three numbers).
nlohmann::json CheckedOptionValue(const OptionDescription& option, const nlohmann::json& value,
                                  std::string_view where);
// A value written as text (a flag's argument, a multipart part): true/false,
// numbers, a choice, "x,y,z", "null" where null is allowed.
nlohmann::json ParseOptionText(const OptionDescription& option, std::string_view text,
                               std::string_view where);
// {name, flag, type, default, help[, min, max, min_open, max_open][, choices][, null_means]}.
nlohmann::json OptionDescriptionJson(const OptionDescription& option,
                                     const nlohmann::json& default_value);
[[noreturn]] void FailUnknownOption(const std::string& key, const std::vector<std::string>& known,
                                    std::string_view where);

// One option of `Options`: its description and the member it reads and writes.
template <typename Options>
struct OptionField : OptionDescription {
  using OptionsType = Options;
  std::function<nlohmann::json(const Options&)> get;
  std::function<void(Options&, const nlohmann::json&)> set;  // the value already checked

  nlohmann::json Default() const { return get(Options{}); }  // on a default Options
  std::string Flag() const { return OptionDescription::Flag(Default()); }
};

// A field over a member of type T (bool, an integer or double), read and written through
// `member`, which returns a reference to it.
template <typename Options, typename T>
OptionField<Options> MemberField(std::string name, OptionType type, std::string help,
                                 std::function<T&(Options&)> member) {
  OptionField<Options> f;
  f.name = std::move(name);
  f.type = type;
  f.help = std::move(help);
  f.get = [member](const Options& o) { return nlohmann::json(member(const_cast<Options&>(o))); };
  f.set = [member](Options& o, const nlohmann::json& v) {
    if constexpr (std::is_same_v<T, bool>) {
      member(o) = v.get<bool>();
    } else {
      member(o) = static_cast<T>(v.get<double>());
    }
  };
  return f;
}

template <typename Options>
const OptionField<Options>* FindOption(std::span<const OptionField<Options>> table,
                                       std::string_view name) {
  for (const OptionField<Options>& f : table) {
    if (f.name == name) return &f;
  }
  return nullptr;
}

// Checks `value` and sets it on `options`.
template <typename Options>
void SetOption(Options* options, const OptionField<Options>& field, const nlohmann::json& value,
               std::string_view where) {
  field.set(*options, CheckedOptionValue(field, value, where));
}

// Sets every option of the JSON object `fields`; a key that names no option fails, listing them.
template <typename Options>
void SetOptions(Options* options, std::span<const OptionField<Options>> table,
                const nlohmann::json& fields, std::string_view where) {
  for (const auto& [key, value] : fields.items()) {
    const OptionField<Options>* field = FindOption(table, key);
    if (!field) {
      std::vector<std::string> known;
      for (const OptionField<Options>& f : table) known.push_back(f.name);
      FailUnknownOption(key, known, where);
    }
    SetOption(options, *field, value, where);
  }
}

// The table itself: what `linecloud options --json` prints.
template <typename Options>
nlohmann::json OptionTableJson(std::span<const OptionField<Options>> table) {
  nlohmann::json out = nlohmann::json::array();
  for (const OptionField<Options>& f : table) out.push_back(OptionDescriptionJson(f, f.Default()));
  return out;
}

}  // namespace linecloud
