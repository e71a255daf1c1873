// serve/http: the HTTP layer on its own (no linecloud routes), raw bytes on a
// loopback socket. What cpp-httplib could not do is what these check: a
// request head's memory, slow handlers that hold no connection thread,
// pipelining, per-address connection limits, the drain on Stop().
#include "linecloud/serve/http.h"

#include <gtest/gtest.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <future>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "linecloud/serve/raw_http.h"
#include "linecloud/util/memory.h"

namespace linecloud {
namespace {

using namespace std::chrono_literals;

// /slow sleeps 1 s in its handler; /echo answers what the server read;
// /refuse is refused on its head (403).
HttpServerOptions TestOptions() {
  HttpServerOptions o;
  o.max_body_bytes = 1 << 20;
  o.handler_threads = 16;
  o.drain = 5s;
  o.headers = {{"X-Common", "yes"}};
  o.screen = [](const HttpRequest& req) -> std::optional<HttpResponse> {
    if (req.path == "/refuse") return ErrorResponse(403, "refused on its head");
    return std::nullopt;
  };
  o.handle = [](HttpRequest& req) {
    if (req.path == "/slow") std::this_thread::sleep_for(1s);
    HttpResponse r;
    r.content_type = "text/plain";
    r.body =
        fmt::format("{} path={} bytes={} q={} parts={} client={}", req.method,
                    std::string(req.path.size(), '?') == req.path ? "" : req.path, req.body.size(),
                    req.Query("q").value_or("-"), req.parts.size(), req.client);
    if (req.path.find('\0') != std::string::npos) r.body += " NUL";
    for (const auto& [name, value] : req.parts) r.body += " " + name + "=" + value;
    return r;
  };
  return o;
}

RawAnswer Get(int port, const std::string& path, const std::string& extra = "") {
  return RawExchange(
      port, "GET " + path + " HTTP/1.1\r\nHost: x\r\n" + extra + "Connection: close\r\n\r\n");
}

TEST(Http, AnswersHeadsQueriesBodiesAndMultipart) {
  HttpServer server(TestOptions());
  const int port = server.Bind();
  RawAnswer a = Get(port, "/a%20b%00c?q=x%26y+z");
  ASSERT_EQ(a.status, 200) << a.head;
  EXPECT_NE(a.body.find("path=/a b"), std::string::npos) << a.body;
  EXPECT_NE(a.body.find(" NUL"), std::string::npos) << a.body;  // decoded, not cut
  EXPECT_NE(a.body.find("q=x&y z"), std::string::npos) << a.body;
  EXPECT_NE(a.body.find("client=127.0.0.1"), std::string::npos) << a.body;
  EXPECT_EQ(a.Header("X-Common"), "yes");
  a = RawExchange(port, "POST /p HTTP/1.1\r\nHost: x\r\nContent-Length: 5\r\n\r\nhello");
  EXPECT_NE(a.body.find("bytes=5"), std::string::npos) << a.body;
  const std::string form =
      "--XyZ\r\nContent-Disposition: form-data; name=\"camera\"\r\n\r\nPINHOLE 2 2 1 1 1 1\r\n"
      "--XyZ\r\nContent-Disposition: form-data; name=\"image\"; filename=\"a.jpg\"\r\n"
      "Content-Type: image/jpeg\r\n\r\n\xff\xd8 bytes\r\n--XyZ--\r\n";
  a = RawExchange(port,
                  fmt::format("POST /p HTTP/1.1\r\nHost: x\r\nContent-Type: "
                              "multipart/form-data; boundary=XyZ\r\nContent-Length: {}\r\n\r\n",
                              form.size()) +
                      form);
  EXPECT_NE(a.body.find("parts=2"), std::string::npos) << a.body;
  EXPECT_NE(a.body.find("camera=PINHOLE 2 2 1 1 1 1"), std::string::npos) << a.body;
  EXPECT_NE(a.body.find("image=\xff\xd8 bytes"), std::string::npos) << a.body;
  // A multipart body cut before its closing boundary, one without a boundary.
  const std::string cut = form.substr(0, form.size() - 12);
  a = RawExchange(port,
                  fmt::format("POST /p HTTP/1.1\r\nHost: x\r\nContent-Type: "
                              "multipart/form-data; boundary=XyZ\r\nContent-Length: {}\r\n\r\n",
                              cut.size()) +
                      cut);
  EXPECT_EQ(a.status, 400) << a.body;
  EXPECT_NE(a.body.find("closing boundary"), std::string::npos) << a.body;
  a = RawExchange(port,
                  "POST /p HTTP/1.1\r\nHost: x\r\nContent-Type: multipart/form-data\r\n"
                  "Content-Length: 4\r\n\r\nabcd");
  EXPECT_EQ(a.status, 400) << a.body;
  EXPECT_NE(a.body.find("boundary"), std::string::npos) << a.body;
  // Refused on its head: a client waiting for 100 Continue gets the answer at once, the
  // connection closed; one that sends its body first (Python's urllib) gets it after the body
  // is read and dropped, not a reset in the middle of its write.
  a = RawExchange(port,
                  "POST /refuse HTTP/1.1\r\nHost: x\r\nExpect: 100-continue\r\n"
                  "Content-Length: 1000000\r\n\r\n");
  EXPECT_EQ(a.status, 403);
  EXPECT_EQ(a.Header("Connection"), "close");
  a = RawExchange(port, "POST /refuse HTTP/1.1\r\nHost: x\r\nContent-Length: 1000000\r\n\r\n" +
                            std::string(1000000, 'x'));
  EXPECT_EQ(a.status, 403);
  EXPECT_EQ(a.Header("Connection"), "close");
}

TEST(Http, ABodyOverTheCapIsReadThen413AndFarOverAtOnce) {
  HttpServer server(TestOptions());
  const int port = server.Bind();
  const std::string over(1 << 20 | 1, 'a');
  RawAnswer a = RawExchange(
      port,
      fmt::format("POST /p HTTP/1.1\r\nHost: x\r\nContent-Length: {}\r\n\r\n", over.size()) + over);
  EXPECT_EQ(a.status, 413) << a.head;  // read whole: the client sees the answer
  a = RawExchange(port, "POST /p HTTP/1.1\r\nHost: x\r\nContent-Length: 99999999999\r\n\r\nabc");
  EXPECT_EQ(a.status, 413) << a.head;
  EXPECT_LT(a.seconds, 2.0);
}

// [siege]: one account (the screen's: a token) holds at most its share of the body budget,
// whoever else is uploading; the layer's own refusals reach `answered`.
TEST(Http, AnAccountHoldsOnlyItsShareOfTheBodyBudget) {
  HttpServerOptions o = TestOptions();
  o.body_budget_bytes = 4 << 20;
  o.account_budget_bytes = 1 << 20;
  o.max_body_bytes = 1 << 20;
  o.screen = [](HttpRequest& req) -> std::optional<HttpResponse> {
    req.account = req.Header("X-Account");
    return std::nullopt;
  };
  std::mutex mutex;
  std::vector<int> answered;
  o.answered = [&](const HttpRequest&, const HttpResponse& r) {
    std::lock_guard<std::mutex> lock(mutex);
    answered.push_back(r.status);
  };
  HttpServer server(o);
  const int port = server.Bind();
  // Account a announces 800 KB and sends nothing yet: it holds 800 KB of its 1 MB.
  const int held = ConnectLoopback(port);
  const std::string head =
      "POST /p HTTP/1.1\r\nHost: x\r\nX-Account: a\r\nContent-Length: 800000\r\n\r\n";
  ASSERT_EQ(::send(held, head.data(), head.size(), MSG_NOSIGNAL),
            static_cast<ssize_t>(head.size()));
  std::this_thread::sleep_for(100ms);
  const std::string body(400000, 'x');
  const auto post = [&](const std::string& account) {
    return RawExchange(port, fmt::format("POST /p HTTP/1.1\r\nHost: x\r\nX-Account: {}\r\n"
                                         "Content-Length: {}\r\n\r\n",
                                         account, body.size()) +
                                 body);
  };
  const RawAnswer a = post("a");
  EXPECT_EQ(a.status, 503) << a.body;  // a's share is taken by its own upload
  EXPECT_EQ(post("b").status, 200);    // b's is not
  ::close(held);
  std::lock_guard<std::mutex> lock(mutex);
  EXPECT_EQ(answered, std::vector<int>{503});
}

// [siege]: a body that drips (a byte a second, never silent for the idle
// timeout) is cut off at body_time after its head.
TEST(Http, ADrippingBodyIsCutOffAtItsTimeBound) {
  HttpServerOptions o = TestOptions();
  o.idle_seconds = 5;
  o.body_time = 1500ms;
  HttpServer server(o);
  const int port = server.Bind();
  const int fd = ConnectLoopback(port, 10);
  const std::string head = "POST /p HTTP/1.1\r\nHost: x\r\nContent-Length: 100\r\n\r\n";
  ASSERT_EQ(::send(fd, head.data(), head.size(), MSG_NOSIGNAL), static_cast<ssize_t>(head.size()));
  const auto start = std::chrono::steady_clock::now();
  bool closed = false;
  for (int i = 0; i < 10 && !closed; ++i) {
    std::this_thread::sleep_for(500ms);
    closed = ::send(fd, "x", 1, MSG_NOSIGNAL) != 1;
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ::close(fd);
  EXPECT_TRUE(closed);
  EXPECT_LT(seconds, 3.5);
  EXPECT_EQ(Get(port, "/echo").status, 200);
}

// Row 5: 500 000 header fields (6 MB). cpp-httplib: no answer, +55 MB.
TEST(Http, AHugeHeadCostsItsBoundAndA431) {
  HttpServerOptions o = TestOptions();
  HttpServer server(o);
  const int port = server.Bind();
  std::string head = "GET /echo HTTP/1.1\r\nHost: x\r\n";
  for (int i = 0; i < 500000; ++i) head += fmt::format("X-{}: v\r\n", i);
  head += "\r\n";
  const size_t before = ResidentBytes();
  const RawAnswer a = RawExchange(port, head);
  EXPECT_EQ(a.status, 431) << a.head;
  EXPECT_LT(a.seconds, 2.0);
  EXPECT_LT(ResidentBytes(), before + (8 << 20));  // the request's 6 MB were never kept
  const RawAnswer uri = Get(port, "/" + std::string(100000, 'u'));
  EXPECT_EQ(uri.status, 414) << uri.head;
  EXPECT_EQ(Get(port, "/echo").status, 200);
}

// Handlers run on their own threads while the connection waits suspended:
// eight slow requests hold no reader, others are answered at once.
TEST(Http, SlowHandlersDoNotHoldOthers) {
  HttpServer server(TestOptions());
  const int port = server.Bind();
  std::vector<std::future<RawAnswer>> slow;
  for (int i = 0; i < 8; ++i) {
    slow.push_back(std::async(std::launch::async, [port] { return Get(port, "/slow"); }));
  }
  std::this_thread::sleep_for(200ms);
  const RawAnswer fast = Get(port, "/echo");
  EXPECT_EQ(fast.status, 200);
  EXPECT_LT(fast.seconds, 0.5);
  for (auto& f : slow) EXPECT_EQ(f.get().status, 200);
}

// Row 14: two requests in one write, both answered, in order (cpp-httplib
// answered the first and left the client waiting).
TEST(Http, PipelinedRequestsAreAnsweredInOrder) {
  HttpServer server(TestOptions());
  const int port = server.Bind();
  const int fd = ConnectLoopback(port, 3);
  ASSERT_GE(fd, 0);
  const std::string two =
      "GET /one HTTP/1.1\r\nHost: x\r\n\r\nGET /two HTTP/1.1\r\nHost: x\r\nConnection: "
      "close\r\n\r\n";
  ASSERT_EQ(::send(fd, two.data(), two.size(), MSG_NOSIGNAL), static_cast<ssize_t>(two.size()));
  std::string in;
  char buffer[4096];
  for (ssize_t n; (n = ::recv(fd, buffer, sizeof(buffer), 0)) > 0;) in.append(buffer, n);
  ::close(fd);
  const size_t one = in.find("path=/one"), second = in.find("path=/two");
  EXPECT_NE(one, std::string::npos) << in;
  EXPECT_NE(second, std::string::npos) << in;
  EXPECT_LT(one, second);
}

// One address may hold `connections_per_address` connections; the next is
// closed on accept, and a slot freed is usable again.
TEST(Http, OneAddressGetsItsShareOfConnections) {
  HttpServerOptions o = TestOptions();
  o.connections_per_address = 4;
  o.limit_loopback = true;  // the test's only address is loopback
  HttpServer server(o);
  const int port = server.Bind();
  std::vector<int> held;
  for (int i = 0; i < 4; ++i) held.push_back(ConnectLoopback(port, 2));
  std::this_thread::sleep_for(100ms);  // accepted
  RawAnswer a = Get(port, "/echo");
  EXPECT_EQ(a.status, 0) << a.head;  // closed on accept
  ::close(held.back());
  held.pop_back();
  std::this_thread::sleep_for(100ms);
  a = Get(port, "/echo");
  EXPECT_EQ(a.status, 200) << a.head;
  for (const int fd : held) ::close(fd);
}

// Stop(): new connections refused, a request in flight answered first.
TEST(Http, StopAnswersWhatIsInFlight) {
  auto server = std::make_unique<HttpServer>(TestOptions());
  const int port = server->Bind();
  std::thread runner([&] { server->Run(); });
  auto slow = std::async(std::launch::async, [port] { return Get(port, "/slow"); });
  std::this_thread::sleep_for(300ms);
  const auto start = std::chrono::steady_clock::now();
  server->Stop();
  runner.join();
  EXPECT_LT(std::chrono::steady_clock::now() - start, 3s);
  EXPECT_EQ(slow.get().status, 200);
  EXPECT_EQ(ConnectLoopback(port, 1), -1);  // nothing listens any more
}

}  // namespace
}  // namespace linecloud
