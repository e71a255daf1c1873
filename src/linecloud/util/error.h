// Error type used across linecloud: every failure a user can cause (bad file,
// bad field, bad value) is reported by throwing linecloud::Error with a message
// that names the file or field at fault. The CLI prints it as `error: <what>`.
#pragma once

#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace linecloud {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

template <typename... Args>
[[noreturn]] void Fail(fmt::format_string<Args...> format, Args&&... args) {
  throw Error(fmt::format(format, std::forward<Args>(args)...));
}

}  // namespace linecloud
