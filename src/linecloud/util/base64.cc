#include "linecloud/util/base64.h"

#include <sodium.h>

#include "linecloud/util/error.h"

namespace linecloud {

std::string Base64Encode(std::span<const uint8_t> bytes) {
  std::string out(sodium_base64_ENCODED_LEN(bytes.size(), sodium_base64_VARIANT_ORIGINAL), '\0');
  sodium_bin2base64(out.data(), out.size(), bytes.data(), bytes.size(),
                    sodium_base64_VARIANT_ORIGINAL);
  out.pop_back();  // the terminating NUL
  return out;
}

std::string Base64Decode(std::string_view text, const std::string& field) {
  std::string out(text.size() / 4 * 3 + 3, '\0');
  size_t len = 0;
  if (sodium_base642bin(reinterpret_cast<unsigned char*>(out.data()), out.size(), text.data(),
                        text.size(), " \n\r", &len, nullptr, sodium_base64_VARIANT_ORIGINAL) != 0) {
    Fail("{}: not base64", field);
  }
  out.resize(len);
  return out;
}

}  // namespace linecloud
