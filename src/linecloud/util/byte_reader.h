// Bounds-checked little-endian reading from an in-memory buffer. Every read
// names the source and the field, so truncated or corrupt binary files give a
// precise error instead of undefined behaviour or a huge allocation.
#pragma once

#include <cstdint>
#include <bit>
#include <cmath>
#include <cstring>
#include <ostream>
#include <string>
#include <string_view>
#include <type_traits>

#include "linecloud/util/error.h"

namespace linecloud {

static_assert(std::endian::native == std::endian::little,
              "linecloud's binary formats are little-endian; big-endian hosts "
              "are not supported");

class ByteReader {
 public:
  ByteReader(std::string_view data, std::string source) : data_(data), source_(std::move(source)) {}

  template <typename T>
  T Read(std::string_view field) {
    static_assert(std::is_trivially_copyable_v<T>);
    Require(sizeof(T), field);
    T value;
    std::memcpy(&value, data_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }

  double ReadFiniteDouble(std::string_view field) {
    const double value = Read<double>(field);
    if (!std::isfinite(value)) {
      Fail("{}: field '{}' at byte {} is not a finite number", source_, field,
           pos_ - sizeof(double));
    }
    return value;
  }

  // Reads a NUL-terminated string.
  std::string ReadCString(std::string_view field) {
    const size_t end = data_.find('\0', pos_);
    if (end == std::string_view::npos) {
      Fail("{}: truncated: unterminated string '{}' at byte {}", source_, field, pos_);
    }
    std::string value(data_.substr(pos_, end - pos_));
    pos_ = end + 1;
    return value;
  }

  // Reads a record count and checks that `count * min_record_bytes` bytes can
  // still follow, so that a corrupt count cannot trigger a huge allocation.
  uint64_t ReadCount(std::string_view field, size_t min_record_bytes) {
    const uint64_t count = Read<uint64_t>(field);
    if (min_record_bytes > 0 && count > Remaining() / min_record_bytes) {
      Fail("{}: corrupt or truncated: '{}' = {} but only {} bytes remain", source_, field, count,
           Remaining());
    }
    return count;
  }

  void Require(size_t bytes, std::string_view field) const {
    if (bytes > Remaining()) {
      Fail(
          "{}: truncated while reading '{}' at byte {} ({} bytes needed, {} "
          "left)",
          source_, field, pos_, bytes, Remaining());
    }
  }

  std::string_view ReadBytes(size_t bytes, std::string_view field) {
    Require(bytes, field);
    std::string_view view = data_.substr(pos_, bytes);
    pos_ += bytes;
    return view;
  }

  size_t Remaining() const { return data_.size() - pos_; }
  size_t Position() const { return pos_; }
  bool AtEnd() const { return pos_ == data_.size(); }
  const std::string& Source() const { return source_; }

 private:
  std::string_view data_;
  size_t pos_ = 0;
  std::string source_;
};

template <typename T>
void WriteLE(std::ostream& out, const T& value) {
  static_assert(std::is_trivially_copyable_v<T>);
  out.write(reinterpret_cast<const char*>(&value), sizeof(T));
}

}  // namespace linecloud
