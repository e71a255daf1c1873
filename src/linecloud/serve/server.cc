#include "linecloud/serve/server.h"

#include <sodium.h>

#include <algorithm>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <arpa/inet.h>
#include <sys/socket.h>
#include <cstring>
#include <cerrno>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <future>
#include <limits>
#include <iostream>
#include <map>
#include <mutex>
#include <semaphore>
#include <thread>
#include <unordered_map>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "linecloud/features/image.h"
#include "linecloud/features/sift.h"
#include "linecloud/features/sift_scale_space.h"
#include "linecloud/io/ply.h"
#include "linecloud/io/json_util.h"
#include "linecloud/pipeline/image_query.h"
#include "linecloud/localize/query_json.h"
#include "linecloud/pipeline/localizer.h"
#include "linecloud/pipeline/localizer_option_table.h"
#include "linecloud/pipeline/localizer_result_json.h"
#include "linecloud/io/geo.h"
#include "linecloud/serve/geopose_request.h"
#include "linecloud/serve/http.h"
#include "linecloud/serve/localize_body.h"
#include "linecloud/serve/map_registry.h"
#include "linecloud/serve/metrics.h"
#include "linecloud/serve/pools.h"
#include "linecloud/serve/tokens.h"
#include "linecloud/localize/overlay_marks.h"
#include "linecloud/serve/wire.h"
#include "linecloud/util/base64.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"
#include "linecloud/util/memory.h"

namespace linecloud {
namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

// Header fields a request may carry (their bytes are bounded by
// HttpServerOptions::head_bytes before this count is taken).
constexpr size_t kMaxHeaders = 100;

// The smallest RANSAC threshold a request may ask for (pixels): SIFT locates
// keypoints to ~0.1 px; 1e-300 made every draw fail until the deadline.
constexpr double kMinServedThreshold = 0.05;

// A path under /v1/maps/: the map's id and what follows it ("" for the map
// itself, else "/localize", "/segments", ...); nullopt for any other path.
struct MapPath {
  std::string id, tail;
};
std::optional<MapPath> SplitMapPath(const std::string& path) {
  constexpr std::string_view kMaps = "/v1/maps/";
  if (path.rfind(kMaps, 0) != 0) return std::nullopt;
  const std::string rest = path.substr(kMaps.size());
  const size_t slash = rest.find('/');
  return MapPath{rest.substr(0, slash), slash == std::string::npos ? "" : rest.substr(slash)};
}

// The API's routes by path: their method ("GET" / "POST"), "" for any other
// path (the console's files).
std::string AllowedMethods(const std::string& path) {
  if (path == "/healthz" || path == "/readyz" || path == "/metrics" || path == "/v1/maps") {
    return "GET";
  }
  if (path == "/geopose") return "POST";
  const std::optional<MapPath> map = SplitMapPath(path);
  if (!map) return "";
  if (map->tail.empty() || map->tail == "/segments" || map->tail == "/audit" ||
      map->tail == "/audit/points") {
    return "GET";
  }
  return map->tail == "/localize" ? "POST" : "";
}

// The Authorization header whole, as sent (never percent-decoded: with
// cpp-httplib "Bearer%20TOKEN" and "Bearer TOKEN%00junk" authenticated).
std::string Authorization(const HttpRequest& req) { return req.Header("Authorization"); }

// The console's Content-Security-Policy: its own files, and its inline
// import map by hash (Chromium reads import maps inline only), nothing else;
// never framed. `index_html` is the page ("" when there is no console).
std::string ConsolePolicy(const std::string& index_html) {
  std::string scripts = "'self'";
  const std::string open = "<script type=\"importmap\">", close = "</script>";
  const size_t begin = index_html.find(open);
  if (begin != std::string::npos) {
    const size_t start = begin + open.size();
    const size_t end = index_html.find(close, start);
    if (end != std::string::npos) {
      unsigned char digest[crypto_hash_sha256_BYTES];
      crypto_hash_sha256(digest, reinterpret_cast<const unsigned char*>(index_html.data() + start),
                         end - start);
      std::string b64(sodium_base64_ENCODED_LEN(sizeof(digest), sodium_base64_VARIANT_ORIGINAL),
                      '\0');
      sodium_bin2base64(b64.data(), b64.size(), digest, sizeof(digest),
                        sodium_base64_VARIANT_ORIGINAL);
      b64.resize(std::strlen(b64.c_str()));
      scripts += " 'sha256-" + b64 + "'";
    }
  }
  return "default-src 'self'; script-src " + scripts +
         "; style-src 'self'; img-src 'self' data: blob:; connect-src 'self'; object-src 'none'; "
         "base-uri 'none'; form-action 'self'; frame-ancestors 'none'";
}

// The route a path belongs to, as the access log and /metrics name it
// ("static" for the console's files).
std::string RouteName(const std::string& path) {
  if (AllowedMethods(path).empty()) return "static";
  const std::optional<MapPath> map = SplitMapPath(path);
  return map ? "/v1/maps/{id}" + map->tail : path;
}

// An answer with a status: errors carry {"error": ...}.
struct HttpError {
  int status;
  std::string message;
  double retry_after = 0;  // seconds, for 429 / 503
  HttpFields headers = {};
};

[[noreturn]] void Throw(int status, std::string message, double retry_after = 0) {
  throw HttpError{status, std::move(message), retry_after};
}

// The pose (cam_from_world, or rig_from_world for a device's frames; with
// its scale for the Sim(3) methods) and its statistics. For the map's owner (an admin
// token, `owner_map` given) also what the CLI's --overlay draws: the inliers'
// and outliers' pixels in the photo and, per inlier, the segment where the pose
// puts its map line (null when behind the camera). With the pose and the lines
// they would let anyone pin the map's points, so never for readers.
json PoseJson(const LocalizerResult& r, const LocalizationMap* owner_map = nullptr) {
  if (!r.success()) return {{"success", false}, {"reason", r.reason}};
  const Sim3d& p = r.pose.query_from_world;
  const Eigen::Vector3d c = p.Inverse().translation;
  const Eigen::Quaterniond q = p.rotation.normalized();
  const size_t matches = r.query.observations.size();
  const json times = json(StageTimesToJson(r.times));
  const MethodInfo& method = FindMethod(r.method);
  json j = {{"success", true},
            {"method", r.method},
            {"pose", method.multi ? "rig_from_world" : "cam_from_world"},
            {"q", {q.w(), q.x(), q.y(), q.z()}},
            {"t", {p.translation.x(), p.translation.y(), p.translation.z()}},
            {"center", {c.x(), c.y(), c.z()}},
            {"num_matches", matches},
            {"num_inliers", r.pose.inliers.size()},
            {"inlier_ratio", matches ? double(r.pose.inliers.size()) / matches : 0.0},
            {"uncertainty",
             {{"rotation_deg", r.pose.uncertainty.rotation_deg},
              {"position", r.pose.uncertainty.position}}},
            {"times_ms", times}};
  if (method.similarity()) j["scale"] = p.scale;
  if (owner_map && r.query.cameras.size() == 1) {
    const std::vector<OverlayMark> marks =
        OverlayMarks(r.query, r.pose, *owner_map,
                     OverlaySegmentHalfLength(static_cast<int>(r.query.cameras[0].width)));
    json inliers = json::array(), segments = json::array(), outliers = json::array();
    for (const int i : r.pose.inliers) {
      const OverlayMark& m = marks[i];
      inliers.push_back({m.keypoint.x(), m.keypoint.y()});
      if (m.feature) {
        segments.push_back({m.feature->first.x(), m.feature->first.y(), m.feature->second.x(),
                            m.feature->second.y()});
      } else {
        segments.push_back(nullptr);
      }
    }
    for (const OverlayMark& m : marks) {
      if (!m.inlier) outliers.push_back({m.keypoint.x(), m.keypoint.y()});
    }
    j["inlier_keypoints"] = std::move(inliers);
    j["inlier_segments"] = std::move(segments);
    j["outlier_keypoints"] = std::move(outliers);
  }
  return j;
}

// Whether an Accept-Encoding field takes gzip (a "gzip" entry whose q is not 0).
bool AcceptsGzip(const std::string& accept_encoding) {
  for (size_t begin = 0; begin < accept_encoding.size();) {
    const size_t end = std::min(accept_encoding.find(',', begin), accept_encoding.size());
    std::string entry = accept_encoding.substr(begin, end - begin);
    begin = end + 1;
    std::erase(entry, ' ');
    std::transform(entry.begin(), entry.end(), entry.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (entry.rfind("gzip", 0) != 0 || (entry.size() > 4 && entry[4] != ';')) continue;
    const size_t q = entry.find(";q=");
    return q == std::string::npos || std::strtod(entry.c_str() + q + 3, nullptr) > 0;
  }
  return false;
}

// The console's files beside the executable (build tree) or installed with
// it; empty when neither exists.
std::string DefaultWebDir() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (ec) return "";
  for (const fs::path& dir : {exe.parent_path() / "web",
                              exe.parent_path().parent_path() / "share" / "linecloud" / "web"}) {
    if (fs::is_regular_file(dir / "index.html", ec)) return dir.string();
  }
  return "";
}

// A loopback address by value (127.0.0.0/8, ::1, "localhost"), not by
// spelling: "127.evil.com" is a name anyone may point anywhere. `host` as
// ParseListen gives it (an IPv6 address without its brackets).
bool IsLoopback(const std::string& host) {
  if (host == "localhost") return true;
  in_addr v4{};
  if (::inet_pton(AF_INET, host.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6{};
  if (::inet_pton(AF_INET6, host.c_str(), &v6) == 1) return IN6_IS_ADDR_LOOPBACK(&v6);
  return false;
}

}  // namespace

std::pair<std::string, int> ParseListen(const std::string& listen, const std::string& option) {
  const size_t colon = listen.rfind(':');
  if (colon == std::string::npos || colon == 0)
    Fail("{}: expected HOST:PORT, got '{}'", option, listen);
  std::string host = listen.substr(0, colon);
  const std::string port = listen.substr(colon + 1);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') {
    host = host.substr(1, host.size() - 2);  // [::1]:8080
  }
  if (port.empty() || port.size() > 5 ||
      port.find_first_not_of("0123456789") != std::string::npos || std::stoi(port) > 65535) {
    Fail("{}: '{}' is not a port (0-65535)", option, port);
  }
  return {host, std::stoi(port)};
}

void ServeOptions::Check() const {
  if (maps_dir.empty()) Fail("serve: --maps DIR is required");
  if (threads < 1 || threads > 256) Fail("serve: --threads must be 1-256, got {}", threads);
  if (queue < 0 || queue > 100000) Fail("serve: --queue must be 0-100000, got {}", queue);
  if (connections < 1 || connections > 65536) {
    Fail("serve: --connections must be 1-65536, got {}", connections);
  }
  if (connections_per_address < 0 || connections_per_address > connections) {
    Fail("serve: --connections-per-address must be 0-{} (--connections), got {}", connections,
         connections_per_address);
  }
  if (!(max_body_mb > 0 && max_body_mb <= 1024)) {
    Fail("serve: --max-body-mb must be in (0, 1024], got {}", max_body_mb);
  }
  if (!(body_budget_mb >= max_body_mb && body_budget_mb <= 1e6)) {
    Fail("serve: --body-budget-mb must be in [--max-body-mb, 1e6], got {}", body_budget_mb);
  }
  if (max_pixels < 1) Fail("serve: --max-pixels must be positive");
  if (max_frames < 1 || max_frames > 64) Fail("serve: --max-frames must be in [1, 64]");
  localizer.Check();
  if (!(memory_budget_mb >= 64 && memory_budget_mb <= 1e7)) {
    Fail("serve: --memory-budget-mb must be in [64, 1e7], got {}", memory_budget_mb);
  }
  if (!(request_seconds > 0 && request_seconds <= 3600)) {
    Fail("serve: --request-seconds must be in (0, 3600], got {}", request_seconds);
  }
  const auto [host, port] = ParseListen(listen, "--listen");
  if (!IsLoopback(host) && tokens_path.empty()) {
    Fail("serve: listening on {} (not loopback) needs --tokens TOKENS.json", host);
  }
}

struct Server::Impl {
  ServeOptions options;
  // Swapped as a whole on reload (SIGHUP); a request keeps the store it started with.
  std::shared_ptr<const TokenStore> tokens_ = std::make_shared<const TokenStore>();
  mutable std::mutex tokens_mutex;
  std::shared_ptr<const TokenStore> Tokens() const {
    std::lock_guard<std::mutex> lock(tokens_mutex);
    return tokens_;
  }
  // Reads the tokens file again; a file that does not read keeps the previous tokens.
  void ReloadTokens() {
    if (options.tokens_path.empty()) return;
    try {
      auto fresh = std::make_shared<TokenStore>(TokenStore::Read(options.tokens_path));
      std::lock_guard<std::mutex> lock(tokens_mutex);
      fresh->KeepRatesOf(*tokens_);
      tokens_ = std::move(fresh);
    } catch (const std::exception& e) {
      Log(DumpJson(
          json{{"notice",
                fmt::format("tokens not reloaded, the previous ones are kept: {}", e.what())}}));
    }
  }
  Metrics metrics;
  std::unique_ptr<WorkPool> pool;
  std::unique_ptr<std::counting_semaphore<>> parse_slots;  // ParseBody
  std::string host;
  int port = -1;
  std::string web_dir;  // the console's files ("": none)
  std::atomic<int> in_flight{0};
  std::mutex running_mutex;                      // running
  std::unordered_map<std::string, int> running;  // readers' localizations, per token (TokenSlot)
  int PerTokenRequests() const { return std::max(1, options.threads / 2); }

  // A reader's localizations being handled (parsed, queued or running) at
  // most PerTokenRequests() at once, then 429: one token holds at most half
  // the workers and the parse slots, whatever its requests cost.
  class TokenSlot {
   public:
    TokenSlot(Impl& impl, const std::optional<TokenEntry>& token) : impl_(impl) {
      if (!token || token->admin) return;
      std::lock_guard<std::mutex> lock(impl.running_mutex);
      int& n = impl.running[token->id];
      if (n >= impl.PerTokenRequests()) {
        Throw(429,
              fmt::format("this token has {} request(s) being localized, the most it may have at "
                          "once: send the next when one is answered",
                          n),
              1);
      }
      ++n;
      account_ = token->id;
    }
    TokenSlot(const TokenSlot&) = delete;
    TokenSlot& operator=(const TokenSlot&) = delete;
    ~TokenSlot() {
      if (account_.empty()) return;
      std::lock_guard<std::mutex> lock(impl_.running_mutex);
      if (--impl_.running[account_] <= 0) impl_.running.erase(account_);
    }

   private:
    Impl& impl_;
    std::string account_;
  };
  std::unique_ptr<MapRegistry> registry;

  std::shared_ptr<const MapSet> Maps() const { return registry->Maps(); }

  void Log(const std::string& line) const {
    if (options.log) {
      options.log(line);
    } else {
      std::cerr << line << "\n";
    }
  }

  // The caller's token entry (nullopt: no tokens file, everything allowed);
  // 401 without a known token.
  std::optional<TokenEntry> Authorize(const HttpRequest& req) const {
    const auto tokens = Tokens();
    if (tokens->open()) return std::nullopt;
    auto e = tokens->Authenticate(Authorization(req));
    if (!e) Throw(401, "a valid 'Authorization: Bearer TOKEN' header is required");
    return e;
  }

  void Throttle(const std::optional<TokenEntry>& token) {
    if (!token) return;
    if (const auto wait = Tokens()->Throttle(token->id, token->requests_per_minute)) {
      Throw(429, "rate limit: too many requests for this token", *wait);
    }
  }

  // 404 for unknown maps and for maps this token may not use alike.
  std::shared_ptr<const LoadedMap> FindMap(const std::string& id,
                                           const std::optional<TokenEntry>& token) const {
    const std::shared_ptr<const MapSet> set = Maps();
    const auto it = IsMapId(id) ? set->find(id) : set->end();
    if (it == set->end() || (token && !token->MayUse(id))) Throw(404, "no such map");
    return it->second;
  }

  // A request body's JSON, parsed by at most workers + 2 requests at once (a
  // parse costs up to ~50 MB: kMaxRequestJsonValues); 503 when no slot frees
  // before the deadline.
  // `parse()` (a body's JSON, or a multipart body's JSON parts) in a parse slot.
  template <typename Parse>
  auto Parsing(Clock::time_point deadline, Parse parse) -> decltype(parse()) {
    if (!parse_slots->try_acquire_until(deadline)) {
      Throw(503, "the server is busy: every JSON parsing slot is taken", 1);
    }
    struct Release {
      std::counting_semaphore<>& slots;
      ~Release() { slots.release(); }
    } release{*parse_slots};
    return parse();
  }

  json ParseBody(std::string_view body, std::string_view what, Clock::time_point deadline) {
    return Parsing(deadline, [&] { return ParseRequestJson(body, what); });
  }

  // When a request that arrives now must be answered (--request-seconds).
  // --request-seconds from the request's arrival (its head), the body's upload included.
  Clock::time_point Deadline(const HttpRequest& req) const {
    const Clock::time_point start = req.arrived == Clock::time_point{} ? Clock::now() : req.arrived;
    return start + std::chrono::duration_cast<Clock::duration>(
                       std::chrono::duration<double>(options.request_seconds));
  }

  // Runs `job` on a worker within the request's deadline: 503 when the queue
  // is full, 504 when the deadline passes first.
  LocalizerResult RunBounded(std::function<LocalizerResult()> job, Clock::time_point deadline) {
    ++in_flight;  // this request, from here until it is answered
    struct Done {
      std::atomic<int>& n;
      ~Done() { --n; }
    } done{in_flight};
    auto promise = std::make_shared<std::promise<LocalizerResult>>();
    std::future<LocalizerResult> result = promise->get_future();
    if (!pool->TrySubmit([promise, job = std::move(job)] {
          try {
            promise->set_value(job());
          } catch (...) {
            promise->set_exception(std::current_exception());
          }
        })) {
      Throw(503, "the server is busy: every worker and queue slot is taken", 1);
    }
    if (result.wait_until(deadline) != std::future_status::ready) {
      Throw(504, fmt::format("no answer within the {} s deadline", options.request_seconds));
    }
    LocalizerResult answer;
    try {
      answer = result.get();
    } catch (const Error& e) {
      Throw(400, e.what());
    }
    // No pose and the deadline gone: the job saw it pass first (SIFT's memory wait, RANSAC's
    // budget cut to it, a stage skipped) — the same answer as above, not a 200 "no pose".
    if (!answer.success() && Clock::now() >= deadline) {
      Throw(504, fmt::format("no answer within the {} s deadline ({})", options.request_seconds,
                             answer.reason));
    }
    return answer;
  }

  // A request's method, rig fields and options (the request-scope options of
  // localizer_option_table.h, on the map's defaults); 400 naming the field
  // when one is bad, unknown or the map's, or the method does not fit what
  // was sent.
  LocalizeRequest RequestOptions(const LoadedMap& map, const LocalizeBody& body,
                                 Clock::time_point deadline, const std::string& where) {
    LocalizeRequest r;
    try {
      body.SetOn(&r);
      // null is "not set": the map's value (as Python's None), never the table's default.
      json set = json::object();
      for (const auto& [key, value] : body.options.items()) {
        if (!value.is_null()) set[key] = value;
      }
      if (!set.empty()) {
        LocalizerOptions o = map.localizer->options();
        constexpr OptionScope kRequest[] = {OptionScope::kRequest};
        SetLocalizerOptions(&o, set, kRequest, where);
        try {
          o.localize.Check();  // combinations (min_iterations <= max_iterations) before any work
        } catch (const Error& e) {
          Fail("{}: {}", where, e.what());
        }
        // What would only hold a worker: a floor of draws that takes a good part of the
        // deadline (p6L takes ~0.6 ms a draw, after ~1-2 s of SIFT for a photo; an outsider's
        // min_iterations 10 000 held a worker 9 s), a threshold below what any keypoint is
        // located to.
        const double most_draws = 50 * options.request_seconds;
        if (o.localize.ransac.min_iterations > most_draws) {
          Fail(
              "{}.options.min_iterations: {} draws do not fit this server's {} s deadline (at "
              "most {:g})",
              where, o.localize.ransac.min_iterations, options.request_seconds, most_draws);
        }
        if (o.localize.ransac.max_error < kMinServedThreshold) {
          Fail("{}.options.threshold: {} px is below the {} px keypoints are located to", where,
               o.localize.ransac.max_error, kMinServedThreshold);
        }
        r.options = o.localize;
      }
      // The method and what it needs, before the photos are read (seconds for nothing).
      r.method = map.localizer->PhotosMethod(body.Photos(), r).name;
    } catch (const Error& e) {
      Throw(400, e.what());
    }
    // Counted when the work starts, not when the request arrived: a job that
    // waited in the queue past its deadline (already answered 504) is
    // skipped, and RANSAC stops at it (3 requests RANSAC could not finish
    // held one worker 31 s).
    r.deadline = deadline;
    return r;
  }

  // The photo's header (400 when it is none or differs from its camera, 413
  // past the pixel cap or the memory budget); returns its pixel count.
  uint64_t CheckPhotoHeader(const std::string& bytes, const Camera& camera, const std::string& name,
                            const LoadedMap& map) {
    const std::span<const uint8_t> data(reinterpret_cast<const uint8_t*>(bytes.data()),
                                        bytes.size());
    ImageHeader header;
    try {
      header = ReadImageHeader(data, name, ImageLimits{.max_pixels = UINT64_MAX});
    } catch (const Error& e) {
      Throw(400, e.what());
    }
    if (header.width * header.height > options.max_pixels) {
      Throw(413, fmt::format("{}: {}x{} pixels exceed this server's limit of {} pixels", name,
                             header.width, header.height, options.max_pixels));
    }
    // The camera is the photo's size as stored, or as displayed when its EXIF
    // orientation turns it (then the photo is turned before its features are found).
    try {
      CheckImageSize(header, camera.width, camera.height, name);
    } catch (const Error& e) {
      Throw(400, e.what());
    }
    CheckPhotoMemory(header.width, header.height, name, map);
    return header.width * header.height;
  }

  // 413 when SIFT's scale space for a photo this size (after downscaling
  // to max_image_size) alone exceeds the budget; others wait for room.
  void CheckPhotoMemory(uint64_t width, uint64_t height, const std::string& name,
                        const LoadedMap& map) const {
    // With the map's SIFT options: its max_image_size decides the downscaling.
    const size_t need = SiftScaleSpaceBytes(static_cast<int>(width), static_cast<int>(height),
                                            map.localizer->options().image.sift);
    if (need > BudgetBytes()) {
      Throw(413, fmt::format("{}: SIFT on a {}x{} photo needs {} MB, over the server's memory "
                             "budget of {} MB: send a smaller photo",
                             name, width, height, need >> 20, BudgetBytes() >> 20));
    }
  }

  size_t BudgetBytes() const { return static_cast<size_t>(options.memory_budget_mb * 1024 * 1024); }

  void RecordStages(const LocalizerResult& r) {
    metrics.Stage("decode", r.times.decode_ms);
    metrics.Stage("extract", r.times.extract_ms);
    metrics.Stage("match", r.times.match_ms);
    metrics.Stage("ransac", r.times.ransac_ms);
    metrics.Stage("refine", r.times.refine_ms);
    metrics.Stage("total", r.times.total_ms);
  }

  // POST /v1/maps/{id}/localize: one photo or a device's frames (localize_body.h).
  json Localize(const HttpRequest& req, const std::string& id, json* log) {
    const auto token = Authorize(req);
    if (token) (*log)["token"] = token->id;
    const auto map = FindMap(id, token);
    (*log)["map"] = id;
    const TokenSlot slot(*this, token);
    const Clock::time_point deadline = Deadline(req);  // rate charged at the head (Screen)
    const std::string type = req.Header("Content-Type");
    if (!req.multipart && type.rfind("application/json", 0) != 0) {
      Throw(415, "send multipart/form-data (image + camera) or application/json (features)");
    }
    auto body = std::make_shared<LocalizeBody>();
    try {
      *body =
          req.multipart
              ? Parsing(deadline, [&] { return ReadMultipartBody(req.parts, options.max_frames); })
              : Parsing(deadline, [&] {
                  return ReadJsonBody(ParseRequestJson(req.body, "body"), options.max_frames);
                });
    } catch (const FramesOverLimit& e) {
      Throw(413, e.what());
    } catch (const Error& e) {
      Throw(400, e.what());
    }
    CheckFramePixels(*body, *map);
    CheckRigExtent(*body, *map);
    const LocalizeRequest r =
        RequestOptions(*map, *body, deadline, req.multipart ? "multipart" : "body");
    (*log)["frames"] = body->frames.size();
    std::function<LocalizerResult()> job = [map, body, r] {
      return map->localizer->LocalizePhotos(body->Photos(), r);
    };
    const LocalizerResult result = RunBounded(std::move(job), deadline);
    RecordStages(result);
    (*log)["times_ms"] = json(StageTimesToJson(result.times));
    (*log)["success"] = result.success();
    return PoseJson(result, token && token->admin ? &map->localizer->map() : nullptr);
  }

  // A rig's cameras within reach of the map: a camera 1 000 map diagonals
  // (and 10 000 units) from its rig (cam_from_rig.t = 1e30) is no device's,
  // and its rays held a worker until the deadline. (A rig's units may be
  // metres and the map's not: the bound is loose.)
  static void CheckRigExtent(const LocalizeBody& body, const LoadedMap& map) {
    if (body.frames.size() < 2 || !map.details.contains("anchor_bbox")) return;
    const json& box = map.details["anchor_bbox"];
    const Eigen::Vector3d lo(box["min"][0], box["min"][1], box["min"][2]);
    const Eigen::Vector3d hi(box["max"][0], box["max"][1], box["max"][2]);
    const double reach = std::max(1e4, 1000 * (hi - lo).norm());
    for (const WireFrame& f : body.frames) {
      const double d = f.cam_from_rig.translation.norm();
      if (!(d <= reach)) {
        Throw(400, fmt::format("{}: cam_from_rig puts the camera {:g} from the rig's origin, "
                               "beyond reach of the map ({:g})",
                               f.name, d, reach));
      }
    }
  }

  // Each photo's header (CheckPhotoHeader), and their pixels together within the cap (413).
  void CheckFramePixels(const LocalizeBody& body, const LoadedMap& map) {
    uint64_t pixels = 0;
    for (const WireFrame& f : body.frames) {
      if (!f.image.empty()) pixels += CheckPhotoHeader(f.image, f.camera, f.name, map);
    }
    if (pixels > options.max_pixels) {
      Throw(413, fmt::format("{} frames of {} pixels together exceed this server's limit of {} "
                             "pixels a request",
                             body.frames.size(), pixels, options.max_pixels));
    }
  }

  // A map route's caller and map (401 / 404 as Authorize and FindMap), logged.
  std::pair<std::optional<TokenEntry>, std::shared_ptr<const LoadedMap>> RequestMap(
      const HttpRequest& req, const std::string& id, json* log) const {
    const auto token = Authorize(req);
    if (token) (*log)["token"] = token->id;
    auto map = FindMap(id, token);
    (*log)["map"] = map->id;
    return {token, std::move(map)};
  }

  // The maps' owner: an admin token, or anyone on a server without tokens.
  static bool Owner(const std::optional<TokenEntry>& token) { return !token || token->admin; }
  // Who may have a map's lines (/segments): its owner, and every token of it once published.
  static bool MaySeeLines(const std::optional<TokenEntry>& token, const LoadedMap& map) {
    return Owner(token) || map.publish_lines;
  }
  static void RefuseUnpublishedLines(const std::optional<TokenEntry>& token, const LoadedMap& map) {
    if (!MaySeeLines(token, map)) {
      Throw(403, "the map's lines are for admin tokens: its owner has not published them");
    }
  }

  // The owner's file `ID + suffix` beside the map.
  std::string OwnerFilePath(const LoadedMap& map, const std::string& suffix) const {
    return JoinPaths(options.maps_dir, map.id + suffix);
  }
  // ... for a request: admin tokens only, 404 when absent.
  std::string OwnerFile(const std::optional<TokenEntry>& token, const LoadedMap& map,
                        const std::string& suffix) const {
    if (!Owner(token)) Throw(404, "no audit for this token");
    const std::string path = OwnerFilePath(map, suffix);
    if (!FileExists(path)) Throw(404, fmt::format("no {} next to the map", "ID" + suffix));
    return path;
  }

  // GET /v1/maps/{id}/segments?limit=N: float32 segments (MapSegments), the
  // first N of the map's fixed order (default 20 000).
  std::string Segments(const HttpRequest& req, const std::string& id, HttpResponse& res,
                       json* log) {
    const auto [token, map] = RequestMap(req, id, log);
    RefuseUnpublishedLines(token, *map);
    const size_t total = map->segments.size() / 6;
    size_t limit = std::min<size_t>(total, 20000);
    if (const auto limit_param = req.Query("limit")) {
      const std::string& v = *limit_param;
      if (v.empty() || v.size() > 9 || !std::all_of(v.begin(), v.end(), ::isdigit)) {
        Throw(400, "limit: expected a number of segments");
      }
      limit = std::min<size_t>(total, std::stoul(v));
    }
    res.headers.emplace_back("X-Linecloud-Lines", std::to_string(total));
    res.headers.emplace_back("X-Linecloud-Segments", std::to_string(limit));
    return std::string(reinterpret_cast<const char*>(map->segments.data()),
                       limit * 6 * sizeof(float));
  }

  // GET /v1/maps/{id}/audit: the owner's audit report (DIR/ID.audit.json,
  // `linecloud audit --out` writes it as report.json); admin tokens only.
  json Audit(const HttpRequest& req, const std::string& id, json* log) {
    const auto [token, map] = RequestMap(req, id, log);
    const std::string path = OwnerFile(token, *map, ".audit.json");
    try {
      return ParseJsonUniqueKeys(ReadFilePrefix(path, 1 << 22), map->id + ".audit.json");
    } catch (const std::exception& e) {
      Throw(500, fmt::format("{}: not JSON ({})", map->id + ".audit.json", e.what()));
    }
  }

  // GET /v1/maps/{id}/audit/points: the points the audit's attack recovered
  // (DIR/ID.audit.ply, the recovered.ply of `linecloud audit --out`), coloured
  // by error; admin tokens only. N x 3 float32 then N x 3 uint8.
  std::string AuditPoints(const HttpRequest& req, const std::string& id, HttpResponse& res,
                          json* log) {
    const auto [token, map] = RequestMap(req, id, log);
    const std::string path = OwnerFile(token, *map, ".audit.ply");
    std::vector<float> xyz;
    std::vector<uint8_t> rgb;
    try {
      ReadColoredPointsPly(path, 10'000'000, &xyz, &rgb);
    } catch (const Error& e) {
      Throw(500, fmt::format("{}.audit.ply: {}", map->id,
                             e.what()));  // the server's file, not the request
    }
    res.headers.emplace_back("X-Linecloud-Points", std::to_string(xyz.size() / 3));
    std::string body(reinterpret_cast<const char*>(xyz.data()), xyz.size() * sizeof(float));
    body.append(reinterpret_cast<const char*>(rgb.data()), rgb.size());
    return body;
  }

  // /geopose's map: ?map=ID, else the token's only geo-anchored map (404 otherwise).
  std::shared_ptr<const LoadedMap> GeoPoseMap(const HttpRequest& req,
                                              const std::optional<TokenEntry>& token) const {
    std::string id = req.Query("map").value_or("");
    if (id.empty()) {
      std::vector<std::string> anchored;
      for (const auto& [mid, m] : *Maps()) {
        if (m->anchor && (!token || token->MayUse(mid))) anchored.push_back(mid);
      }
      if (anchored.size() != 1) {
        Throw(404,
              anchored.empty() ? "no geo-anchored map" : "several geo-anchored maps: give ?map=ID");
      }
      id = anchored.front();
    }
    auto map = FindMap(id, token);
    if (!map->anchor) Throw(404, "the map has no geo-anchor");
    return map;
  }

  // POST /geopose (OSCP GeoPose Protocol v2)
  json GeoPoseRoute(const HttpRequest& req, json* log) {
    // Who, which map and how often before the body is read: a stranger's or
    // a throttled client's body costs no parsing.
    const auto token = Authorize(req);
    if (token) (*log)["token"] = token->id;
    const auto map = GeoPoseMap(req, token);
    (*log)["map"] = map->id;
    const TokenSlot slot(*this, token);
    const Clock::time_point deadline = Deadline(req);  // rate charged at the head (Screen)
    json j = ParseBody(req.body, "GeoPoseReq", deadline);
    const json* reading = nullptr;
    Camera camera;
    auto image = std::make_shared<GreyImage>();
    auto bytes = std::make_shared<std::string>();
    try {
      reading = &CheckGeoPoseReq(j);
      const json& c = *reading;
      if (!c.contains("imageBytes") || !c["imageBytes"].is_string()) Fail("imageBytes is missing");
      // OSCP types size as number[]: 1536.0 is a width too.
      const auto whole = [](const json& v) {
        return v.is_number() && v.get<double>() >= 0 && v.get<double>() <= 1e9 &&
               v.get<double>() == std::floor(v.get<double>());
      };
      if (!c.contains("size") || !c["size"].is_array() || c["size"].size() != 2 ||
          !whole(c["size"][0]) || !whole(c["size"][1])) {
        Fail("size: expected [width, height] in whole pixels");
      }
      if (!c.contains("params") || !c["params"].is_object()) Fail("params is missing");
      const json& p = c["params"];
      if (!p.contains("model") || !p["model"].is_string() || !p.contains("modelParams") ||
          !p["modelParams"].is_array()) {
        Fail("params: 'model' (a COLMAP camera name) and 'modelParams' are required");
      }
      // The reference clients read "pinhole" as PINHOLE.
      std::string model = p["model"].get<std::string>();
      for (char& ch : model) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
      camera = CameraFromJson({{"model", model},
                               {"width", c["size"][0].get<uint64_t>()},
                               {"height", c["size"][1].get<uint64_t>()},
                               {"params", p["modelParams"]}},
                              "cameraReadings[0]");
      CheckServedCamera(camera, "cameraReadings[0]");
    } catch (const Error& e) {
      Throw(400, std::string("GeoPoseReq: ") + e.what());
    }
    const json& c = *reading;
    *bytes = Base64Decode(c["imageBytes"].get<std::string>(), "imageBytes");
    const auto* b = reinterpret_cast<const unsigned char*>(bytes->data());
    const bool encoded =
        bytes->size() > 8 && ((b[0] == 0xFF && b[1] == 0xD8) || (b[0] == 0x89 && b[1] == 'P'));
    if (encoded) {
      CheckPhotoHeader(*bytes, camera, "imageBytes", *map);
    } else {
      // Raw pixels: GRAY8 or RGBA32 of `size`.
      const std::string format = c.contains("imageFormat") && c["imageFormat"].is_string()
                                     ? c["imageFormat"].get<std::string>()
                                     : "";
      const uint64_t n = camera.width * camera.height;
      if (n > options.max_pixels) Throw(413, "imageBytes: the image exceeds the pixel cap");
      CheckPhotoMemory(camera.width, camera.height, "imageBytes", *map);
      const int channels = format == "GRAY8" ? 1 : format == "RGBA32" ? 4 : 0;
      if (channels == 0) Throw(400, "imageBytes: neither JPEG / PNG nor GRAY8 / RGBA32 pixels");
      if (bytes->size() != n * channels) {
        Throw(400, fmt::format("imageBytes: {} bytes, {}x{} {} needs {}", bytes->size(),
                               camera.width, camera.height, format, n * channels));
      }
      // Converted as an encoded photo is (one grey for every route: COLMAP's).
      *image = GreyImageFromPixels(std::span(b, bytes->size()), static_cast<int>(camera.width),
                                   static_cast<int>(camera.height), channels, "imageBytes");
    }
    LocalizeBody one;  // the map's method for one photo, its options
    one.frames.resize(1);
    const LocalizeRequest r = RequestOptions(*map, one, deadline, "geopose");
    const LocalizerResult result = RunBounded(
        [map, bytes, image, camera, r, encoded] {
          return encoded ? map->localizer->LocalizeEncodedImage(
                               std::span(reinterpret_cast<const uint8_t*>(bytes->data()),
                                         bytes->size()),
                               camera, r, "imageBytes")
                         : map->localizer->LocalizeImage(*image, camera, r);
        },
        deadline);
    RecordStages(result);
    (*log)["success"] = result.success();
    if (!result.success()) Throw(404, "no pose: " + result.reason);
    const Sim3d& p = result.pose.query_from_world;
    const GeoPose g = GeoPoseOfCamera(*map->anchor, Rigid3d(p.rotation, p.translation));
    const double scale = map->anchor->enu_from_map.scale;
    // Every field a GeoPoseResp has, of its type: the reference clients read each (a null id
    // or accuracy fails their parsing).
    const auto finite_or_max = [](double v) {
      return std::isfinite(v) ? v : std::numeric_limits<double>::max();
    };
    return {{"id", j.contains("id") && j["id"].is_string() ? j["id"] : json("")},
            {"timestamp", std::chrono::duration_cast<std::chrono::milliseconds>(
                              std::chrono::system_clock::now().time_since_epoch())
                              .count()},
            {"type", "geopose"},
            {"accuracy",
             {{"position", finite_or_max(result.pose.uncertainty.position * scale)},
              {"orientation", finite_or_max(result.pose.uncertainty.rotation_deg)}}},
            {"geopose",
             {{"position", {{"lat", g.lat_deg}, {"lon", g.lon_deg}, {"h", g.h_m}}},
              {"quaternion",
               {{"x", g.enu_from_camera.x()},
                {"y", g.enu_from_camera.y()},
                {"z", g.enu_from_camera.z()},
                {"w", g.enu_from_camera.w()}}}}}};
  }

  // Every route: status from HttpError, library errors 400, one access-log line.
  // `answer` returns JSON, or fills the response itself and returns null.
  // An access-log line's first fields.
  static json LogLine(const std::string& route, const HttpRequest& req) {
    return {{"time", std::chrono::duration_cast<std::chrono::milliseconds>(
                         std::chrono::system_clock::now().time_since_epoch())
                         .count()},
            {"route", route},
            {"method", req.method},
            {"client", req.client}};
  }

  HttpResponse Handle(const std::string& route, const HttpRequest& req,
                      const std::function<json(json*, HttpResponse*)>& answer) {
    const auto start = Clock::now();
    json log = LogLine(route, req);
    HttpResponse res;
    const auto refuse = [&](int status, const std::string& message) {
      res = ErrorResponse(status, message);
    };
    try {
      json j = answer(&log, &res);
      if (!j.is_null()) res.body = DumpJson(j);
    } catch (const HttpError& e) {
      refuse(e.status, e.message);
      res.headers = e.headers;
      if (e.status == 401)
        res.headers.emplace_back("WWW-Authenticate", "Bearer realm=\"linecloud\"");
      if (e.status == 405) res.headers.emplace_back("Allow", AllowedMethods(req.path));
      if (e.retry_after > 0) {
        res.headers.emplace_back("Retry-After",
                                 std::to_string(static_cast<int>(std::ceil(e.retry_after))));
      }
    } catch (const Error& e) {
      refuse(400, e.what());
    } catch (const std::exception& e) {
      refuse(500, "internal error");
      log["exception"] = e.what();
    }
    metrics.Request(route, res.status);
    log["status"] = res.status;
    log["ms"] = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    Log(DumpJson(log));
    return res;
  }

  // A route answering bytes (application/octet-stream), errors as JSON.
  using BytesRoute = std::string (Impl::*)(const HttpRequest&, const std::string&, HttpResponse&,
                                           json*);
  HttpResponse Bytes(const std::string& route, const HttpRequest& req, const std::string& id,
                     BytesRoute bytes) {
    return Handle(route, req, [&](json* log, HttpResponse* res) {
      res->body = (this->*bytes)(req, id, *res, log);
      res->content_type = "application/octet-stream";
      return json();
    });
  }

  // A map route's checks that need no body, at its head: who (401), which
  // map (404), may they (403), how often (429: every request that gets this
  // far is charged, whether its body then arrives or not).
  void HeadChecks(HttpRequest& req) {
    const bool geopose = req.path == "/geopose";
    const std::optional<MapPath> map_path = SplitMapPath(req.path);
    if (!geopose && !map_path) return;
    const auto token = Authorize(req);
    if (token) req.account = "token " + token->id;  // else the address (HttpServer's default)
    const std::string tail = map_path ? map_path->tail : "";
    const auto map = geopose ? GeoPoseMap(req, token) : FindMap(map_path->id, token);
    if (tail == "/segments") RefuseUnpublishedLines(token, *map);
    if (geopose || tail == "/localize" || tail == "/segments") Throttle(token);
  }

  // Before a request's body is read: what no route answers with a body,
  // refused at once (the connection then closes). Answered through Handle
  // (logged, counted).
  std::optional<HttpResponse> Screen(HttpRequest& req) {
    std::optional<HttpError> refusal;
    const std::string allowed = AllowedMethods(req.path);
    const std::string length = req.Header("Content-Length");
    const std::string range = req.Header("Range");
    if (req.headers.size() > kMaxHeaders) {
      refusal = HttpError{431, fmt::format("more than {} header fields", kMaxHeaders)};
    } else if (req.path.find('\0') != std::string::npos) {
      // A decoded %00 cut a console file's name short (app.js%00.html was
      // served as HTML).
      refusal = HttpError{400, "the path holds a NUL byte"};
    } else if (req.HeaderCount("Content-Length") > 1 ||
               (!length.empty() && !std::all_of(length.begin(), length.end(), ::isdigit))) {
      refusal = HttpError{400, "Content-Length: one decimal number expected"};
    } else if (!allowed.empty() && allowed.find(req.method) == std::string::npos &&
               !(req.method == "HEAD" && allowed == "GET")) {
      refusal = HttpError{405, fmt::format("{} is not allowed here ({})", req.method, allowed)};
    } else if (req.BodyLength() > static_cast<uint64_t>(4 * options.max_body_mb * 1024 * 1024)) {
      // Far over the cap: answered at once and the connection closed. A body
      // just over the cap is still read (and dropped), so its client reads
      // the 413 (HttpServer).
      refusal = HttpError{
          413, BodyLimitMessage(static_cast<uint64_t>(options.max_body_mb * 1024 * 1024))};
    } else if (req.HeaderCount("Transfer-Encoding") > 0) {
      refusal =
          HttpError{411, "send the body with a Content-Length (Transfer-Encoding is refused)"};
    } else if (range.find(',') != std::string::npos || req.HeaderCount("Range") > 1) {
      // 500 ranges of one file answered 808 MB (cpp-httplib).
      refusal = HttpError{416, "one range per request"};
    }
    const std::string route = RouteName(req.path);
    if (refusal) return Handle(route, req, [&](json*, HttpResponse*) -> json { throw *refusal; });
    // Whoever may send a body is known before any of it is read or held.
    try {
      HeadChecks(req);
      if (allowed != "POST" && req.AnnouncesBody()) {
        if (allowed.empty()) Throw(404, "no such route");  // the console's files take no body
        Throw(400, fmt::format("{} {} takes no body", req.method, route));
      }
      // The probes answered here, on the connections' thread: never behind
      // requests waiting for a handler, a parse slot or a worker.
      if (req.path == "/healthz" || req.path == "/readyz") return Dispatch(req);
      return std::nullopt;
    } catch (const HttpError& e) {
      return Handle(route, req, [&](json*, HttpResponse*) -> json { throw e; });
    }
  }

  // An answer the HTTP layer gave itself (413, 503, a broken multipart
  // body): logged and counted as the routes' are.
  void Answered(const HttpRequest& req, const HttpResponse& res) {
    const std::string route = RouteName(req.path);
    metrics.Request(route, res.status);
    json log = LogLine(route, req);
    log["status"] = res.status;
    log["by"] = "http";
    try {
      log["error"] = json::parse(res.body).value("error", "");
    } catch (const std::exception&) {
    }
    Log(DumpJson(log));
  }

  // Content-Security-Policy of every answer (ConsolePolicy).
  std::string security_policy = ConsolePolicy("");

  // The API's routes by path (their methods were checked by Screen), else
  // the console's files.
  HttpResponse Dispatch(const HttpRequest& req) {
    const std::string& path = req.path;
    if (path == "/healthz") {
      return Handle(path, req, [](json*, HttpResponse*) { return json{{"status", "ok"}}; });
    }
    if (path == "/readyz") {
      return Handle(path, req, [this](json*, HttpResponse*) {
        // No count: anyone may ask (admins read it in /metrics).
        if (Maps()->empty()) Throw(503, "no map is loaded");
        return json{{"status", "ready"}};
      });
    }
    if (path == "/metrics")
      return Handle(path, req,
                    [&](json* log, HttpResponse* res) { return MetricsRoute(req, log, res); });
    if (path == "/v1/maps")
      return Handle(path, req, [&](json* log, HttpResponse*) { return MapsRoute(req, log); });
    if (path == "/geopose")
      return Handle(path, req, [&](json* log, HttpResponse*) { return GeoPoseRoute(req, log); });
    if (const auto map_path = SplitMapPath(path); map_path && !AllowedMethods(path).empty()) {
      const std::string& id = map_path->id;
      const std::string& tail = map_path->tail;
      const std::string route = RouteName(path);
      if (tail.empty())
        return Handle(route, req,
                      [&](json* log, HttpResponse*) { return DetailsRoute(req, id, log); });
      if (tail == "/segments") return Bytes(route, req, id, &Impl::Segments);
      if (tail == "/audit/points") return Bytes(route, req, id, &Impl::AuditPoints);
      if (tail == "/audit")
        return Handle(route, req, [&](json* log, HttpResponse*) { return Audit(req, id, log); });
      return Handle(route, req, [&](json* log, HttpResponse*) { return Localize(req, id, log); });
    }
    return Handle("static", req, [&](json* log, HttpResponse* res) {
      (*log)["path"] = req.path;
      StaticFile(req, res);
      return json();
    });
  }

  // GET /metrics (admin tokens; 404 for readers)
  json MetricsRoute(const HttpRequest& req, json* log, HttpResponse* res) {
    const auto token = Authorize(req);
    if (token && !token->admin) Throw(404, "no such route for this token");
    if (token) (*log)["token"] = token->id;
    res->body = metrics.Text(in_flight.load(), pool->queued(), Maps()->size());
    res->content_type = "text/plain; version=0.0.4";
    return json();
  }

  // GET /v1/maps: the maps this token may use.
  json MapsRoute(const HttpRequest& req, json* log) {
    const auto token = Authorize(req);
    if (token) (*log)["token"] = token->id;
    json list = json::array();
    for (const auto& [id, m] : *Maps()) {
      if (!token || token->MayUse(id)) list.push_back(m->info);
    }
    return json{{"maps", list}};
  }

  // GET /v1/maps/{id}: what `linecloud info` says; readers get no geometry.
  json DetailsRoute(const HttpRequest& req, const std::string& id, json* log) {
    const auto [token, map] = RequestMap(req, id, log);
    const bool owner = Owner(token);
    json details = map->details;
    if (!owner) {
      details.erase("anchor_bbox");
      // The key's fingerprint links maps lifted under one model key: the owner's to know.
      details.erase("key_fingerprint");
    }
    // What this token may fetch of the map: a client (the console) asks only
    // for those, instead of learning it from a 403 / 404.
    details["for_this_token"] = {
        {"admin", owner},
        {"segments", MaySeeLines(token, *map)},
        {"audit", owner && FileExists(OwnerFilePath(*map, ".audit.json"))},
        {"audit_points", owner && FileExists(OwnerFilePath(*map, ".audit.ply"))}};
    return details;
  }

  // The console's files (GET / HEAD under web_dir), one byte range at most.
  void StaticFile(const HttpRequest& req, HttpResponse* res) const {
    if (web_dir.empty() || (req.method != "GET" && req.method != "HEAD")) {
      Throw(404, "no such route");
    }
    // Only names under web_dir: every segment a plain name (no empty one, so
    // no absolute path: "//etc/shadow" joined to the folder was /etc/shadow,
    // an outsider's find), and the file found inside the folder.
    if (req.path.empty() || req.path.front() != '/') Throw(404, "no such route");
    const std::string relative = req.path == "/" ? "index.html" : req.path.substr(1);
    for (size_t begin = 0; begin <= relative.size();) {
      const size_t end = std::min(relative.find('/', begin), relative.size());
      const std::string_view segment(relative.data() + begin, end - begin);
      if (segment.empty() || segment == ".." || segment == "." ||
          segment.find('\\') != std::string_view::npos) {
        Throw(404, "no such route");
      }
      begin = end + 1;
    }
    fs::path file = fs::path(web_dir) / fs::path(relative).relative_path();
    std::error_code inside;
    const fs::path real = fs::weakly_canonical(file, inside);
    const std::string root = fs::weakly_canonical(web_dir, inside).string() + "/";
    if (inside || real.string().rfind(root, 0) != 0) Throw(404, "no such route");
    std::error_code ec;
    if (fs::is_directory(file, ec)) file /= "index.html";
    if (!fs::is_regular_file(file, ec)) Throw(404, "no such route");
    res->content_type = MediaType(file.extension().string());
    const std::string range = req.Header("Range");
    // The file compressed beside it (scripts/build_web.sh writes NAME.gz) when the client takes
    // gzip and wants the whole file.
    std::string etag_suffix;
    res->headers = {
        {"Accept-Ranges", "bytes"}, {"Cache-Control", "no-cache"}, {"Vary", "Accept-Encoding"}};
    if (range.empty() && AcceptsGzip(req.Header("Accept-Encoding")) &&
        fs::is_regular_file(file.string() + ".gz", ec)) {
      file += ".gz";
      etag_suffix = "-gz";
      res->headers.emplace_back("Content-Encoding", "gzip");
    }
    const uint64_t size = fs::file_size(file, ec);
    if (ec) Throw(404, "no such route");
    const auto mtime = fs::last_write_time(file, ec);
    if (ec) Throw(404, "no such route");
    // Revalidated on each load (no-cache): an unchanged file costs a 304 and no bytes.
    const std::string etag =
        fmt::format("\"{:x}-{:x}{}\"", size, mtime.time_since_epoch().count(), etag_suffix);
    res->headers.emplace_back("ETag", etag);
    if (const std::string match = req.Header("If-None-Match");
        !match.empty() && (match == "*" || match.find(etag) != std::string::npos)) {
      res->status = 304;
      return;
    }
    res->file = file.string();
    res->file_length = size;
    // If-Range with another validator: the whole (changed) file, not a piece of it.
    if (range.empty() || (req.HeaderCount("If-Range") > 0 && req.Header("If-Range") != etag))
      return;
    // bytes=A-B, bytes=A-, bytes=-N (RFC 9110 14.1.2); other forms ignored.
    if (range.rfind("bytes=", 0) != 0) return;
    const std::string spec = range.substr(6);
    const size_t dash = spec.find('-');
    const auto number = [](const std::string& v, uint64_t* out) {
      if (v.empty() || v.size() > 18 || !std::all_of(v.begin(), v.end(), ::isdigit)) return false;
      *out = std::stoull(v);
      return true;
    };
    uint64_t first = 0, last = size ? size - 1 : 0, n = 0;
    if (dash == std::string::npos) return;
    const std::string a = spec.substr(0, dash), b = spec.substr(dash + 1);
    if (a.empty()) {
      if (!number(b, &n)) return;
      if (n == 0 || size == 0) Throw416(size);
      first = size - std::min(n, size);
    } else {
      if (!number(a, &first) || (!b.empty() && !number(b, &last))) return;
      if (!b.empty() && last < first) return;
      if (first >= size) Throw416(size);
      last = std::min(last, size - 1);
    }
    res->status = 206;
    res->file_offset = first;
    res->file_length = last - first + 1;
    res->headers.emplace_back("Content-Range", fmt::format("bytes {}-{}/{}", first, last, size));
  }

  [[noreturn]] static void Throw416(uint64_t size) {
    throw HttpError{416,
                    fmt::format("the range is outside the file ({} bytes)", size),
                    0,
                    {{"Content-Range", fmt::format("bytes */{}", size)}}};
  }

  static std::string MediaType(const std::string& extension) {
    static const std::map<std::string, std::string> kTypes = {
        {".html", "text/html; charset=utf-8"},
        {".js", "text/javascript; charset=utf-8"},
        {".mjs", "text/javascript; charset=utf-8"},
        {".css", "text/css; charset=utf-8"},
        {".json", "application/json"},
        {".png", "image/png"},
        {".jpg", "image/jpeg"},
        {".svg", "image/svg+xml"},
        {".ico", "image/x-icon"},
        {".wasm", "application/wasm"},
        {".txt", "text/plain; charset=utf-8"},
        {".map", "application/json"}};
    const auto it = kTypes.find(extension);
    return it == kTypes.end() ? "application/octet-stream" : it->second;
  }

  // Last: destroyed first, its handlers done before anything they use goes.
  std::unique_ptr<HttpServer> http;
};

Server::Server(ServeOptions options) : impl_(std::make_unique<Impl>()) {
  options.Check();
  if (sodium_init() < 0) Fail("libsodium could not be initialised");
  impl_->options = std::move(options);
  const ServeOptions& o = impl_->options;
  if (!o.tokens_path.empty()) {
    impl_->tokens_ = std::make_shared<const TokenStore>(TokenStore::Read(o.tokens_path));
  }
  std::tie(impl_->host, impl_->port) = ParseListen(o.listen, "--listen");
  LocalizerOptions defaults = o.localizer;
  defaults.image.max_pixels = o.max_pixels;
  defaults.image.threads = defaults.image.index.threads = 1;  // concurrency: the workers
  impl_->registry = std::make_unique<MapRegistry>(
      o.maps_dir, defaults, [impl = impl_.get()](const std::string& line) { impl->Log(line); },
      &impl_->metrics);
  impl_->registry->Load();
  impl_->pool = std::make_unique<WorkPool>(o.threads, o.queue);
  impl_->parse_slots = std::make_unique<std::counting_semaphore<>>(o.threads + 2);
  SetSiftMemoryLimit(impl_->BudgetBytes());  // process-wide: the extractions of every map
  const std::string web = o.web_dir.empty() ? DefaultWebDir() : o.web_dir;
  // [newcomer] The console's sources (web/src) lack three.js: the page would
  // load and do nothing. Only a built console (build/web) is served.
  const bool built = fs::is_regular_file(fs::path(web) / "vendor" / "three" / "three.module.js");
  if (!web.empty() && fs::is_regular_file(fs::path(web) / "index.html") && !built) {
    if (!o.web_dir.empty()) {
      Fail(
          "serve: --web {}: not a built console (no vendor/three/three.module.js): serve the "
          "folder scripts/build_web.sh makes (build/web)",
          o.web_dir);
    }
    impl_->Log(DumpJson(json{{"warning", "no console: " + web + " is not a built console"}}));
  } else if (!web.empty() && fs::is_regular_file(fs::path(web) / "index.html")) {
    impl_->web_dir = web;
    impl_->security_policy =
        ConsolePolicy(ReadFilePrefix((fs::path(web) / "index.html").string(), 1 << 20));
    impl_->Log(DumpJson(json{{"notice", "console at /"}, {"web", web}}));
  } else if (!o.web_dir.empty()) {
    Fail("serve: --web {}: no index.html there (build it: bash scripts/build_web.sh)", o.web_dir);
  }
  Impl* impl = impl_.get();
  HttpServerOptions h;
  h.host = impl->host;
  h.port = impl->port;
  h.connections = o.connections;
  h.connections_per_address = o.connections_per_address;
  h.max_body_bytes = static_cast<uint64_t>(o.max_body_mb * 1024 * 1024);
  h.body_budget_bytes = static_cast<uint64_t>(o.body_budget_mb * 1024 * 1024);
  // One token's (or, without tokens, one address's) bodies: a quarter of the budget, at least
  // one body of the largest size.
  h.account_budget_bytes = std::max(h.max_body_bytes, h.body_budget_bytes / 4);
  // A body still arriving a socket timeout after the request's deadline is cut off (until
  // then it is answered 504).
  h.body_time = std::chrono::milliseconds(
      static_cast<int64_t>(1000 * (o.request_seconds + o.read_timeout_s)));
  h.refused_body_time = std::chrono::milliseconds(static_cast<int64_t>(1000 * o.read_timeout_s));
  h.idle_seconds = static_cast<unsigned>(std::max(1.0, std::ceil(o.read_timeout_s)));
  // Handlers wait for a worker (or their deadline): the workers, the queue and
  // a few for cheap routes; more requests wait in line, read and suspended.
  h.handler_threads = o.threads + o.queue + 16;
  h.drain = std::chrono::milliseconds(
      static_cast<int64_t>(1000 * (o.request_seconds + o.read_timeout_s + o.write_timeout_s)));
  h.grace = std::chrono::milliseconds(static_cast<int64_t>(1000 * o.read_timeout_s));
  // Every answer: no sniffing, no framing, no referrer; the console's page
  // may run its own files and its import map only (security_policy).
  h.headers = {{"X-Content-Type-Options", "nosniff"},
               {"X-Frame-Options", "DENY"},
               {"Referrer-Policy", "no-referrer"},
               {"Content-Security-Policy", impl->security_policy}};
  h.screen = [impl](HttpRequest& req) { return impl->Screen(req); };
  h.answered = [impl](const HttpRequest& req, const HttpResponse& res) {
    impl->Answered(req, res);
  };
  h.handle = [impl](HttpRequest& req) { return impl->Dispatch(req); };
  h.notice = [impl](const std::string& text) { impl->Log(DumpJson(json{{"notice", text}})); };
  h.closed = [impl](const std::string& client) {
    impl->Log(DumpJson(json{{"time", std::chrono::duration_cast<std::chrono::milliseconds>(
                                         std::chrono::system_clock::now().time_since_epoch())
                                         .count()},
                            {"route", "other"},
                            {"client", client},
                            {"closed", "before a request reached a route"}}));
  };
  impl_->http = std::make_unique<HttpServer>(std::move(h));
}

Server::~Server() { Stop(); }

int Server::Bind() { return impl_->port = impl_->http->Bind(); }

void Server::Run() { impl_->http->Run(); }

void Server::Stop() { impl_->http->Stop(); }

void Server::Reload() {
  impl_->registry->Reload();
  impl_->ReloadTokens();
}

size_t Server::num_maps() const { return impl_->Maps()->size(); }

std::string Server::url() const {
  // An IPv6 address in brackets (RFC 3986): http://[::1]:8080.
  const bool v6 = impl_->host.find(':') != std::string::npos;
  return v6 ? fmt::format("http://[{}]:{}", impl_->host, impl_->port)
            : fmt::format("http://{}:{}", impl_->host, impl_->port);
}

}  // namespace linecloud
