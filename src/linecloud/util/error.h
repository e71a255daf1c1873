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

// A file that cannot be opened, read or written (the operating system said
// no): `error_number` is errno (0 when unknown). Bindings raise OSError.
class FileError : public Error {
 public:
  FileError(const std::string& what, int error_number) : Error(what), error_number_(error_number) {}
  int error_number() const { return error_number_; }

 private:
  int error_number_ = 0;
};

// A caller's deadline passed while work was under way (a service's request):
// the pipeline answers "no pose" naming the stage, not an error.
class DeadlinePassed : public Error {
 public:
  using Error::Error;
};

template <typename... Args>
[[noreturn]] void Fail(fmt::format_string<Args...> format, Args&&... args) {
  throw Error(fmt::format(format, std::forward<Args>(args)...));
}

template <typename... Args>
[[noreturn]] void FailFile(int error_number, fmt::format_string<Args...> format, Args&&... args) {
  throw FileError(fmt::format(format, std::forward<Args>(args)...), error_number);
}

}  // namespace linecloud
