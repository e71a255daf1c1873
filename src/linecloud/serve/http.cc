#include "linecloud/serve/http.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <microhttpd.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <condition_variable>
#include <cstdarg>
#include <cstring>
#include <mutex>
#include <unordered_map>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "linecloud/serve/pools.h"
#include "linecloud/serve/wire.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

bool SameName(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) ==
                  std::tolower(static_cast<unsigned char>(y));
         });
}

int HexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

std::string AddressText(const sockaddr* addr) {
  char text[INET6_ADDRSTRLEN] = "";
  if (addr == nullptr) return "";
  if (addr->sa_family == AF_INET) {
    ::inet_ntop(AF_INET, &reinterpret_cast<const sockaddr_in*>(addr)->sin_addr, text, sizeof(text));
  } else if (addr->sa_family == AF_INET6) {
    ::inet_ntop(AF_INET6, &reinterpret_cast<const sockaddr_in6*>(addr)->sin6_addr, text,
                sizeof(text));
  }
  return text;
}

// Whose connections count together: an IPv4 address, or an IPv6 /64 (one
// host is usually given a whole /64: per address it had no limit).
std::string LimitKey(const sockaddr* addr) {
  if (addr == nullptr || addr->sa_family != AF_INET6) return AddressText(addr);
  sockaddr_in6 prefix = *reinterpret_cast<const sockaddr_in6*>(addr);
  if (IN6_IS_ADDR_V4MAPPED(&prefix.sin6_addr)) return AddressText(addr);
  std::fill(prefix.sin6_addr.s6_addr + 8, prefix.sin6_addr.s6_addr + 16, 0);
  return AddressText(reinterpret_cast<const sockaddr*>(&prefix)) + "/64";
}

bool IsLoopbackAddress(const sockaddr* addr) {
  if (addr == nullptr) return false;
  if (addr->sa_family == AF_INET) {
    return (ntohl(reinterpret_cast<const sockaddr_in*>(addr)->sin_addr.s_addr) >> 24) == 127;
  }
  if (addr->sa_family == AF_INET6) {
    const in6_addr& a = reinterpret_cast<const sockaddr_in6*>(addr)->sin6_addr;
    if (IN6_IS_ADDR_LOOPBACK(&a)) return true;
    return IN6_IS_ADDR_V4MAPPED(&a) && a.s6_addr[12] == 127;
  }
  return false;
}

// A request from its head to its answer (MHD's per-request `con_cls`).
struct RequestState {
  HttpRequest request;
  MHD_PostProcessor* post = nullptr;
  std::string post_error;               // what the multipart body broke
  uint64_t received = 0;                // body bytes
  bool refused = false;                 // answered before its body was read
  bool too_large = false;               // over max_body_bytes: read and dropped, then 413
  std::optional<HttpResponse> pending;  // a refusal found in the body, sent at its end
  uint64_t reserved = 0;                // of body_budget_bytes
  bool dispatched = false;
  std::optional<HttpResponse> answer;  // set by the handler before it resumes the connection
};

MHD_Result CollectField(void* cls, MHD_ValueKind, const char* key, size_t key_size,
                        const char* value, size_t value_size) {
  auto* fields = static_cast<HttpFields*>(cls);
  fields->emplace_back(std::string(key, key_size),
                       value ? std::string(value, value_size) : std::string());
  return MHD_YES;
}

// multipart/form-data fields, by name (at most 64 of them).
MHD_Result CollectPart(void* cls, MHD_ValueKind, const char* key, const char*, const char*,
                       const char*, const char* data, uint64_t offset, size_t size) {
  auto* state = static_cast<RequestState*>(cls);
  auto& parts = state->request.parts;
  const std::string name = key ? key : "";
  if (!parts.count(name) && parts.size() >= 64) {
    state->post_error = "multipart: more than 64 parts";
    return MHD_NO;
  }
  if (offset == 0 && parts.count(name)) {  // a part's first bytes, and the name was taken
    state->post_error = fmt::format("multipart: part '{}' is given twice", name);
    return MHD_NO;
  }
  parts[name].append(data ? data : "", data ? size : 0);
  return MHD_YES;
}

// libmicrohttpd's thread (its callbacks run on it) at nice 10, as the
// RequestPool's: reading and refusing a flood of bad requests must not take
// the CPU from the localization workers (at nice 0 a client's p99 under
// `bench serve --attack-seconds` rose from 1.2x to 1.9x its p99 alone).
void BelowTheWorkers() {
  thread_local bool lowered = false;
  if (lowered) return;
  ::setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), 10);
  lowered = true;
}

// Path and query as sent: the server decodes them itself (HttpRequest::path
// may hold a NUL, which MHD's C strings would cut).
size_t KeepEscaped(void*, MHD_Connection*, char* s) { return std::strlen(s); }

}  // namespace

std::string PercentDecode(std::string_view s, bool plus_is_space) {
  std::string out;
  out.reserve(s.size());
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size() && HexValue(s[i + 1]) >= 0 && HexValue(s[i + 2]) >= 0) {
      out.push_back(static_cast<char>(16 * HexValue(s[i + 1]) + HexValue(s[i + 2])));
      i += 2;
    } else if (plus_is_space && s[i] == '+') {
      out.push_back(' ');
    } else {
      out.push_back(s[i]);
    }
  }
  return out;
}

HttpResponse ErrorResponse(int status, std::string_view message, bool close) {
  HttpResponse r;
  r.status = status;
  r.body = DumpJson(nlohmann::json{{"error", std::string(message)}});
  r.close = close;
  return r;
}

std::string HttpRequest::Header(std::string_view name) const {
  for (const auto& [k, v] : headers) {
    if (SameName(k, name)) return v;
  }
  return "";
}

size_t HttpRequest::HeaderCount(std::string_view name) const {
  return static_cast<size_t>(std::count_if(headers.begin(), headers.end(),
                                           [&](const auto& f) { return SameName(f.first, name); }));
}

std::string BodyLimitMessage(uint64_t max_body_bytes) {
  return fmt::format("the body exceeds this server's limit of {:g} MB",
                     static_cast<double>(max_body_bytes) / (1 << 20));
}

bool HttpRequest::AnnouncesBody() const {
  return BodyLength() > 0 || HeaderCount("Transfer-Encoding") > 0;
}

uint64_t HttpRequest::BodyLength() const {
  const std::string v = Header("Content-Length");
  if (v.empty()) return 0;
  if (v.size() > 15 || !std::all_of(v.begin(), v.end(), ::isdigit)) return UINT64_MAX;
  return std::stoull(v);
}

std::optional<std::string> HttpRequest::Query(std::string_view name) const {
  for (const auto& [k, v] : query) {
    if (k == name) return v;
  }
  return std::nullopt;
}

struct HttpServer::Impl {
  HttpServerOptions options;
  RequestPool pool;
  MHD_Daemon* daemon = nullptr;
  int listen_fd = -1;
  int port = 0;

  std::mutex mutex;  // stopping, stopped, in_flight, per_address
  std::condition_variable changed;
  bool stop_called = false, stopping = false, stopped = false;
  int in_flight = 0;        // requests between their head and their completion
  int dispatched = 0;       // of which handed to a handler
  uint64_t body_bytes = 0;  // reserved by requests in flight (ReserveBody)
  std::unordered_map<std::string, uint64_t> account_bytes;  // of which per account
  std::unordered_map<std::string, int> per_address;

  explicit Impl(HttpServerOptions o)
      : options(std::move(o)), pool(options.handler_threads, std::chrono::seconds(30)) {}

  // Body bytes of all requests being read, at most body_budget_bytes: a
  // request's announced length from its head, more if it sends more; an
  // account's requests at most account_budget_bytes of it.
  bool ReserveBody(RequestState* state, uint64_t bytes) {
    if (bytes <= state->reserved) return true;
    const uint64_t more = bytes - state->reserved;
    std::lock_guard<std::mutex> lock(mutex);
    if (body_bytes + more > options.body_budget_bytes) return false;
    if (!state->request.account.empty()) {  // "": no account (a loopback peer, no token)
      uint64_t& account = account_bytes[state->request.account];
      if (account + more > options.account_budget_bytes) {
        if (account == 0) account_bytes.erase(state->request.account);
        return false;
      }
      account += more;
    }
    body_bytes += more;
    state->reserved = bytes;
    return true;
  }

  // Gives a request's reservation back (its lock held).
  void ReleaseBody(const RequestState& state) {
    if (state.reserved == 0) return;
    body_bytes -= state.reserved;
    const auto it = account_bytes.find(state.request.account);
    if (it != account_bytes.end() && (it->second -= state.reserved) == 0) account_bytes.erase(it);
  }

  // A refusal of the library's own after the screen admitted the request.
  MHD_Result Answer(MHD_Connection* connection, RequestState* state, HttpResponse r) const {
    if (options.answered) options.answered(state->request, r);
    return Queue(connection, std::move(r));
  }

  // The same refusal, sent once the body has arrived (libmicrohttpd takes no
  // answer while a body is being read).
  void Pend(RequestState* state, HttpResponse r) const {
    if (options.answered) options.answered(state->request, r);
    state->pending = std::move(r);
  }

  // A refusal decided from the head is answered after the body it announced
  // has been read and dropped (bounded), unless the client waits for a 100
  // Continue or announced no body at all.
  bool DrainBeforeRefusal(const HttpRequest& req) const {
    const uint64_t announced = req.BodyLength();
    if (announced == UINT64_MAX || announced / 4 > options.max_body_bytes) return false;
    // Chunks of unknown total are not waited for (the server takes none).
    if (!req.Header("Expect").empty() || req.HeaderCount("Transfer-Encoding") > 0) return false;
    return announced > 0;
  }

  void Notice(const std::string& text) const {
    if (options.notice) options.notice(text);
  }

  bool Exempt(const sockaddr* addr) const {
    return !options.limit_loopback && IsLoopbackAddress(addr);
  }

  void Closed(const std::string& client) const {
    if (options.closed) options.closed(client);
  }

  MHD_Result Queue(MHD_Connection* connection, HttpResponse r) const {
    MHD_Response* m = nullptr;
    if (!r.file.empty()) {
      const int fd = ::open(r.file.c_str(), O_RDONLY | O_CLOEXEC);
      if (fd >= 0) {
        m = MHD_create_response_from_fd_at_offset64(r.file_length, fd, r.file_offset);
        if (m == nullptr) ::close(fd);
      }
      if (m == nullptr) {
        r = ErrorResponse(500, "the file could not be read");
      }
    }
    if (m == nullptr) {
      m = MHD_create_response_from_buffer(r.body.size(), r.body.data(), MHD_RESPMEM_MUST_COPY);
    }
    if (m == nullptr) return MHD_NO;  // out of memory: MHD closes the connection
    MHD_add_response_header(m, "Content-Type", r.content_type.c_str());
    for (const auto& [k, v] : r.headers) MHD_add_response_header(m, k.c_str(), v.c_str());
    for (const auto& [k, v] : options.headers) MHD_add_response_header(m, k.c_str(), v.c_str());
    if (r.close) MHD_add_response_header(m, "Connection", "close");
    const MHD_Result ok = MHD_queue_response(connection, static_cast<unsigned>(r.status), m);
    MHD_destroy_response(m);
    return ok;
  }

  // The request's head into `state` (MHD's first call).
  void ReadHead(MHD_Connection* connection, const char* url, const char* method,
                RequestState* state) const {
    HttpRequest& req = state->request;
    req.arrived = std::chrono::steady_clock::now();
    req.method = method;
    req.path = PercentDecode(url, false);
    const MHD_ConnectionInfo* info =
        MHD_get_connection_info(connection, MHD_CONNECTION_INFO_CLIENT_ADDRESS);
    if (info) req.client = AddressText(info->client_addr);
    MHD_get_connection_values_n(connection, MHD_HEADER_KIND, &CollectField, &req.headers);
    HttpFields raw;
    MHD_get_connection_values_n(connection, MHD_GET_ARGUMENT_KIND, &CollectField, &raw);
    for (const auto& [k, v] : raw) {
      req.query.emplace_back(PercentDecode(k, true), PercentDecode(v, true));
    }
  }

  static MHD_Result OnRequest(void* cls, MHD_Connection* connection, const char* url,
                              const char* method, const char*, const char* upload,
                              size_t* upload_size, void** con_cls) {
    BelowTheWorkers();
    return static_cast<Impl*>(cls)->Request(connection, url, method, upload, upload_size,
                                            reinterpret_cast<RequestState**>(con_cls));
  }

  MHD_Result Request(MHD_Connection* connection, const char* url, const char* method,
                     const char* upload, size_t* upload_size, RequestState** slot) {
    RequestState* state = *slot;
    if (state == nullptr) {  // the head only
      state = *slot = new RequestState;
      const MHD_ConnectionInfo* socket =
          MHD_get_connection_info(connection, MHD_CONNECTION_INFO_SOCKET_CONTEXT);
      if (socket != nullptr && socket->socket_context != nullptr) {
        ++static_cast<ConnectionState*>(socket->socket_context)->requests;
      }
      {
        std::lock_guard<std::mutex> lock(mutex);
        ++in_flight;
      }
      ReadHead(connection, url, method, state);
      // The peer's address is the account until the screen names one; not a
      // loopback one (behind a local proxy every client is 127.0.0.1), as for
      // connections_per_address.
      const MHD_ConnectionInfo* peer =
          MHD_get_connection_info(connection, MHD_CONNECTION_INFO_CLIENT_ADDRESS);
      if (!(peer && Exempt(peer->client_addr))) state->request.account = state->request.client;
      if (options.screen) {
        if (std::optional<HttpResponse> refusal = options.screen(state->request)) {
          // A body announced is not read further: the connection closes after it.
          if (state->request.AnnouncesBody()) refusal->close = true;
          if (DrainBeforeRefusal(state->request)) {
            state->pending = std::move(*refusal);  // its body read and dropped first
            return MHD_YES;
          }
          state->refused = true;
          return Queue(connection, std::move(*refusal));
        }
      }
      const uint64_t announced = state->request.BodyLength();
      state->too_large = announced > options.max_body_bytes;
      if (announced / 4 > options.max_body_bytes) {
        state->refused = true;  // far over: not worth reading to answer politely
        return Answer(connection, state,
                      ErrorResponse(413, BodyLimitMessage(options.max_body_bytes), true));
      }
      if (state->too_large) {
        HttpResponse r = ErrorResponse(413, BodyLimitMessage(options.max_body_bytes), true);
        if (!DrainBeforeRefusal(state->request)) {
          state->refused = true;
          return Answer(connection, state, std::move(r));
        }
        Pend(state, std::move(r));
        return MHD_YES;
      }
      if (!ReserveBody(state, announced)) {
        // Busy: answered at once (reading a body to drop it is no help to a busy server).
        state->refused = true;
        HttpResponse r = ErrorResponse(
            503, "the server is busy: request bodies being read fill its memory for bodies", true);
        r.headers = {{"Retry-After", "1"}};
        return Answer(connection, state, std::move(r));
      }
      const std::string type = state->request.Header("Content-Type");
      if (type.rfind("multipart/form-data", 0) != 0) {
        state->request.body.reserve(announced);
      } else {
        state->request.multipart = true;
        state->post = MHD_create_post_processor(connection, 64 * 1024, &CollectPart, state);
        if (state->post == nullptr) {
          state->refused = true;
          return Answer(
              connection, state,
              ErrorResponse(400, "Content-Type: multipart/form-data needs a boundary", true));
        }
      }
      return MHD_YES;
    }
    if (*upload_size > 0) {
      // libmicrohttpd takes no answer while a body is being read: a refusal
      // found here waits for its end (bounded: Content-Length <= 4 x the cap).
      const size_t n = *upload_size;
      *upload_size = 0;
      state->received += n;
      // A drip is cut off: no answer could be given before the request's deadline anyway.
      // A refused request's body, read only so that its client sees the answer, gets the
      // shorter refused_body_time (token-less drips held connections for the whole bound).
      const auto allowed_time =
          state->refused || state->pending ? options.refused_body_time : options.body_time;
      if (std::chrono::steady_clock::now() - state->request.arrived > allowed_time) {
        Notice(fmt::format("{}: a body still arriving {} ms after its head: closed",
                           state->request.client, allowed_time.count()));
        return MHD_NO;
      }
      if (state->refused || state->pending) {
        // Dropped; a body beyond what it announced (or endless chunks) ends the connection.
        return state->received / 4 > options.max_body_bytes ? MHD_NO : MHD_YES;
      }
      if (state->received > options.max_body_bytes) state->too_large = true;
      if (state->too_large || !ReserveBody(state, state->received)) {
        Pend(state, state->too_large
                        ? ErrorResponse(413, BodyLimitMessage(options.max_body_bytes), true)
                        : ErrorResponse(503,
                                        "the server is busy: request bodies being read fill its "
                                        "memory for bodies",
                                        true));
        return MHD_YES;
      }
      if (state->post != nullptr) {
        if (MHD_post_process(state->post, upload, n) != MHD_YES) {
          const std::string why = state->post_error.empty()
                                      ? "multipart: the body is not multipart/form-data with the "
                                        "boundary its Content-Type names"
                                      : state->post_error;
          Pend(state, ErrorResponse(400, why, true));
        }
      } else {
        state->request.body.append(upload, n);
      }
      return MHD_YES;
    }
    if (state->answer) return Queue(connection, std::move(*state->answer));  // resumed
    if (state->dispatched || state->refused) return MHD_YES;
    if (state->too_large && !state->pending) {
      Pend(state, ErrorResponse(413, BodyLimitMessage(options.max_body_bytes), true));
    }
    if (state->post != nullptr && !state->pending) {
      const MHD_Result complete = MHD_destroy_post_processor(state->post);
      state->post = nullptr;
      if (complete != MHD_YES) {
        Pend(state,
             ErrorResponse(400, "multipart: the body ends before its closing boundary", true));
      }
    }
    if (state->pending) {
      state->refused = true;
      return Queue(connection, std::move(*state->pending));
    }
    std::lock_guard<std::mutex> lock(mutex);
    if (stopping) {
      state->refused = true;
      HttpResponse r = ErrorResponse(503, "the server is stopping", true);
      r.headers = {{"Retry-After", "1"}};
      return Answer(connection, state, std::move(r));
    }
    state->dispatched = true;
    ++dispatched;
    MHD_suspend_connection(connection);
    pool.Submit([this, connection, state] {
      HttpResponse r;
      try {
        r = options.handle(state->request);
      } catch (const std::exception& e) {
        Notice(fmt::format("handler failed: {}", e.what()));
        r = ErrorResponse(500, "internal error");
      }
      state->answer = std::move(r);
      MHD_resume_connection(connection);  // `state` is MHD's again from here
    });
    return MHD_YES;
  }

  static void OnCompleted(void* cls, MHD_Connection*, void** con_cls, MHD_RequestTerminationCode) {
    auto* state = static_cast<RequestState*>(*con_cls);
    if (state == nullptr) return;
    *con_cls = nullptr;
    if (state->post != nullptr) MHD_destroy_post_processor(state->post);
    auto* impl = static_cast<Impl*>(cls);
    std::lock_guard<std::mutex> lock(impl->mutex);
    impl->ReleaseBody(*state);
    impl->dispatched -= state->dispatched;
    delete state;
    --impl->in_flight;
    impl->changed.notify_all();
  }

  // Per-address connection counts (loopback not counted: see the options).
  static MHD_Result OnAccept(void* cls, const sockaddr* addr, socklen_t) {
    auto* impl = static_cast<Impl*>(cls);
    if (impl->options.connections_per_address <= 0 || impl->Exempt(addr)) return MHD_YES;
    std::lock_guard<std::mutex> lock(impl->mutex);
    const auto it = impl->per_address.find(LimitKey(addr));
    return it != impl->per_address.end() && it->second >= impl->options.connections_per_address
               ? MHD_NO
               : MHD_YES;
  }

  // A connection's address and how many requests it brought (MHD's
  // per-connection `socket_context`).
  struct ConnectionState {
    std::string address;
    std::string key;       // LimitKey
    bool counted = false;  // in per_address
    int requests = 0;
  };

  static void OnConnection(void* cls, MHD_Connection* connection, void** socket_context,
                           MHD_ConnectionNotificationCode code) {
    BelowTheWorkers();
    auto* impl = static_cast<Impl*>(cls);
    if (code == MHD_CONNECTION_NOTIFY_STARTED) {
      const MHD_ConnectionInfo* info =
          MHD_get_connection_info(connection, MHD_CONNECTION_INFO_CLIENT_ADDRESS);
      auto* c = new ConnectionState;
      *socket_context = c;
      if (info == nullptr) return;
      c->address = AddressText(info->client_addr);
      c->key = LimitKey(info->client_addr);
      c->counted = impl->options.connections_per_address > 0 && !impl->Exempt(info->client_addr);
      if (!c->counted) return;
      std::lock_guard<std::mutex> lock(impl->mutex);
      ++impl->per_address[c->key];
      return;
    }
    auto* c = static_cast<ConnectionState*>(*socket_context);
    if (c == nullptr) return;
    *socket_context = nullptr;
    if (c->counted) {
      std::lock_guard<std::mutex> lock(impl->mutex);
      if (--impl->per_address[c->key] <= 0) impl->per_address.erase(c->key);
    }
    if (c->requests == 0) {
      // Nothing reached a route: an idle connection, or a head the library
      // refused itself (its notice, just before, says which status).
      impl->Closed(c->address);
    }
    delete c;
  }

  static void OnLog(void* cls, const char* format, va_list args) {
    char text[512];
    std::vsnprintf(text, sizeof(text), format, args);
    std::string line = text;
    while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
    static_cast<Impl*>(cls)->Notice("http: " + line);
  }

  int Listen() {
    const std::string host = options.host == "localhost" ? "127.0.0.1" : options.host;
    sockaddr_storage addr{};
    socklen_t length = 0;
    auto* v4 = reinterpret_cast<sockaddr_in*>(&addr);
    auto* v6 = reinterpret_cast<sockaddr_in6*>(&addr);
    if (::inet_pton(AF_INET, host.c_str(), &v4->sin_addr) == 1) {
      v4->sin_family = AF_INET;
      v4->sin_port = htons(static_cast<uint16_t>(options.port));
      length = sizeof(sockaddr_in);
    } else if (::inet_pton(AF_INET6, host.c_str(), &v6->sin6_addr) == 1) {
      v6->sin6_family = AF_INET6;
      v6->sin6_port = htons(static_cast<uint16_t>(options.port));
      length = sizeof(sockaddr_in6);
    } else {
      Fail("serve: cannot listen on {}: not an IPv4 or IPv6 address", options.host);
    }
    const int fd = ::socket(addr.ss_family, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0) Fail("serve: cannot make a socket ({})", std::strerror(errno));
    const int one = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
    // Accepted sockets inherit it: no Nagle delay on keep-alive answers.
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
    if (addr.ss_family == AF_INET6) ::setsockopt(fd, IPPROTO_IPV6, IPV6_V6ONLY, &one, sizeof(one));
    if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), length) != 0 ||
        ::listen(fd, SOMAXCONN) != 0) {
      const int error = errno;
      ::close(fd);
      Fail("serve: cannot listen on {}:{} ({})", options.host, options.port, std::strerror(error));
    }
    sockaddr_storage bound{};
    socklen_t bound_length = sizeof(bound);
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&bound), &bound_length);
    port = ntohs(bound.ss_family == AF_INET ? reinterpret_cast<sockaddr_in*>(&bound)->sin_port
                                            : reinterpret_cast<sockaddr_in6*>(&bound)->sin6_port);
    return fd;
  }
};

HttpServer::HttpServer(HttpServerOptions options)
    : impl_(std::make_unique<Impl>(std::move(options))) {}

HttpServer::~HttpServer() { Stop(); }

int HttpServer::Bind() {
  Impl& s = *impl_;
  if (s.daemon != nullptr) return s.port;
  // A socket per connection, and files for the maps and answers: the soft
  // open-file limit (often 1 024) raised towards the hard one.
  rlimit files{};
  const rlim_t want = static_cast<rlim_t>(s.options.connections) + 256;
  if (::getrlimit(RLIMIT_NOFILE, &files) == 0 && files.rlim_cur < want) {
    files.rlim_cur = std::min(want, files.rlim_max);
    ::setrlimit(RLIMIT_NOFILE, &files);
    if (files.rlim_cur < want) {
      s.Notice(fmt::format("{} connections asked, but the open-file limit is {}: fewer are served",
                           s.options.connections, files.rlim_cur));
    }
  }
  s.listen_fd = s.Listen();
  s.daemon = MHD_start_daemon(
      MHD_USE_POLL_INTERNAL_THREAD | MHD_USE_ITC | MHD_ALLOW_SUSPEND_RESUME | MHD_USE_ERROR_LOG, 0,
      &Impl::OnAccept, &s, &Impl::OnRequest, &s, MHD_OPTION_EXTERNAL_LOGGER, &Impl::OnLog, &s,
      MHD_OPTION_LISTEN_SOCKET, s.listen_fd, MHD_OPTION_CONNECTION_LIMIT,
      static_cast<unsigned>(s.options.connections), MHD_OPTION_CONNECTION_MEMORY_LIMIT,
      s.options.head_bytes, MHD_OPTION_CONNECTION_TIMEOUT, s.options.idle_seconds,
      MHD_OPTION_NOTIFY_COMPLETED, &Impl::OnCompleted, &s, MHD_OPTION_NOTIFY_CONNECTION,
      &Impl::OnConnection, &s, MHD_OPTION_UNESCAPE_CALLBACK, &KeepEscaped, nullptr, MHD_OPTION_END);
  if (s.daemon == nullptr) {
    ::close(s.listen_fd);
    s.listen_fd = -1;
    Fail("serve: libmicrohttpd did not start on {}:{}", s.options.host, s.port);
  }
  return s.port;
}

void HttpServer::Run() {
  std::unique_lock<std::mutex> lock(impl_->mutex);
  impl_->changed.wait(lock, [&] { return impl_->stopped; });
}

void HttpServer::Stop() {
  Impl& s = *impl_;
  {
    std::unique_lock<std::mutex> lock(s.mutex);
    if (s.stop_called) {
      s.changed.wait(lock, [&] { return s.stopped; });
      return;
    }
    s.stop_called = true;
  }
  if (s.daemon != nullptr) {
    const int fd = MHD_quiesce_daemon(s.daemon);  // no new connections
    if (fd >= 0) ::close(fd);
    {
      // Requests handed to a handler are answered (within `drain`); one still
      // sending its head or body gets `grace` (a client dripping a body
      // held the exit 21 s).
      std::unique_lock<std::mutex> lock(s.mutex);
      const auto start = std::chrono::steady_clock::now();
      s.changed.wait_for(lock, s.options.grace, [&] { return s.in_flight == 0; });
      s.changed.wait_until(lock, start + s.options.drain, [&] { return s.dispatched == 0; });
      s.stopping = true;  // from here requests completing their body are refused (503)
    }
    s.pool.WaitIdle();  // every suspended connection resumed (MHD requires it before stopping)
    MHD_stop_daemon(s.daemon);
    s.daemon = nullptr;
  }
  std::lock_guard<std::mutex> lock(s.mutex);
  s.stopped = true;
  s.changed.notify_all();
}

}  // namespace linecloud
