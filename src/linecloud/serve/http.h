// The service's HTTP/1.1 layer on libmicrohttpd (Debian's 0.9.75): one poll()
// thread reads every connection's head and body (a client that dribbles costs
// a socket and at most `head_bytes`, never a thread), complete requests are
// handled on a RequestPool while their connection is suspended, and answers
// are written back by the same thread. poll(), not epoll: with 0.9.75's
// edge-triggered epoll a client that sent part of a head and closed its side
// was noticed only at the idle timeout (5 of 12 tries held it 5 s); poll()
// notices at once, for 0.15 instead of 0.10 cores under 2 000 dribblers. Knows nothing of
// linecloud's routes: `screen` sees each request's head (refuse before the body), `handle` the
// whole request. Why this library: docs/serve.md ("The server library").
#pragma once

#include <chrono>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace linecloud {

using HttpFields = std::vector<std::pair<std::string, std::string>>;

struct HttpRequest {
  std::string method;
  std::string path;    // percent-decoded: may hold any byte, NUL included
  std::string client;  // the peer's address
  HttpFields headers;  // as received (names as sent, values not decoded)
  HttpFields query;    // percent-decoded names and values
  std::string body;    // empty for multipart/form-data (see `parts`)
  bool multipart = false;
  std::map<std::string, std::string> parts;  // multipart/form-data fields by name
  // When its head arrived (before its body was read): deadlines run from here.
  std::chrono::steady_clock::time_point arrived{};
  // Whom the screen admitted it for (a token's id, else the peer's address;
  // "" for a loopback peer without a token, which may be a local proxy's
  // many clients): its body is charged to that account's share of the body
  // budget.
  std::string account;

  // The first field of that name (case-insensitive), "" when absent.
  std::string Header(std::string_view name) const;
  size_t HeaderCount(std::string_view name) const;
  std::optional<std::string> Query(std::string_view name) const;
  // The announced Content-Length: 0 when absent, UINT64_MAX when it is not a
  // number below 10^15 (no body that large is read).
  uint64_t BodyLength() const;
  // A body announced: a Content-Length above 0, or a Transfer-Encoding.
  bool AnnouncesBody() const;
};

struct HttpResponse {
  int status = 200;
  std::string content_type = "application/json";
  std::string body;
  HttpFields headers;
  // A file's bytes [file_offset, file_offset + file_length) instead of
  // `body` (written from the file, not copied into memory).
  std::string file;
  uint64_t file_offset = 0, file_length = 0;
  bool close = false;  // Connection: close after this answer
};

// 413's message: the limit in MB, not the operator's flag (clients cannot set it).
std::string BodyLimitMessage(uint64_t max_body_bytes);

// {"error": message} with `status`.
HttpResponse ErrorResponse(int status, std::string_view message, bool close = false);

struct HttpServerOptions {
  std::string host = "127.0.0.1";  // an address or "localhost"
  int port = 0;                    // 0: a free one
  int connections = 1024;          // open at once; more are closed on accept
  // Open at once from one address, an IPv6 /64 counting as one (0: no
  // limit). Loopback addresses are not
  // limited: behind a proxy on the same machine every client is 127.0.0.1.
  int connections_per_address = 32;
  bool limit_loopback = false;    // count loopback addresses too (tests)
  size_t head_bytes = 32 * 1024;  // a connection's request line + header fields (then 431 / 414)
  uint64_t max_body_bytes = 16 << 20;  // then 413, the connection closed
  // Bodies of all requests being read or handled at once (then 503): a
  // request admitted by `screen` holds its announced length from its head on,
  // charged to its account, which may hold at most `account_budget_bytes` of
  // it (one client cannot fill the budget for the others).
  uint64_t body_budget_bytes = uint64_t{256} << 20;
  uint64_t account_budget_bytes = uint64_t{64} << 20;
  // A body still arriving this long after its head is cut off (the
  // connection closed): silence is bounded by `idle_seconds`, a drip by this.
  std::chrono::milliseconds body_time{10000};
  // The same for the body of a request refused from its head (read and
  // dropped so that its client sees the answer).
  std::chrono::milliseconds refused_body_time{5000};
  unsigned idle_seconds = 5;  // a connection silent this long is closed
  int handler_threads = 64;   // at most; made as requests come
  // Stop(): how long requests in flight may take to finish (their handlers
  // always finish: each is bounded by its request's deadline).
  std::chrono::milliseconds drain{15000};
  // Stop(): how long a request still being sent (head or body) may take.
  std::chrono::milliseconds grace{5000};
  HttpFields headers;  // added to every answer (security headers)
  // On each request's head (path, query, header fields; no body yet): an
  // answer refuses the request before its body is read (or answers a cheap
  // bodiless one on the connections' thread); else it sets the request's
  // `account`. A refused request's body (when it announced one,
  // within 4 x max_body_bytes and without Expect: 100-continue) is read and
  // dropped before the answer, so that clients which send their whole body
  // before they read (Python's urllib) see the status, not a broken pipe.
  std::function<std::optional<HttpResponse>(HttpRequest&)> screen;
  // An answer the library gave itself after `screen` admitted the request
  // (413, 503, a malformed multipart body): for the log and the counters.
  std::function<void(const HttpRequest&, const HttpResponse&)> answered;
  // The whole request, on a handler thread.
  std::function<HttpResponse(HttpRequest&)> handle;
  // The library's own messages (a request it refused unparsed, ...).
  std::function<void(const std::string&)> notice;
  // A connection closed before any request reached `screen`: idle, or a head
  // the library refused itself (answered 400 / 414 / 431 / 505 with its own
  // short HTML, or closed when it was not HTTP). The client's address.
  std::function<void(const std::string&)> closed;
};

// Percent-decoding (RFC 3986); `plus_is_space` for query strings.
std::string PercentDecode(std::string_view s, bool plus_is_space);

class HttpServer {
 public:
  explicit HttpServer(HttpServerOptions options);
  ~HttpServer();  // Stop()
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  // Listens (backlog SOMAXCONN) and starts serving; returns the port. Throws
  // Error naming the address when it cannot.
  int Bind();
  // Blocks until Stop() has finished.
  void Run();
  // Stops accepting, lets requests in flight finish (at most `drain`, then
  // their handlers), closes every connection. Idempotent.
  void Stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace linecloud
