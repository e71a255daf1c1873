// Fuzzes the service's request handling (issue [shield]): each input is the
// bytes one client sends on one connection to a `linecloud serve` running in
// this process (127.0.0.1, a small map with descriptors, tokens), after which
// the client closes its sending side and reads until the server closes. Any
// input must be answered or dropped — never crash the server (libFuzzer sees
// the crash), corrupt its memory (ASan) or trip undefined behaviour (UBSan).
// cpp-httplib is Debian's compiled library: uninstrumented, so coverage
// guides through linecloud's screening, routes and parsers behind it.
#include <sys/socket.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "linecloud/geometry/plucker.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/serve/raw_http.h"
#include "linecloud/serve/server.h"
#include "linecloud/serve/tokens.h"
#include "linecloud/util/file.h"

namespace {

int g_port = 0;

// maps/synth.lcm (200 lines with descriptors) and tokens.json (an admin
// "root-secret", a reader "alice-secret" of synth) in a fresh folder.
std::string WriteServedFolder() {
  namespace fs = std::filesystem;
  char pattern[] = "/tmp/linecloud-http-fuzzer-XXXXXX";
  const std::string dir = ::mkdtemp(pattern);
  fs::create_directories(dir + "/maps");
  linecloud::LineCloud cloud;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  cloud.descriptor_dim = 128;
  cloud.descriptor_type = "colmap-sift-uint8";
  cloud.descriptor_aggregation = "medoid";
  for (int i = 0; i < 200; ++i) {
    cloud.ids.push_back(10 + i);
    cloud.lines.push_back(linecloud::PluckerLine::FromPointAndDirection(
        Eigen::Vector3d(u(rng), u(rng), 5 + u(rng)), Eigen::Vector3d(u(rng), u(rng), u(rng))));
    for (int k = 0; k < 128; ++k) cloud.descriptors.push_back(static_cast<uint8_t>(rng() % 60));
  }
  linecloud::WriteLineCloud(cloud, dir + "/maps/synth.lcm");
  const nlohmann::json tokens = {{"tokens",
                                  {{{"id", "alice"},
                                    {"sha256", linecloud::TokenSha256Hex("alice-secret")},
                                    {"maps", {"synth"}}},
                                   {{"id", "root"},
                                    {"sha256", linecloud::TokenSha256Hex("root-secret")},
                                    {"maps", {"*"}},
                                    {"admin", true}}}}};
  linecloud::WriteFileAtomically(dir + "/tokens.json",
                                 [&](std::ostream& os) { os << tokens.dump(); });
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const std::string dir = WriteServedFolder();
  linecloud::ServeOptions o;
  o.maps_dir = dir + "/maps";
  o.tokens_path = dir + "/tokens.json";
  o.listen = "127.0.0.1:0";
  o.threads = 1;
  o.request_seconds = 2;
  o.read_timeout_s = o.write_timeout_s = 1;
  o.max_body_mb = 1;
  o.max_pixels = 1'000'000;
  o.memory_budget_mb = 512;
  o.log = [](const std::string&) {};
  static auto server = std::make_unique<linecloud::Server>(o);
  g_port = server->Bind();
  std::thread([] { server->Run(); }).detach();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const int fd = linecloud::ConnectLoopback(g_port, 3);
  if (fd < 0) std::abort();  // the server stopped accepting
  size_t sent = 0;
  while (sent < size) {
    const ssize_t n = ::send(fd, data + sent, size - sent, MSG_NOSIGNAL);
    if (n <= 0) break;
    sent += static_cast<size_t>(n);
  }
  ::shutdown(fd, SHUT_WR);
  char buffer[65536];
  while (::recv(fd, buffer, sizeof(buffer), 0) > 0) {
  }
  ::close(fd);
  return 0;
}
