// The .lcm line-cloud map format, version 2. Little-endian, checksummed and
// self-describing:
//
//   offset 0   8 bytes   magic "LCMAP\r\n\x1a" (catches text-mode mangling)
//          8   uint32    format version (2; 1 is still read)
//         12   uint32    header length H in bytes
//         16   H bytes   header: UTF-8 JSON describing the content (counts,
//                        encoding, record sizes, descriptor type, key
//                        fingerprint, byte offsets of the sections)
//      16+H..  sections, each starting at a multiple of 8:
//                ids          uint64[N]
//                lines        N x 48 bytes (v, w as float64) or
//                             N x 9 bytes (uint8 direction, 2 x float32)
//                descriptors  N x D bytes (optional)
//      end-32  32 bytes  BLAKE2b-256 of every preceding byte
//
// The writer takes only a LineCloud, so no point coordinate, colour, error or
// track can ever reach the file.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "linecloud/lifting/line_cloud.h"

namespace linecloud {

// Version 2: line ids are the keyed permutation of the point ids (lifting.h)
// and lines are stored in increasing line-id order; the layout is version 1's.
// Version 1 files (point ids as line ids) are still read.
inline constexpr uint32_t kLcmVersion = 2;
inline constexpr uint32_t kLcmOldestVersion = 1;
// Format limits, shared by the writer and the reader.
inline constexpr int kLcmMaxDescriptorDim = 4096;

void WriteLineCloud(const LineCloud& cloud, const std::string& path);
// Serialises to bytes (what WriteLineCloud writes).
std::string SerializeLineCloud(const LineCloud& cloud);

// Throws Error naming `path` for a missing, truncated, corrupt (checksum),
// unsupported-version or inconsistent file.
LineCloud ReadLineCloud(const std::string& path);
LineCloud ParseLineCloud(std::string_view data, const std::string& source);

// The JSON header of a file (for `info`), validated like ParseLineCloud.
std::string ReadLineCloudHeader(std::string_view data, const std::string& source);

}  // namespace linecloud
