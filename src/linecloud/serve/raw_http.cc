#include "linecloud/serve/raw_http.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cctype>
#include <algorithm>
#include <chrono>
#include <thread>
#include <cstdlib>

namespace linecloud {

std::string RawAnswer::Header(const std::string& name) const {
  const auto lower = [](std::string s) {
    for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
  };
  const std::string text = lower(head);
  const std::string key = "\r\n" + lower(name) + ":";
  const size_t at = text.find(key);
  if (at == std::string::npos) return "";
  size_t begin = at + key.size();
  while (begin < head.size() && head[begin] == ' ') ++begin;
  return head.substr(begin, head.find("\r\n", begin) - begin);
}

int ConnectLoopback(int port, double timeout_s) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return -1;
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0) {
    ::close(fd);
    return -1;
  }
  timeval tv{};
  tv.tv_sec = static_cast<time_t>(timeout_s);
  tv.tv_usec = static_cast<suseconds_t>((timeout_s - static_cast<double>(tv.tv_sec)) * 1e6);
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
  return fd;
}

RawAnswer RawExchange(int port, const std::string& request, double timeout_s, size_t pause_after,
                      double pause_s) {
  const auto start = std::chrono::steady_clock::now();
  RawAnswer a;
  const int fd = ConnectLoopback(port, timeout_s);
  if (fd < 0) return a;
  size_t sent = 0;
  const size_t first = pause_s > 0 ? std::min(pause_after, request.size()) : request.size();
  for (const size_t until : {first, request.size()}) {
    if (sent == first && first < request.size() && pause_s > 0)
      std::this_thread::sleep_for(std::chrono::duration<double>(pause_s));
    while (sent < until) {
      const ssize_t n = ::send(fd, request.data() + sent, until - sent, MSG_NOSIGNAL);
      if (n <= 0) break;  // the server may answer and close before reading everything
      sent += static_cast<size_t>(n);
    }
  }
  std::string in;
  char buffer[65536];
  size_t header_end = std::string::npos;
  size_t length = 0;
  for (;;) {
    const ssize_t n = ::recv(fd, buffer, sizeof(buffer), 0);
    if (n <= 0) break;
    in.append(buffer, static_cast<size_t>(n));
    if (header_end == std::string::npos &&
        (header_end = in.find("\r\n\r\n")) != std::string::npos) {
      a.head = in.substr(0, header_end);
      const std::string cl = a.Header("Content-Length");
      length = cl.empty() ? 0 : std::strtoul(cl.c_str(), nullptr, 10);
    }
    if (header_end != std::string::npos && in.size() >= header_end + 4 + length) break;
  }
  ::close(fd);
  if (header_end != std::string::npos) {
    a.status = std::atoi(in.c_str() + in.find(' ') + 1);
    a.body = in.substr(header_end + 4);
  }
  a.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return a;
}

}  // namespace linecloud
