// Fuzzes the .lcm reader: any input must either parse into a valid line
// cloud or throw linecloud::Error — never crash, hang or over-allocate.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include <sodium.h>

#include "linecloud/io/lcm_format.h"
#include "linecloud/util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  // The file's last 32 bytes are the BLAKE2b-256 of the rest (SPEC.md): set
  // them right, so that mutations reach the parser behind the checksum (the
  // reader itself always checks it; the tests share this build).
  std::string input(reinterpret_cast<const char*>(data), size);
  if (input.size() >= 32) {
    crypto_generichash(reinterpret_cast<unsigned char*>(input.data()) + input.size() - 32, 32,
                       reinterpret_cast<const unsigned char*>(input.data()), input.size() - 32,
                       nullptr, 0);
  }
  try {
    const linecloud::LineCloud cloud = linecloud::ParseLineCloud(input, "fuzz.lcm");
    // A parsed cloud must serialise and parse back to the same content (the
    // header's formatting may differ from the input's: compare meaning).
    const linecloud::LineCloud back =
        linecloud::ParseLineCloud(linecloud::SerializeLineCloud(cloud), "round-trip.lcm");
    bool same =
        back.ids == cloud.ids && back.encoding == cloud.encoding &&
        back.keyed_line_ids == cloud.keyed_line_ids &&
        back.key_fingerprint == cloud.key_fingerprint && back.descriptors == cloud.descriptors &&
        back.descriptor_dim == cloud.descriptor_dim && back.lines.size() == cloud.lines.size();
    for (size_t i = 0; same && i < cloud.lines.size(); ++i) {
      same = back.lines[i].v == cloud.lines[i].v && back.lines[i].w == cloud.lines[i].w;
    }
    if (!same) __builtin_trap();
  } catch (const linecloud::Error&) {
  }
  return 0;
}
