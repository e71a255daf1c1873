// Base64 (RFC 4648, with padding): descriptors and images in JSON bodies (the
// service, OSCP GeoPose). Encoding by libsodium, decoding by a table.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>

namespace linecloud {

std::string Base64Encode(std::span<const uint8_t> bytes);
// Throws Error naming `field` on anything but base64 (whitespace is skipped).
std::string Base64Decode(std::string_view text, const std::string& field);

}  // namespace linecloud
