// Whitespace-separated text records (COLMAP .txt files, cameras.txt-style
// lists). Comment lines start with '#'. Every parse error names the file, the
// line and the field.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "linecloud/util/error.h"

namespace linecloud {

class TextLines {
 public:
  TextLines(std::string_view data, std::string source) : data_(data), source_(std::move(source)) {}

  // Next non-empty, non-comment line; false at the end.
  bool Next(std::string_view* line) {
    std::string_view l;
    while (NextRaw(&l)) {
      const size_t first = l.find_first_not_of(" \t");
      if (first == std::string_view::npos || l[first] == '#') continue;
      *line = l;
      return true;
    }
    return false;
  }

  // Next line whatever it holds (used for the 2D-point line of images.txt,
  // which may be empty); false at the end.
  bool NextRaw(std::string_view* line) {
    if (pos_ >= data_.size()) return false;
    size_t end = data_.find('\n', pos_);
    if (end == std::string_view::npos) end = data_.size();
    std::string_view l = data_.substr(pos_, end - pos_);
    pos_ = end + 1;
    ++line_number_;
    if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
    *line = l;
    return true;
  }

  size_t LineNumber() const { return line_number_; }
  const std::string& Source() const { return source_; }

  [[noreturn]] void FailHere(std::string_view message) const {
    Fail("{}:{}: {}", source_, line_number_, message);
  }

 private:
  std::string_view data_;
  size_t pos_ = 0;
  size_t line_number_ = 0;
  std::string source_;
};

inline std::vector<std::string_view> SplitWhitespace(std::string_view line) {
  std::vector<std::string_view> tokens;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t') ++j;
    if (j > i) tokens.push_back(line.substr(i, j - i));
    i = j;
  }
  return tokens;
}

template <typename T>
T ParseNumber(std::string_view token, const TextLines& lines, std::string_view field) {
  T value{};
  const char* begin = token.data();
  const char* end = token.data() + token.size();
  if (!token.empty() && *begin == '+') ++begin;
  const auto [ptr, ec] = std::from_chars(begin, end, value);
  if (ec != std::errc() || ptr != end) {
    lines.FailHere("field '" + std::string(field) + "': cannot parse '" + std::string(token) +
                   "' as a number");
  }
  if constexpr (std::is_floating_point_v<T>) {
    if (!std::isfinite(value)) {
      lines.FailHere("field '" + std::string(field) + "' is not finite ('" + std::string(token) +
                     "')");
    }
  }
  return value;
}

}  // namespace linecloud
