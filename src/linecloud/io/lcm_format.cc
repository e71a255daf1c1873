#include "linecloud/io/lcm_format.h"

#include <sodium.h>

#include <cstring>
#include <filesystem>
#include <sstream>

#include <nlohmann/json.hpp>

#include "linecloud/lifting/key.h"
#include "linecloud/util/byte_reader.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

constexpr char kMagic[8] = {'L', 'C', 'M', 'A', 'P', '\r', '\n', '\x1a'};
constexpr size_t kChecksumBytes = 32;
constexpr size_t kPluckerRecordBytes = 48;
constexpr size_t kCompactRecordBytes = 9;
constexpr size_t kMaxHeaderBytes = 1 << 20;

size_t Align8(size_t x) { return (x + 7) & ~size_t{7}; }

size_t RecordBytes(LineEncoding encoding) {
  return encoding == LineEncoding::kPlucker ? kPluckerRecordBytes : kCompactRecordBytes;
}

struct Section {
  size_t offset = 0;
  size_t bytes = 0;
};

struct Layout {
  Section ids, lines, descriptors;
  size_t checksum_offset = 0;
};

Layout ComputeLayout(size_t body_start, size_t n, LineEncoding encoding, size_t descriptor_dim) {
  Layout l;
  l.ids = {Align8(body_start), n * 8};
  l.lines = {Align8(l.ids.offset + l.ids.bytes), n * RecordBytes(encoding)};
  l.descriptors = {Align8(l.lines.offset + l.lines.bytes), n * descriptor_dim};
  l.checksum_offset = l.descriptors.offset + l.descriptors.bytes;
  return l;
}

nlohmann::json SectionJson(const Section& s) { return {{"offset", s.offset}, {"bytes", s.bytes}}; }

// BLAKE2b-256 of `data`, as 32 raw bytes.
std::string Checksum(std::string_view data) {
  unsigned char hash[kChecksumBytes];
  crypto_generichash(hash, sizeof(hash), reinterpret_cast<const unsigned char*>(data.data()),
                     data.size(), nullptr, 0);
  return std::string(reinterpret_cast<char*>(hash), sizeof(hash));
}

// Header JSON for a given layout; the header length feeds back into the
// layout, so iterate until the length is stable (two rounds at most).
std::string BuildHeader(const LineCloud& cloud, Layout* layout) {
  std::string header;
  size_t header_size = 0;
  for (int round = 0; round < 4; ++round) {
    *layout = ComputeLayout(16 + header_size, cloud.size(), cloud.encoding, cloud.descriptor_dim);
    nlohmann::json j;
    j["format"] = "linecloud-map";
    j["version"] = cloud.keyed_line_ids ? kLcmVersion : 1;
    j["generator"] = "linecloud";
    j["num_lines"] = cloud.size();
    j["encoding"] = std::string(LineEncodingName(cloud.encoding));
    j["line_record_bytes"] = RecordBytes(cloud.encoding);
    j["line_record_layout"] = cloud.encoding == LineEncoding::kPlucker
                                  ? "vx vy vz wx wy wz (float64); w = X x v, |v| = 1"
                                  : "direction index (uint8, fibonacci-hemisphere-256-v1), "
                                    "position in the plane orthogonal to it (2 x float32)";
    j["key_fingerprint"] = ToHex(cloud.key_fingerprint);
    if (cloud.gravity) j["gravity"] = {cloud.gravity->x(), cloud.gravity->y(), cloud.gravity->z()};
    j["line_ids"] = cloud.keyed_line_ids
                        ? "keyed permutation of the point ids, stored in increasing order"
                        : "point ids (format version 1)";
    if (cloud.has_descriptors()) {
      j["descriptors"] = {{"dim", cloud.descriptor_dim},
                          {"dtype", "uint8"},
                          {"type", cloud.descriptor_type},
                          {"aggregation", cloud.descriptor_aggregation}};
    } else {
      j["descriptors"] = nullptr;
    }
    j["sections"] = {{"ids", SectionJson(layout->ids)},
                     {"lines", SectionJson(layout->lines)},
                     {"descriptors", SectionJson(layout->descriptors)}};
    j["checksum"] = "blake2b-256 of all preceding bytes, in the last 32 bytes";
    header = j.dump();
    if (header.size() == header_size) break;
    header_size = header.size();
  }
  return header;
}

}  // namespace

std::string SerializeLineCloud(const LineCloud& cloud) {
  EnsureSodiumInitialized();
  cloud.Check("line cloud to write");
  if (cloud.descriptor_dim < 0 || cloud.descriptor_dim > kLcmMaxDescriptorDim) {
    Fail("line cloud to write: descriptors of {} dimensions (the format holds 1 to {})",
         cloud.descriptor_dim, kLcmMaxDescriptorDim);
  }
  Layout layout;
  const std::string header = BuildHeader(cloud, &layout);
  std::string out(layout.checksum_offset + kChecksumBytes, '\0');
  std::memcpy(out.data(), kMagic, 8);
  const uint32_t version = cloud.keyed_line_ids ? kLcmVersion : 1;
  const uint32_t header_size = static_cast<uint32_t>(header.size());
  std::memcpy(out.data() + 8, &version, 4);
  std::memcpy(out.data() + 12, &header_size, 4);
  std::memcpy(out.data() + 16, header.data(), header.size());
  // memcpy from a null pointer is undefined even for 0 bytes (an empty map).
  if (layout.ids.bytes > 0)
    std::memcpy(out.data() + layout.ids.offset, cloud.ids.data(), layout.ids.bytes);
  char* lines = out.data() + layout.lines.offset;
  for (size_t i = 0; i < cloud.size(); ++i) {
    if (cloud.encoding == LineEncoding::kPlucker) {
      const PluckerLine& l = cloud.lines[i];
      const double values[6] = {l.v.x(), l.v.y(), l.v.z(), l.w.x(), l.w.y(), l.w.z()};
      std::memcpy(lines + i * kPluckerRecordBytes, values, sizeof(values));
    } else {
      const CompactLine& c = cloud.compact[i];
      char* rec = lines + i * kCompactRecordBytes;
      rec[0] = static_cast<char>(c.direction_index);
      std::memcpy(rec + 1, c.position, 2 * sizeof(float));
    }
  }
  if (!cloud.descriptors.empty()) {
    std::memcpy(out.data() + layout.descriptors.offset, cloud.descriptors.data(),
                cloud.descriptors.size());
  }
  const std::string hash = Checksum(std::string_view(out.data(), layout.checksum_offset));
  std::memcpy(out.data() + layout.checksum_offset, hash.data(), kChecksumBytes);
  return out;
}

void WriteLineCloud(const LineCloud& cloud, const std::string& path) {
  const std::string bytes = SerializeLineCloud(cloud);
  WriteFileAtomically(path, [&](std::ostream& o) {
    o.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  });
}

namespace {

struct ParsedHeader {
  nlohmann::json json;
  size_t body_start = 0;
  uint32_t version = 0;
};

// Magic, version and header size (the first 16 bytes), checked.
std::pair<uint32_t, uint32_t> ParseHeaderStart(std::string_view data, const std::string& source) {
  ByteReader r(data, source);
  const std::string_view magic = r.ReadBytes(8, "magic");
  if (std::memcmp(magic.data(), kMagic, 8) != 0) {
    Fail("{}: not a linecloud map (bad magic bytes)", source);
  }
  const uint32_t version = r.Read<uint32_t>("version");
  if (version < kLcmOldestVersion || version > kLcmVersion) {
    Fail("{}: unsupported .lcm format version {} (this build reads versions {} to {})", source,
         version, kLcmOldestVersion, kLcmVersion);
  }
  const uint32_t header_size = r.Read<uint32_t>("header_size");
  if (header_size > kMaxHeaderBytes) {
    Fail("{}: corrupt header size {}", source, header_size);
  }
  return {version, header_size};
}

ParsedHeader ParseHeader(std::string_view data, const std::string& source) {
  EnsureSodiumInitialized();
  ByteReader r(data, source);
  const auto [version, header_size] = ParseHeaderStart(data, source);
  r.ReadBytes(16, "header start");
  const std::string_view header = r.ReadBytes(header_size, "header");
  if (data.size() < r.Position() + kChecksumBytes) {
    Fail("{}: truncated (no room for the checksum)", source);
  }
  const size_t body_end = data.size() - kChecksumBytes;
  const std::string hash = Checksum(data.substr(0, body_end));
  if (std::memcmp(hash.data(), data.data() + body_end, kChecksumBytes) != 0) {
    Fail("{}: checksum mismatch: the file is truncated or corrupt", source);
  }
  ParsedHeader parsed;
  parsed.version = version;
  parsed.body_start = r.Position();
  parsed.json = nlohmann::json::parse(header, nullptr, /*allow_exceptions=*/false);
  if (parsed.json.is_discarded() || !parsed.json.is_object()) {
    Fail("{}: header is not valid JSON", source);
  }
  return parsed;
}

template <typename T>
T Field(const nlohmann::json& j, const char* name, const std::string& source) {
  const auto it = j.find(name);
  if (it == j.end()) Fail("{}: header field '{}' is missing", source, name);
  try {
    return it->get<T>();
  } catch (const nlohmann::json::exception&) {
    Fail("{}: header field '{}' has the wrong type", source, name);
  }
}

}  // namespace

std::string ReadLineCloudHeader(std::string_view data, const std::string& source) {
  return ParseHeader(data, source).json.dump(2);
}

LineCloud ParseLineCloud(std::string_view data, const std::string& source) {
  const ParsedHeader header = ParseHeader(data, source);
  const nlohmann::json& j = header.json;
  if (Field<std::string>(j, "format", source) != "linecloud-map") {
    Fail("{}: header field 'format' is not 'linecloud-map'", source);
  }
  LineCloud cloud;
  cloud.keyed_line_ids = header.version >= 2;
  const std::string encoding = Field<std::string>(j, "encoding", source);
  if (encoding == LineEncodingName(LineEncoding::kPlucker)) {
    cloud.encoding = LineEncoding::kPlucker;
  } else if (encoding == LineEncodingName(LineEncoding::kCompact)) {
    cloud.encoding = LineEncoding::kCompact;
  } else {
    Fail("{}: unknown line encoding '{}'", source, encoding);
  }
  const uint64_t n = Field<uint64_t>(j, "num_lines", source);
  const size_t body_end = data.size() - kChecksumBytes;
  if (n > body_end / 8) Fail("{}: header field 'num_lines' = {} is corrupt", source, n);
  size_t dim = 0;
  if (j.contains("descriptors") && !j["descriptors"].is_null()) {
    const auto& d = j["descriptors"];
    dim = Field<size_t>(d, "dim", source);
    if (dim == 0 || dim > kLcmMaxDescriptorDim)
      Fail("{}: descriptor dim {} is invalid", source, dim);
    if (Field<std::string>(d, "dtype", source) != "uint8") {
      Fail("{}: unsupported descriptor dtype", source);
    }
    cloud.descriptor_type = Field<std::string>(d, "type", source);
    cloud.descriptor_aggregation = Field<std::string>(d, "aggregation", source);
  }
  const Layout layout = ComputeLayout(header.body_start, n, cloud.encoding, dim);
  if (layout.checksum_offset != body_end) {
    Fail(
        "{}: file size does not match its header ({} lines need {} bytes "
        "before the checksum, found {})",
        source, n, layout.checksum_offset, body_end);
  }
  const auto& sections = Field<nlohmann::json>(j, "sections", source);
  for (const auto& [name, expected] :
       {std::pair{"ids", layout.ids}, std::pair{"lines", layout.lines},
        std::pair{"descriptors", layout.descriptors}}) {
    const auto s = Field<nlohmann::json>(sections, name, source);
    if (Field<size_t>(s, "offset", source) != expected.offset ||
        Field<size_t>(s, "bytes", source) != expected.bytes) {
      Fail("{}: section '{}' does not match the layout of version {}", source, name,
           header.version);
    }
  }
  if (j.contains("gravity")) {
    const auto g = Field<std::vector<double>>(j, "gravity", source);
    if (g.size() != 3) Fail("{}: header field 'gravity' must be [x, y, z]", source);
    const Eigen::Vector3d v(g[0], g[1], g[2]);
    if (!v.allFinite() || std::abs(v.norm() - 1.0) > 1e-6) {
      Fail("{}: header field 'gravity' is not a unit vector", source);
    }
    cloud.gravity = v;
  }
  const std::string fingerprint = Field<std::string>(j, "key_fingerprint", source);
  if (!ParseHex(fingerprint, cloud.key_fingerprint.data(), cloud.key_fingerprint.size())) {
    Fail("{}: header field 'key_fingerprint' is malformed", source);
  }

  cloud.ids.resize(n);
  if (n > 0) std::memcpy(cloud.ids.data(), data.data() + layout.ids.offset, n * 8);
  cloud.lines.resize(n);
  const char* lines = data.data() + layout.lines.offset;
  if (cloud.encoding == LineEncoding::kPlucker) {
    for (size_t i = 0; i < n; ++i) {
      double values[6];
      std::memcpy(values, lines + i * kPluckerRecordBytes, sizeof(values));
      cloud.lines[i] = PluckerLine(Eigen::Vector3d(values[0], values[1], values[2]),
                                   Eigen::Vector3d(values[3], values[4], values[5]));
    }
  } else {
    cloud.compact.resize(n);
    for (size_t i = 0; i < n; ++i) {
      CompactLine& c = cloud.compact[i];
      c.direction_index = static_cast<uint8_t>(lines[i * kCompactRecordBytes]);
      std::memcpy(c.position, lines + i * kCompactRecordBytes + 1, 2 * sizeof(float));
      if (!std::isfinite(c.position[0]) || !std::isfinite(c.position[1])) {
        Fail("{}: line {} has a non-finite position", source, i);
      }
      cloud.lines[i] = DecodeCompactLine(c);
    }
  }
  cloud.descriptor_dim = static_cast<int>(dim);
  cloud.descriptors.assign(data.data() + layout.descriptors.offset,
                           data.data() + layout.descriptors.offset + layout.descriptors.bytes);
  cloud.Check(source);
  return cloud;
}

LineCloud ReadLineCloud(const std::string& path) {
  // The magic first: a large file that is no map is refused before it is read.
  // Header first (magic, version, header size), then the body: a large file
  // that is no map, or a map of another version, is refused before it is read.
  const std::string prefix = ReadFilePrefix(path, 16);
  if (prefix.size() < sizeof(kMagic) || std::memcmp(prefix.data(), kMagic, sizeof(kMagic)) != 0) {
    Fail("{}: not a linecloud map (bad magic bytes)", path);
  }
  if (prefix.size() < 16) Fail("{}: truncated header", path);
  const auto [version, header_size] = ParseHeaderStart(prefix, path);
  // Then the sizes: the file must be as long as its header says before its
  // body is read (a small header cannot make the reader take a huge file).
  const std::string head = ReadFilePrefix(path, 16 + size_t{header_size});
  if (head.size() < 16 + size_t{header_size}) Fail("{}: truncated header", path);
  const nlohmann::json j =
      nlohmann::json::parse(head.substr(16), nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object()) Fail("{}: header is not valid JSON", path);
  const std::string encoding = Field<std::string>(j, "encoding", path);
  const LineEncoding e = encoding == LineEncodingName(LineEncoding::kCompact)
                             ? LineEncoding::kCompact
                             : LineEncoding::kPlucker;
  const uint64_t n = Field<uint64_t>(j, "num_lines", path);
  size_t dim = 0;
  if (j.contains("descriptors") && j["descriptors"].is_object()) {
    dim = Field<size_t>(j["descriptors"], "dim", path);
  }
  std::error_code ec;
  const uint64_t on_disk = std::filesystem::file_size(path, ec);
  if (!ec && n < (uint64_t{1} << 40) && dim <= kLcmMaxDescriptorDim) {
    const uint64_t expected =
        ComputeLayout(16 + size_t{header_size}, n, e, dim).checksum_offset + kChecksumBytes;
    if (on_disk != expected) {
      Fail("{}: file size does not match its header ({} lines need {} bytes, the file has {})",
           path, n, expected, on_disk);
    }
  }
  (void)version;
  return ParseLineCloud(ReadFileToString(path), path);
}

}  // namespace linecloud
