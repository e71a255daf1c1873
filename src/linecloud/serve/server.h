// `linecloud serve`: the localization service of docs/http_api.md — the
// paper's first scenario (Speciale et al., CVPR 2019: a cloud service that
// holds only line clouds) over HTTP/1.1 (serve/http: libmicrohttpd, Debian's
// 0.9.75).
//
// Maps are DIR/ID.lcm (+ optional ID.json geo-anchor), each loaded once into a
// Localizer; Reload() (SIGHUP) swaps in a new set while requests in flight
// finish on the old one. Every request is bounded before it is used: body
// size (413), the photo's pixel count from its header (413), a fixed pool of
// localization workers behind a bounded queue (503 + Retry-After when full),
// a deadline (504), per-token rate (429 + Retry-After), socket read / write
// timeouts. Answers reveal the pose only — never inlier indices, line ids or
// 3D data; the access log (one JSON line per request) never holds a token or
// image bytes.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "linecloud/pipeline/localizer.h"

namespace linecloud {

struct ServeOptions {
  std::string maps_dir;
  std::string listen = "127.0.0.1:8080";  // HOST:PORT; port 0 picks a free one
  std::string tokens_path;                // empty: every request allowed (loopback only)
  int threads = 2;                        // localization workers
  int queue = 16;                         // requests waiting for a worker, at most
  // Connections open at once (one poll thread reads them all: a slow client
  // costs a socket and at most 32 KB of request head; the process's open-file
  // limit is raised to fit); more are closed when accepted. From one address
  // at most `connections_per_address` (0: no limit); loopback addresses are
  // not limited (behind a local proxy every client is 127.0.0.1).
  int connections = 10000;
  int connections_per_address = 32;
  double max_body_mb = 16;
  // Bodies of all requests being read or handled at once (then 503 +
  // Retry-After): a slow client holds its announced length from its head on.
  double body_budget_mb = 256;
  uint64_t max_pixels = 50'000'000;  // a request's photos together
  int max_frames = 8;                // a device's frames in one request
  // SIFT's scale space of all requests together, live and pooled (~320 bytes
  // per photo pixel after downscaling to 3 200 px: 550 MB for 1536 x 1024,
  // 3.6 GB at most). A photo needing more alone is refused (413); the others
  // wait for room until their deadline. Decoding comes on top (~8 bytes per
  // pixel; see docs/serve.md for what is not bounded yet).
  double memory_budget_mb = 4096;
  double request_seconds = 10;  // deadline of a localization (queue wait included)
  double read_timeout_s = 5, write_timeout_s = 5;  // a slow client's socket
  // The console's static files (index.html, app.js, vendor/) served at `/`.
  // Empty: `web` beside the executable (the build tree), else
  // `../share/linecloud/web` from it (an install); none found: no console.
  std::string web_dir;
  // Every map's Localizer options (the option table's flags of `serve`; a
  // map's DIR/ID.json "options" change them for that map). The server sets
  // image.max_pixels (max_pixels above) and threads (1: concurrency comes
  // from the workers) itself.
  LocalizerOptions localizer;
  // Access log lines (JSON) and notices; default: standard error.
  std::function<void(const std::string&)> log;

  void Check() const;
};

// The host and port of HOST:PORT; throws Error naming `option`.
std::pair<std::string, int> ParseListen(const std::string& listen, const std::string& option);

class Server {
 public:
  // Reads the tokens and loads the maps (a map that fails to load is logged
  // and left out); throws Error on bad options, a non-loopback listen without
  // tokens, or a missing maps folder.
  explicit Server(ServeOptions options);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  // Binds the listening socket; returns the port. Throws Error when it cannot.
  int Bind();
  // Serves until Stop(); returns once in-flight requests are answered.
  void Run();
  // Stops accepting; Run() returns after the requests in flight finish.
  void Stop();
  // Re-reads the maps folder: new maps in, removed out, changed reloaded.
  void Reload();

  size_t num_maps() const;
  std::string url() const;  // http://HOST:PORT once bound

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace linecloud
