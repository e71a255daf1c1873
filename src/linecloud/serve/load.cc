#include "linecloud/serve/load.h"

#include <sodium.h>

#include <atomic>
#include <chrono>
#include <map>
#include <sys/socket.h>
#include <unistd.h>
#include <mutex>
#include <thread>

#include <fmt/format.h>

#include "linecloud/features/image.h"
#include "linecloud/features/sift.h"
#include "linecloud/io/json_util.h"
#include "linecloud/pipeline/image_query.h"
#include "linecloud/localize/query_json.h"
#include "linecloud/util/error.h"
#include "linecloud/util/base64.h"
#include "linecloud/util/file.h"
#include "linecloud/util/memory.h"
#include "linecloud/util/statistics.h"
#include "linecloud/serve/raw_http.h"

#include <httplib.h>
#undef _res

namespace linecloud {
namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

struct Level {
  std::vector<double> ms;
  std::map<int, int> statuses;  // 0: no answer
  int poses = 0;                // 200 answers with a pose
  double seconds = 0;
};

// `requests` requests over `clients` keep-alive connections.
Level Drive(int port, int clients, int requests, double max_seconds,
            const std::function<httplib::Result(httplib::Client&)>& send) {
  Level level;
  std::mutex mutex;
  std::atomic<int> next = 0;
  const auto start = Clock::now();
  std::vector<std::thread> threads;
  for (int c = 0; c < clients; ++c) {
    threads.emplace_back([&] {
      httplib::Client client("127.0.0.1", port);
      client.set_read_timeout(60, 0);
      client.set_keep_alive(true);
      while (next++ < requests &&
             std::chrono::duration<double>(Clock::now() - start).count() < max_seconds) {
        const auto t = Clock::now();
        const httplib::Result r = send(client);
        const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t).count();
        std::lock_guard<std::mutex> lock(mutex);
        level.ms.push_back(ms);
        ++level.statuses[r ? r->status : 0];
        if (r && r->status == 200 && r->body.find("\"success\":true") != std::string::npos) {
          ++level.poses;
        }
      }
    });
  }
  for (std::thread& t : threads) t.join();
  level.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return level;
}

LoadLevel LevelOf(const std::string& kind, int clients, const Level& l) {
  LoadLevel level;
  level.body = kind;
  level.concurrency = clients;
  level.requests = l.ms.size();
  level.per_second = l.seconds > 0 ? l.ms.size() / l.seconds : 0.0;
  level.p50_ms = Percentile(l.ms, 50);
  level.p99_ms = Percentile(l.ms, 99);
  level.statuses = l.statuses;
  level.poses = l.poses;
  return level;
}

// Requests an attacker would send without a proxy in front, each with a
// kind for the report (docs/serve.md's rows).
std::vector<std::pair<std::string, std::string>> HostileRequests(const std::string& path) {
  const auto raw = [](const std::string& head, const std::string& body = "") {
    return head + "\r\n" + body;
  };
  const std::string host = "Host: 127.0.0.1\r\nConnection: close\r\n";
  std::string nested(100000, '[');
  nested += std::string(100000, ']');
  std::string many_headers = "GET /healthz HTTP/1.1\r\n" + host;
  for (int i = 0; i < 500; ++i) many_headers += fmt::format("X-{}: {}\r\n", i, i);
  std::string ranges = "bytes=0-0";
  for (int i = 0; i < 500; ++i) ranges += ",0-";
  // A JPEG header declaring 7000 x 7000 pixels in a few hundred bytes.
  static constexpr char kBombHead[] =
      "\xFF\xD8\xFF\xC0\x00\x11\x08\x1B\x58\x1B\x58\x03\x01\x22\x00\x02\x11"
      "\x01\x03\x11\x01\xFF\xDA\x00\x0C\x03\x01\x00\x02\x11\x03\x11\x00\x3F\x00";
  // [siege]: 60 000 keys in one object (the duplicate check was quadratic), a body on a GET
  // (its announced length was reserved from the head), a threshold that fails every draw.
  std::string many_keys = "{\"keypoints\": []";
  for (int i = 0; i < 60000; ++i) many_keys += fmt::format(",\"k{}\":0", i);
  many_keys += "}";
  const std::string implausible =
      R"({"camera": {"model": "PINHOLE", "width": 640, "height": 480, "params": [500, 500, 320,)"
      R"( 240]}, "keypoints": [], "descriptors": "", "threshold": 1e-300})";
  std::string bomb(kBombHead, sizeof(kBombHead) - 1);  // 36 bytes (was read as 38: ASan)
  bomb += std::string(300, '\x55') + "\xFF\xD9";
  const std::string form =
      "--B\r\nContent-Disposition: form-data; name=\"image\"; filename=\"a.jpg\"\r\n\r\n" + bomb +
      "\r\n--B\r\nContent-Disposition: form-data; name=\"camera\"\r\n\r\nPINHOLE 7000 7000 "
      "5000 5000 3500 3500\r\n--B--\r\n";
  return {
      {"nested-json", raw(fmt::format("POST {} HTTP/1.1\r\n{}Content-Type: application/json\r\n"
                                      "Content-Length: {}\r\n",
                                      path, host, nested.size()),
                          nested)},
      {"chunked",
       raw(fmt::format("POST {} HTTP/1.1\r\n{}Transfer-Encoding: chunked\r\n", path, host),
           "100000\r\n" + std::string(4096, 'a'))},
      {"huge-length",
       raw(fmt::format("POST {} HTTP/1.1\r\n{}Content-Length: 99999999999\r\n", path, host))},
      {"500-headers", raw(many_headers)},
      {"500-ranges", raw(fmt::format("GET / HTTP/1.1\r\n{}Range: {}\r\n", host, ranges))},
      {"nul-path", raw(fmt::format("GET /app.js%00.html HTTP/1.1\r\n{}", host))},
      {"bad-json", raw(fmt::format("POST {} HTTP/1.1\r\n{}Content-Type: application/json\r\n"
                                   "Content-Length: 11\r\n",
                                   path, host),
                       "{\"camera\": [")},
      {"jpeg-bomb", raw(fmt::format("POST {} HTTP/1.1\r\n{}Content-Type: multipart/form-data; "
                                    "boundary=B\r\nContent-Length: {}\r\n",
                                    path, host, form.size()),
                        form)},
      {"garbage", std::string("\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03 \r\n\r\n", 17)},
      {"wrong-method", raw(fmt::format("PUT {} HTTP/1.1\r\n{}", path, host))},
      {"long-uri", raw(fmt::format("GET /{} HTTP/1.1\r\n{}", std::string(100000, 'a'), host))},
      {"many-keys", raw(fmt::format("POST {} HTTP/1.1\r\n{}Content-Type: application/json\r\n"
                                    "Content-Length: {}\r\n",
                                    path, host, many_keys.size()),
                        many_keys)},
      {"get-with-body",
       raw(fmt::format("GET /healthz HTTP/1.1\r\n{}Content-Length: 4096\r\n", host),
           std::string(4096, 'x'))},
      {"implausible", raw(fmt::format("POST {} HTTP/1.1\r\n{}Content-Type: application/json\r\n"
                                      "Content-Length: {}\r\n",
                                      path, host, implausible.size()),
                          implausible)},
  };
}

struct Soak {
  std::map<std::string, std::map<int, int>> statuses;  // kind -> status -> count
  int requests = 0;
};

// `dribblers` sockets sending a header line a second (half of them a
// `GET /healthz` that announced a 16 MB body, a byte a second of it), and
// `attackers` threads cycling through HostileRequests, until `stop`.
void Attack(int port, const std::string& path, int attackers, int dribblers,
            const std::atomic<bool>& stop, Soak* soak) {
  const auto requests = HostileRequests(path);
  std::mutex mutex;
  std::vector<std::thread> threads;
  for (int a = 0; a < attackers; ++a) {
    threads.emplace_back([&, a] {
      for (size_t i = static_cast<size_t>(a); !stop; ++i) {
        const auto& [kind, bytes] = requests[i % requests.size()];
        const RawAnswer r = RawExchange(port, bytes, 5);
        std::lock_guard<std::mutex> lock(mutex);
        ++soak->statuses[kind][r.status];
        ++soak->requests;
      }
    });
  }
  threads.emplace_back([&] {
    std::vector<int> sockets;
    for (int d = 0; d < dribblers; ++d) {
      const int fd = ConnectLoopback(port, 5);
      const std::string start = d % 2 == 0 ? "GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                                           : "GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                                             "Content-Length: 16777216\r\n\r\n";
      if (fd >= 0 && ::send(fd, start.data(), start.size(), MSG_NOSIGNAL) > 0)
        sockets.push_back(fd);
    }
    for (int round = 0; !stop; ++round) {
      const std::string line = fmt::format("X-Slow-{}: y\r\n", round);
      for (size_t k = 0; k < sockets.size(); ++k) {
        if (k % 2 == 0) {
          ::send(sockets[k], line.data(), line.size(), MSG_NOSIGNAL);
        } else {
          ::send(sockets[k], "x", 1, MSG_NOSIGNAL);
        }
      }
      for (int i = 0; i < 10 && !stop; ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    for (const int fd : sockets) ::close(fd);
  });
  for (std::thread& t : threads) t.join();
}

// One keep-alive client's feature requests, one after another, for `seconds`.
Level Sequential(int port, double seconds, const std::string& path, const std::string& body) {
  return Drive(port, 1, 1000000, seconds, [&](httplib::Client& client) {
    return client.Post(path.c_str(), body, "application/json");
  });
}

AttackSoak AttackOf(int port, const LoadOptions& o, const std::string& path,
                    const std::string& features) {
  const Level alone = Sequential(port, o.attack_seconds, path, features);
  const size_t before = ResidentBytes();
  std::atomic<bool> stop = false;
  Soak soak;
  std::thread attack([&] { Attack(port, path, o.attackers, o.dribblers, stop, &soak); });
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // the attack under way
  const Level attacked = Sequential(port, o.attack_seconds, path, features);
  stop = true;
  attack.join();
  AttackSoak a;
  a.rss_after_mb = ResidentBytes() / 1e6;
  a.rss_before_mb = before / 1e6;
  a.seconds = o.attack_seconds;
  a.attackers = o.attackers;
  a.dribblers = o.dribblers;
  a.alone = LevelOf("features", 1, alone);
  a.under_attack = LevelOf("features", 1, attacked);
  a.p99_ratio = a.alone.p99_ms > 0 ? a.under_attack.p99_ms / a.alone.p99_ms : 0.0;
  a.hostile_requests = static_cast<size_t>(soak.requests);
  a.hostile_statuses = soak.statuses;
  return a;
}

}  // namespace

namespace {

// One photo's {camera, keypoints, descriptors}.
json FeaturesJson(const std::string& photo, const std::string& camera_text, SiftExtractor extractor,
                  int max_features) {
  const Camera camera = ParseCameraString(camera_text);
  SiftOptions sift;
  sift.extractor = extractor;
  sift.max_num_features = max_features;
  const SiftFeatures f = ExtractSift(
      ReadGreyImage(photo, {.expected_width = camera.width, .expected_height = camera.height}),
      sift);
  json kp = json::array();
  for (const SiftKeypoint& k : f.keypoints) kp.push_back({k.x, k.y});
  return json{{"camera", CameraToJson(camera)},
              {"keypoints", kp},
              {"descriptors", Base64Encode(f.descriptors)}};
}

// The multipart parts of a rig request: image[k], one camera, cam_from_rig[k] and the rig's fields.
httplib::MultipartFormDataItems RigParts(const std::vector<std::string>& photos,
                                         const std::string& camera, const RigFile& rig) {
  httplib::MultipartFormDataItems parts = {{"camera", camera, "", ""}};
  for (size_t k = 0; k < photos.size(); ++k) {
    parts.push_back({fmt::format("image[{}]", k), photos[k], "photo.jpg", "image/jpeg"});
    const Rigid3d& p = rig.cam_from_rig[k];
    parts.push_back(
        {fmt::format("cam_from_rig[{}]", k), PoseToJson(p.rotation, p.translation).dump(), "", ""});
  }
  if (!rig.points_local.empty()) {
    parts.push_back({"points_local", LocalPointsToJson(rig.points_local).dump(), "", ""});
  }
  if (rig.scale_known)
    parts.push_back({"scale_known", *rig.scale_known ? "true" : "false", "", ""});
  if (rig.gravity) {
    parts.push_back({"gravity",
                     fmt::format("{},{},{}", rig.gravity->x(), rig.gravity->y(), rig.gravity->z()),
                     "", ""});
  }
  return parts;
}

}  // namespace

std::string ClientFeaturesJson(const std::string& photo, const std::string& camera_text,
                               SiftExtractor extractor, int max_features) {
  return FeaturesJson(photo, camera_text, extractor, max_features).dump();
}

std::string ClientRigJson(const std::vector<std::string>& photos,
                          const std::vector<std::string>& cameras, const RigFile& rig,
                          SiftExtractor extractor, int max_features) {
  if (cameras.size() != 1 && cameras.size() != photos.size()) {
    Fail("{} photos but {} cameras (give one for all, or one per photo)", photos.size(),
         cameras.size());
  }
  if (rig.cam_from_rig.size() != photos.size()) {
    Fail("{} photos but {} cam_from_rig poses in the rig", photos.size(), rig.cam_from_rig.size());
  }
  json body = {{"frames", json::array()}};
  for (size_t k = 0; k < photos.size(); ++k) {
    json frame =
        FeaturesJson(photos[k], cameras[cameras.size() == 1 ? 0 : k], extractor, max_features);
    const Rigid3d& p = rig.cam_from_rig[k];
    frame["cam_from_rig"] = PoseToJson(p.rotation, p.translation);
    body["frames"].push_back(std::move(frame));
  }
  if (!rig.points_local.empty()) body["points_local"] = LocalPointsToJson(rig.points_local);
  if (rig.scale_known) body["scale_known"] = *rig.scale_known;
  if (rig.gravity) body["gravity"] = {rig.gravity->x(), rig.gravity->y(), rig.gravity->z()};
  return body.dump();
}

void LoadOptions::Check() const {
  if (map_id.empty() || photo.empty() || camera.empty()) {
    Fail("bench serve: --map, --photo and --camera are required");
  }
  if (requests < 1 || requests > 100000) Fail("bench serve: --requests must be 1-100000");
  if (!(attack_seconds >= 0 && attack_seconds <= 3600)) {
    Fail("bench serve: --attack-seconds must be in [0, 3600]");
  }
  if (attackers < 1 || attackers > 64 || dribblers < 0 || dribblers > 900) {
    Fail("bench serve: --attackers 1-64 and --dribblers 0-900");
  }
  for (const int c : concurrency) {
    if (c < 1 || c > 256) Fail("bench serve: concurrency {} out of range [1, 256]", c);
  }
  if (rig.empty() != rig_photos.empty()) {
    Fail("bench serve: --rig and --rig-photo go together (the frames' poses and photos)");
  }
}

// Levels of rig requests: the frames' client features (JSON), then their photos (multipart).
void RigLevels(int port, const LoadOptions& o, const std::string& path, LoadReport* report) {
  const RigFile rig = ReadRigJson(o.rig);
  const std::string features =
      ClientRigJson(o.rig_photos, {o.camera}, rig, SiftOptions{}.extractor, o.max_features);
  std::vector<std::string> photos;
  for (const std::string& p : o.rig_photos) photos.push_back(ReadFileToString(p));
  const httplib::MultipartFormDataItems parts = RigParts(photos, o.camera, rig);
  report->rig_frames = photos.size();
  for (const bool as_photos : {false, true}) {
    if (as_photos && !o.photos) continue;
    for (const int c : o.concurrency) {
      const Level l = Drive(port, c, o.requests, o.max_seconds, [&](httplib::Client& client) {
        return as_photos ? client.Post(path.c_str(), parts)
                         : client.Post(path.c_str(), features, "application/json");
      });
      report->levels.push_back(LevelOf(
          fmt::format("rig of {} {}", photos.size(), as_photos ? "photos" : "features"), c, l));
    }
  }
}

LoadReport RunLoad(const LoadOptions& o) {
  o.Check();
  if (sodium_init() < 0) Fail("libsodium could not be initialised");
  ServeOptions so = o.serve;
  so.listen = "127.0.0.1:0";
  so.log = [](const std::string&) {};  // the access log is not measured here
  Server server(so);
  const int port = server.Bind();
  std::thread runner([&] { server.Run(); });
  const std::string features =
      ClientFeaturesJson(o.photo, o.camera, SiftOptions{}.extractor, o.max_features);
  const size_t num_features = json::parse(features)["keypoints"].size();
  const std::string photo = ReadFileToString(o.photo);
  const std::string path = "/v1/maps/" + o.map_id + "/localize";
  LoadReport report;
  report.map = o.map_id;
  report.client_features = num_features;
  report.workers = so.threads;
  report.queue = so.queue;
  report.hardware_threads = std::thread::hardware_concurrency();
  try {
    for (const bool photos : {false, true}) {
      if (photos && !o.photos) continue;
      for (const int c : o.concurrency) {
        const Level l = Drive(port, c, o.requests, o.max_seconds, [&](httplib::Client& client) {
          if (!photos) return client.Post(path.c_str(), features, "application/json");
          return client.Post(path.c_str(), httplib::MultipartFormDataItems{
                                               {"image", photo, "photo.jpg", "image/jpeg"},
                                               {"camera", o.camera, "", ""}});
        });
        report.levels.push_back(LevelOf(photos ? "photo" : "features", c, l));
      }
    }
    if (!o.rig.empty()) RigLevels(port, o, path, &report);
    if (o.leak_requests > 0) {
      const size_t before = ResidentBytes();
      const Level l =
          Drive(port, 2, o.leak_requests, 10 * o.max_seconds, [&](httplib::Client& client) {
            return client.Post(path.c_str(), features, "application/json");
          });
      const size_t after = ResidentBytes();
      report.leak_check = LeakCheck{l.ms.size(), before / 1e6, after / 1e6, l.statuses};
    }
    if (o.attack_seconds > 0) report.attack = AttackOf(port, o, path, features);
  } catch (...) {
    server.Stop();
    runner.join();
    throw;
  }
  server.Stop();
  runner.join();
  return report;
}

}  // namespace linecloud
