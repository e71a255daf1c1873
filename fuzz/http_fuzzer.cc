// Fuzzes the service's request handling (issue [shield]): each input is the
// bytes one client sends on one connection to a `linecloud serve` running in
// this process (127.0.0.1, a small map with descriptors, tokens), after which
// the client closes its sending side and reads until the server closes. Any
// input must be answered or dropped — never crash the server (libFuzzer sees
// the crash), corrupt its memory (ASan) or trip undefined behaviour (UBSan).
// libmicrohttpd is Debian's compiled library: uninstrumented, so coverage
// guides through linecloud's HTTP layer (serve/http), screening, routes and
// parsers behind it.
#include <sys/socket.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>

#include "linecloud/serve/raw_http.h"
#include "linecloud/serve/serve_fixtures.h"
#include "linecloud/serve/server.h"

namespace {

int g_port = 0;

// maps/synth.lcm and tokens.json (serve_fixtures.h: an admin "root-secret",
// a reader "alice-secret" of synth) in a fresh folder.
std::string WriteServedFolder() {
  char pattern[] = "/tmp/linecloud-http-fuzzer-XXXXXX";
  const std::string dir = ::mkdtemp(pattern);
  std::filesystem::create_directories(dir + "/maps");
  linecloud::WriteLineCloud(linecloud::SmallCloud(), dir + "/maps/synth.lcm");
  linecloud::WriteTestTokens(dir + "/tokens.json");
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
