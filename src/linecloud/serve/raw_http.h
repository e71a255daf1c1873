// HTTP/1.1 exchanges on a raw loopback socket, the request's bytes exactly as
// given: how the hostile tests and `bench serve --attack-seconds` talk to the
// service (malformed requests included, which an HTTP client library would
// not send).
#pragma once

#include <string>

namespace linecloud {

struct RawAnswer {
  int status = 0;  // 0: no answer (closed, or the timeout)
  std::string head, body;
  double seconds = 0;
  // A header's value (case-insensitive name); empty when absent.
  std::string Header(const std::string& name) const;
};

// A TCP connection to 127.0.0.1:`port` whose reads time out after
// `timeout_s`; -1 when it cannot connect.
int ConnectLoopback(int port, double timeout_s = 10);

// Sends `request` on a new connection and reads one answer (the head, then
// Content-Length bytes of body). With `pause_s`, the first `pause_after` bytes are sent, then
// nothing for pause_s seconds, then the rest (a slow upload).
RawAnswer RawExchange(int port, const std::string& request, double timeout_s = 10,
                      size_t pause_after = 0, double pause_s = 0);

}  // namespace linecloud
