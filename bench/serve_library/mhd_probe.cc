// A probe of libmicrohttpd (Debian's 0.9.75) as the service's HTTP layer, for
// the server-library decision of issue [shield] (docs/serve.md): what the
// rows cpp-httplib cannot close look like on it. Not part of the build:
//   g++ -O2 -std=c++20 bench/serve_library/mhd_probe.cc -o build/mhd_probe -lmicrohttpd
//   build/mhd_probe PORT &   then   python3 bench/serve_library/probe_rows.py PORT
// Routes: GET /healthz -> "ok"; GET /echo-authorization -> the header as received;
// POST anything -> the body's size. An epoll thread (plus a pool of 2), at most
// 32 connections per address, 32 KB per connection for the request head, a
// connection idle 10 s is closed.
#include <arpa/inet.h>
#include <microhttpd.h>
#include <netinet/in.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <unistd.h>

namespace {

MHD_Result Answer(MHD_Connection* connection, unsigned status, const std::string& text) {
  MHD_Response* r = MHD_create_response_from_buffer(text.size(), const_cast<char*>(text.data()),
                                                    MHD_RESPMEM_MUST_COPY);
  const MHD_Result ok = MHD_queue_response(connection, status, r);
  MHD_destroy_response(r);
  return ok;
}

MHD_Result Handle(void*, MHD_Connection* connection, const char* url, const char* method,
                  const char*, const char*, size_t* upload_size, void** state) {
  if (std::strcmp(method, "POST") == 0) {
    if (*state == nullptr) {  // first call: the head only
      *state = new size_t(0);
      return MHD_YES;
    }
    size_t* received = static_cast<size_t*>(*state);
    if (*upload_size > 0) {
      *received += *upload_size;
      *upload_size = 0;
      return MHD_YES;
    }
    const size_t n = *received;
    delete received;
    *state = nullptr;
    return Answer(connection, MHD_HTTP_OK, std::to_string(n));
  }
  if (std::strcmp(url, "/echo-authorization") == 0) {
    const char* a = MHD_lookup_connection_value(connection, MHD_HEADER_KIND, "Authorization");
    return Answer(connection, MHD_HTTP_OK, a ? a : "");
  }
  return Answer(connection, MHD_HTTP_OK, "ok");
}

}  // namespace

int main(int argc, char** argv) {
  const int port = argc > 1 ? std::atoi(argv[1]) : 8090;
  sockaddr_in loopback{};
  loopback.sin_family = AF_INET;
  loopback.sin_port = htons(static_cast<uint16_t>(port));
  loopback.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  MHD_Daemon* d = MHD_start_daemon(
      MHD_USE_EPOLL_INTERNAL_THREAD | MHD_USE_ERROR_LOG, static_cast<uint16_t>(port), nullptr,
      nullptr, &Handle, nullptr, MHD_OPTION_THREAD_POOL_SIZE, 2u, MHD_OPTION_CONNECTION_LIMIT,
      10000u, MHD_OPTION_PER_IP_CONNECTION_LIMIT, 32u, MHD_OPTION_CONNECTION_MEMORY_LIMIT,
      size_t{32 * 1024}, MHD_OPTION_CONNECTION_TIMEOUT, 10u, MHD_OPTION_SOCK_ADDR, &loopback,
      MHD_OPTION_END);
  if (!d) {
    std::fprintf(stderr, "cannot start on port %d\n", port);
    return 1;
  }
  std::fprintf(stderr, "listening on http://127.0.0.1:%d\n", port);
  pause();
  MHD_stop_daemon(d);
}
