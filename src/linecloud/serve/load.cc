#include "linecloud/serve/load.h"

#include <sodium.h>

#include <atomic>
#include <chrono>
#include <map>
#include <mutex>
#include <thread>

#include <fmt/format.h>

#include "linecloud/features/image.h"
#include "linecloud/features/sift.h"
#include "linecloud/localize/image_query.h"
#include "linecloud/util/error.h"
#include "linecloud/util/base64.h"
#include "linecloud/util/file.h"
#include "linecloud/util/memory.h"
#include "linecloud/util/statistics.h"

#include <httplib.h>
#undef _res

namespace linecloud {
namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

struct Level {
  std::vector<double> ms;
  std::map<int, int> statuses;  // 0: no answer
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
      }
    });
  }
  for (std::thread& t : threads) t.join();
  level.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return level;
}

json LevelJson(const std::string& kind, int clients, const Level& l) {
  json statuses = json::object();
  for (const auto& [s, n] : l.statuses) statuses[std::to_string(s)] = n;
  return {{"body", kind},
          {"concurrency", clients},
          {"requests", l.ms.size()},
          {"per_second", l.seconds > 0 ? l.ms.size() / l.seconds : 0.0},
          {"p50_ms", Percentile(l.ms, 50)},
          {"p99_ms", Percentile(l.ms, 99)},
          {"statuses", statuses}};
}

}  // namespace

std::string ClientFeaturesJson(const std::string& photo, const std::string& camera_text,
                               SiftExtractor extractor, int max_features) {
  const Camera camera = ParseCameraString(camera_text);
  SiftOptions sift;
  sift.extractor = extractor;
  sift.max_num_features = max_features;
  const SiftFeatures f = ExtractSift(
      ReadGreyImage(photo, {.expected_width = camera.width, .expected_height = camera.height}),
      sift);
  json kp = json::array();
  for (const SiftKeypoint& k : f.keypoints) kp.push_back({k.x, k.y});
  return json{{"camera",
               {{"model", std::string(CameraModelName(camera.model_id))},
                {"width", camera.width},
                {"height", camera.height},
                {"params", camera.params}}},
              {"keypoints", kp},
              {"descriptors", Base64Encode(f.descriptors)}}
      .dump();
}

void LoadOptions::Check() const {
  if (map_id.empty() || photo.empty() || camera.empty()) {
    Fail("bench serve: --map, --photo and --camera are required");
  }
  if (requests < 1 || requests > 100000) Fail("bench serve: --requests must be 1-100000");
  for (const int c : concurrency) {
    if (c < 1 || c > 256) Fail("bench serve: concurrency {} out of range [1, 256]", c);
  }
}

json RunLoad(const LoadOptions& o) {
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
  json report = {{"map", o.map_id},
                 {"client_features", num_features},
                 {"workers", so.threads},
                 {"queue", so.queue},
                 {"hardware_threads", std::thread::hardware_concurrency()},
                 {"levels", json::array()}};
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
        report["levels"].push_back(LevelJson(photos ? "photo" : "features", c, l));
      }
    }
    if (o.leak_requests > 0) {
      const size_t before = ResidentBytes();
      const Level l =
          Drive(port, 2, o.leak_requests, 10 * o.max_seconds, [&](httplib::Client& client) {
            return client.Post(path.c_str(), features, "application/json");
          });
      const size_t after = ResidentBytes();
      report["leak_check"] = {{"requests", l.ms.size()},
                              {"rss_before_mb", before / 1e6},
                              {"rss_after_mb", after / 1e6},
                              {"statuses", LevelJson("features", 2, l)["statuses"]}};
    }
  } catch (...) {
    server.Stop();
    runner.join();
    throw;
  }
  server.Stop();
  runner.join();
  return report;
}

std::string LoadMarkdown(const json& r) {
  std::string md = fmt::format(
      "bench serve: map {}, {} client features a request, {} workers, queue {}, {} hardware "
      "threads; client and server on 127.0.0.1\n\n| body | concurrency | requests | req/s | p50 ms "
      "| p99 ms | statuses |\n"
      "|---|---|---|---|---|---|---|\n",
      r["map"].get<std::string>(), r["client_features"].get<size_t>(), r["workers"].get<int>(),
      r["queue"].get<int>(), r["hardware_threads"].get<unsigned>());
  for (const json& l : r["levels"]) {
    md += fmt::format("| {} | {} | {} | {:.1f} | {:.0f} | {:.0f} | {} |\n",
                      l["body"].get<std::string>(), l["concurrency"].get<int>(),
                      l["requests"].get<size_t>(), l["per_second"].get<double>(),
                      l["p50_ms"].get<double>(), l["p99_ms"].get<double>(), l["statuses"].dump());
  }
  if (r.contains("leak_check")) {
    const json& k = r["leak_check"];
    md += fmt::format(
        "\n{} more feature requests: resident memory {:.1f} MB before, {:.1f} MB "
        "after; statuses {}\n",
        k["requests"].get<size_t>(), k["rss_before_mb"].get<double>(),
        k["rss_after_mb"].get<double>(), k["statuses"].dump());
  }
  return md;
}

}  // namespace linecloud
