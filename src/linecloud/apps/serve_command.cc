#include <pthread.h>
#include <signal.h>

#include <array>
#include <iostream>
#include <memory>
#include <thread>

#include "linecloud/apps/commands.h"
#include "linecloud/apps/localizer_flags.h"
#include "linecloud/serve/load.h"
#include "linecloud/serve/server.h"
#include "linecloud/serve/tokens.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

// Serves until SIGTERM / SIGINT (drain, exit 0); SIGHUP reloads the maps. The
// signals are blocked in every thread and taken by one waiting thread.
void RunServe(const ServeOptions& options) {
  sigset_t signals;
  sigemptyset(&signals);
  for (const int s : {SIGHUP, SIGTERM, SIGINT}) sigaddset(&signals, s);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  Server server(options);
  server.Bind();
  std::cerr << "loaded " << server.num_maps() << " map(s)\n"
            << "listening on " << server.url() << std::endl;
  std::thread waiter([&] {
    for (;;) {
      int s = 0;
      if (sigwait(&signals, &s) != 0) continue;
      if (s == SIGHUP) {
        server.Reload();
        std::cerr << "reloaded: " << server.num_maps() << " map(s)" << std::endl;
        continue;
      }
      server.Stop();
      return;
    }
  });
  server.Run();
  waiter.join();
  std::cerr << "stopped" << std::endl;
}

// `linecloud serve`: the HTTP service.
void RegisterServe(CLI::App& app) {
  auto o = std::make_shared<ServeOptions>();
  CLI::App* cmd = app.add_subcommand(
      "serve",
      "HTTP localization service over a folder of line clouds (DIR/ID.lcm): photos or client "
      "features in, poses out (docs/http_api.md)");
  cmd->add_option("--maps", o->maps_dir, "Folder of ID.lcm maps (+ optional ID.json geo-anchor)")
      ->required();
  cmd->add_option("--listen", o->listen, "HOST:PORT (port 0: a free one)")->capture_default_str();
  cmd->add_option("--tokens", o->tokens_path,
                  "TOKENS.json (SHA-256 of each bearer token, its maps and rate); required off "
                  "loopback");
  cmd->add_option("--threads", o->threads, "Localization workers")->capture_default_str();
  cmd->add_option("--web", o->web_dir,
                  "The console's files (default: web/ beside the executable, or the installed "
                  "share/linecloud/web)");
  cmd->add_option("--connections", o->connections,
                  "Connections open at once (more are closed when accepted)")
      ->capture_default_str();
  cmd->add_option("--connections-per-address", o->connections_per_address,
                  "Connections open at once from one address, loopback not counted (0: no limit)")
      ->capture_default_str();
  cmd->add_option("--queue", o->queue, "Requests waiting for a worker, at most (then 503)")
      ->capture_default_str();
  cmd->add_option("--max-body-mb", o->max_body_mb, "Largest request body (then 413)")
      ->capture_default_str();
  cmd->add_option("--body-budget-mb", o->body_budget_mb,
                  "Bodies of all requests being read or handled at once (then 503)")
      ->capture_default_str();
  cmd->add_option("--max-pixels", o->max_pixels,
                  "A request's photos together, from their headers before decoding (then 413)")
      ->capture_default_str();
  cmd->add_option("--max-frames", o->max_frames,
                  "A device's frames in one request, photos or feature sets (then 413)")
      ->capture_default_str();
  cmd->add_option("--memory-budget-mb", o->memory_budget_mb,
                  "SIFT's scale space of all requests together (a photo needing more alone: "
                  "413; others wait for room)")
      ->capture_default_str();
  cmd->add_option("--request-seconds", o->request_seconds,
                  "Deadline of a localization, queue wait included (then 504)")
      ->capture_default_str();
  // Every map's Localizer options (a map's DIR/ID.json "options" change them
  // for it); --threads and --max-pixels above are the server's own.
  auto flags = std::make_shared<LocalizerFlags>();
  constexpr OptionScope kAll[] = {OptionScope::kMap, OptionScope::kRequest};
  flags->Add(cmd, kAll, {"threads", "max_pixels"});
  cmd->callback([o, flags] {
    flags->Apply(&o->localizer);
    RunServe(*o);
  });
}

// `linecloud bench serve`: the load test (the bench command is registered first).
void RegisterBenchServe(CLI::App& app) {
  auto load = std::make_shared<LoadOptions>();
  auto load_json = std::make_shared<bool>(false);
  CLI::App* bench = app.get_subcommand("bench")->add_subcommand(
      "serve",
      "Load test of the service (in this process, 127.0.0.1): client features and photos at "
      "each concurrency; throughput, p50 / p99, statuses, memory over a run");
  bench->add_option("--maps", load->serve.maps_dir, "Folder of ID.lcm maps")->required();
  bench->add_option("--map", load->map_id, "The map id to localize against")->required();
  bench->add_option("--photo", load->photo, "A photo of the map's scene")->required();
  bench->add_option("--camera", load->camera, "Its camera, \"MODEL W H PARAMS...\"")->required();
  bench->add_option("--threads", load->serve.threads, "Server workers")->capture_default_str();
  bench->add_option("--queue", load->serve.queue, "Server queue")->capture_default_str();
  bench->add_option("--concurrency", load->concurrency, "Client connections per level")
      ->capture_default_str();
  bench->add_option("--requests", load->requests, "Requests per level and body")
      ->capture_default_str();
  bench->add_flag("!--no-photos", load->photos, "Client features only");
  bench->add_option("--rig", load->rig,
                    "Also rig requests: RIG.json (cam_from_rig, points_local, gravity) of the "
                    "--rig-photo frames");
  bench->add_option("--rig-photo", load->rig_photos, "A frame of the rig (repeat; with --rig)");
  bench
      ->add_option("--max-features", load->max_features,
                   "The client's SIFT budget (COLMAP's cap: whole levels from the coarsest)")
      ->capture_default_str();
  bench
      ->add_option("--leak-requests", load->leak_requests,
                   "Then this many more feature requests, memory before / after")
      ->capture_default_str();
  bench
      ->add_option("--attack-seconds", load->attack_seconds,
                   "Then one client alone and under attack (hostile requests, dribbling "
                   "sockets), this long each: p50 / p99 of both")
      ->capture_default_str();
  bench->add_option("--attackers", load->attackers, "Threads sending hostile requests")
      ->capture_default_str();
  bench->add_option("--dribblers", load->dribblers, "Sockets dribbling header lines")
      ->capture_default_str();
  bench->add_flag("--json", *load_json, "Print JSON");
  bench->callback([load, load_json] {
    const LoadReport r = RunLoad(*load);
    std::cout << (*load_json ? ToJson(r).dump(2) + "\n" : LoadMarkdown(r));
  });
}

// `linecloud features`: a client-features body, of one photo or a device's frames.
struct FeaturesArgs {
  std::vector<std::string> images, cameras;
  std::string rig, out;
  std::string extractor = SiftExtractorName(SiftOptions{}.extractor);
  int max_features = 8192;
};

void RegisterFeatures(CLI::App& app) {
  auto args = std::make_shared<FeaturesArgs>();
  CLI::App* fc = app.add_subcommand(
      "features",
      "A photo's SIFT features (or a device's frames', with --rig) as the JSON body of a "
      "client-features request to `serve`");
  fc->add_option("--image", args->images, "The photo (JPEG or PNG); repeat for a rig's frames")
      ->required();
  fc->add_option("--camera", args->cameras,
                 "\"MODEL W H PARAMS...\": one for every photo, or one per --image")
      ->required();
  fc->add_option("--rig", args->rig,
                 "Several frames: RIG.json (cam_from_rig, points_local, scale_known, gravity; "
                 "docs/formats.md), written into the body with the frames");
  fc->add_option("--features", args->extractor, "colmap (COLMAP's own features) or opencv")
      ->capture_default_str();
  fc->add_option("--out", args->out, "Output file")->required();
  fc->add_option("--max-features", args->max_features, "SIFT's cap (COLMAP's rule)")
      ->capture_default_str();
  fc->callback([args] {
    const SiftExtractor extractor = ParseSiftExtractor(args->extractor, "--features");
    std::vector<std::string> inputs = args->images;
    if (!args->rig.empty()) inputs.push_back(args->rig);
    RefuseOutputOverInputs(args->out, inputs, "--out");
    if (args->images.size() > 1 && args->rig.empty()) {
      Fail("{} photos need --rig RIG.json (their cam_from_rig poses)", args->images.size());
    }
    if (args->rig.empty() && args->cameras.size() != 1) {
      Fail("one photo takes one --camera, got {}", args->cameras.size());
    }
    const std::string body =
        args->rig.empty()
            ? ClientFeaturesJson(args->images[0], args->cameras[0], extractor, args->max_features)
            : ClientRigJson(args->images, args->cameras, ReadRigJson(args->rig), extractor,
                            args->max_features);
    WriteFileAtomically(args->out, [&](std::ostream& os) { os << body; });
  });
}

// `linecloud token-hash`: what TOKENS.json stores.
void RegisterTokenHash(CLI::App& app) {
  CLI::App* hash = app.add_subcommand(
      "token-hash", "The SHA-256 of a bearer token, as TOKENS.json stores it (read from stdin)");
  hash->callback([] {
    std::string t;
    std::getline(std::cin, t);
    std::cout << TokenSha256Hex(t) << "\n";
  });
}

}  // namespace

void RegisterServeCommand(CLI::App& app) {
  RegisterServe(app);
  RegisterBenchServe(app);
  RegisterFeatures(app);
  RegisterTokenHash(app);
}

}  // namespace linecloud
