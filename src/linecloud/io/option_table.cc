#include "linecloud/io/option_table.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "linecloud/io/json_util.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using json = nlohmann::json;

std::string Number(double v) {
  if (v == kMaxInteger) return "2^53";
  if (std::abs(v) >= 1e6 && v == std::floor(v)) return fmt::format("{:.0f}", v);
  return fmt::format("{}", v);
}

[[noreturn]] void Expected(const OptionDescription& spec, const json& value,
                           std::string_view where) {
  Fail("{}: {} must be {}, got {}", where, spec.name, spec.Describe(), ShownInMessage(value));
}

bool InRange(const OptionDescription& spec, double v) {
  const bool above = spec.min_open ? v > spec.min : v >= spec.min;
  const bool below = spec.max_open ? v < spec.max : v <= spec.max;
  return std::isfinite(v) && above && below;
}

// The value checked and normalised: booleans, whole numbers, a direction as
// three numbers.
json CheckedValueImpl(const OptionDescription& spec, const json& value, std::string_view where) {
  if (value.is_null()) {
    if (!spec.nullable) Expected(spec, value, where);
    return value;
  }
  switch (spec.type) {
    case OptionType::kBool:
      if (!value.is_boolean()) Expected(spec, value, where);
      return value;
    case OptionType::kInteger: {
      if (!value.is_number()) Expected(spec, value, where);
      if (value.is_number_unsigned()) {  // exact: no rounding through a double (2^53 + 1)
        const uint64_t u = value.get<uint64_t>();
        if (u > static_cast<uint64_t>(spec.max) || static_cast<double>(u) < spec.min) {
          Expected(spec, value, where);
        }
        return value;
      }
      const double v = value.get<double>();
      if (v != std::floor(v) || !InRange(spec, v)) Expected(spec, value, where);
      return json(static_cast<int64_t>(v));
    }
    case OptionType::kNumber:
      if (!value.is_number() || !InRange(spec, value.get<double>())) Expected(spec, value, where);
      return json(value.get<double>());
    case OptionType::kChoice:
      if (!value.is_string() || std::find(spec.choices.begin(), spec.choices.end(),
                                          value.get<std::string>()) == spec.choices.end()) {
        Expected(spec, value, where);
      }
      return value;
    case OptionType::kDirection: {
      if (value.is_string()) {
        return CheckedValueImpl(spec, ParseOptionText(spec, value.get<std::string>(), where),
                                where);
      }
      if (!value.is_array() || value.size() != 3) Expected(spec, value, where);
      double norm = 0;
      for (const json& x : value) {
        if (!x.is_number() || !std::isfinite(x.get<double>())) Expected(spec, value, where);
        norm += x.get<double>() * x.get<double>();
      }
      if (!(norm > 0)) Expected(spec, value, where);
      return json{value[0].get<double>(), value[1].get<double>(), value[2].get<double>()};
    }
  }
  Expected(spec, value, where);
}

}  // namespace

std::string OptionDescription::Flag(const json& default_value) const {
  std::string flag = name;
  std::replace(flag.begin(), flag.end(), '_', '-');
  if (type == OptionType::kBool && default_value == json(true)) return "--no-" + flag;
  return "--" + flag;
}

std::string OptionDescription::Describe() const {
  std::string text;
  switch (type) {
    case OptionType::kBool:
      text = "true or false";
      break;
    case OptionType::kInteger:
      text = fmt::format("a whole number in [{}, {}]", Number(min), Number(max));
      break;
    case OptionType::kNumber:
      text = fmt::format("a number in {}{}, {}{}", min_open ? "(" : "[", Number(min), Number(max),
                         max_open ? ")" : "]");
      break;
    case OptionType::kChoice:
      text = fmt::format("one of {}", fmt::join(choices, ", "));
      break;
    case OptionType::kDirection:
      text = "a finite non-zero direction [x, y, z] (\"x,y,z\" as text)";
      break;
  }
  if (nullable) text += " or null";
  return text;
}

json CheckedOptionValue(const OptionDescription& spec, const json& value, std::string_view where) {
  return CheckedValueImpl(spec, value, where);
}

json ParseOptionText(const OptionDescription& spec, std::string_view text, std::string_view where) {
  const std::string s(text);
  if (spec.nullable && s == "null") return json();
  switch (spec.type) {
    case OptionType::kBool:
      if (s == "true") return true;
      if (s == "false") return false;
      break;
    case OptionType::kInteger:
    case OptionType::kNumber: {
      // A JSON number and nothing else (no hex, "+3", "3.", "nan", spaces):
      // the text means what the same value in a JSON body means.
      if (s.empty() || s.size() > 64 || std::isspace(static_cast<unsigned char>(s.front())) ||
          std::isspace(static_cast<unsigned char>(s.back()))) {
        break;
      }
      const json v = json::parse(s, nullptr, false);
      if (v.is_discarded() || !v.is_number()) break;
      return v;
    }
    case OptionType::kChoice:
      return json(s);
    case OptionType::kDirection: {
      json out = json::array();
      size_t begin = 0;
      for (int k = 0; k < 3; ++k) {
        const size_t end = k < 2 ? s.find(',', begin) : s.size();
        if (end == std::string::npos) Expected(spec, json(s), where);
        const std::string part = s.substr(begin, end - begin);
        char* stop = nullptr;
        const double v = std::strtod(part.c_str(), &stop);
        if (part.empty() || stop != part.c_str() + part.size()) Expected(spec, json(s), where);
        out.push_back(v);
        begin = end + 1;
      }
      return out;
    }
  }
  Expected(spec, json(s), where);
}

json OptionDescriptionJson(const OptionDescription& s, const json& default_value) {
  json o = {{"name", s.name},
            {"flag", s.Flag(default_value)},
            {"type", s.Describe()},
            {"default", default_value},
            {"help", s.help}};
  if (s.type == OptionType::kInteger || s.type == OptionType::kNumber) {
    o["min"] = s.min;
    o["max"] = s.max;
    o["min_open"] = s.min_open;
    o["max_open"] = s.max_open;
  }
  if (!s.choices.empty()) o["choices"] = s.choices;
  if (s.nullable) o["null_means"] = s.null_means;
  return o;
}

[[noreturn]] void FailUnknownOption(const std::string& key, const std::vector<std::string>& known,
                                    std::string_view where) {
  Fail("{}: unknown option {} (known: {})", where, ShownInMessage(json(key)),
       fmt::join(known, ", "));
}

}  // namespace linecloud
