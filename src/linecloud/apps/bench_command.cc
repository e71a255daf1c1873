#include <iostream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "linecloud/apps/commands.h"
#include "linecloud/eval/solver_bench.h"

namespace linecloud {
namespace {

struct BenchArgs {
  SolverBenchOptions options;
  bool json = false;
};

void RunBenchSolvers(const BenchArgs& args) {
  const auto rows = RunSolverBench(args.options, [&](const std::string& what) {
    std::cerr << "bench: " << what << "\n";
  });
  if (args.json) {
    nlohmann::json j = nlohmann::json::array();
    for (const SolverBenchRow& r : rows) {
      j.push_back({{"method", r.method},
                   {"solver", r.solver},
                   {"us_per_call", r.us_per_call},
                   {"mean_solutions", r.mean_solutions},
                   {"found_percent", r.found_percent},
                   {"median_log10_rotation_error", r.median_log10_rotation_error},
                   {"instances", r.instances}});
    }
    std::cout << nlohmann::json{{"seed", args.options.seed}, {"rows", j}}.dump(2) << "\n";
    return;
  }
  std::cout << fmt::format(
      "fixed seed {}, {} noise-free instances per method, >= {:.1f} s timing each, one "
      "thread\n",
      args.options.seed, args.options.instances, args.options.min_seconds);
  std::cout << fmt::format("| {:<12} | {:<29} | {:>9} | {:>9} | {:>8} | {:>10} | {:>14} |\n",
                           "method", "solver", "µs/call", "solutions", "% true",
                           "med log10", "ours / peer");
  std::cout << "|--------------|-------------------------------|-----------|-----------|"
               "----------|------------|----------------|\n";
  double ours = 0;
  for (const SolverBenchRow& r : rows) {
    const bool mine = r.solver == "linecloud";
    if (mine) ours = r.us_per_call;
    std::cout << fmt::format(
        "| {:<12} | {:<29} | {:>9.3f} | {:>9.2f} | {:>8.2f} | {:>10.1f} | {:>14} |\n",
        mine ? r.method : "", r.solver, r.us_per_call, r.mean_solutions, r.found_percent,
        r.median_log10_rotation_error,
        mine ? std::string("") : fmt::format("{:.2f}x", ours / r.us_per_call));
  }
}

}  // namespace

void RegisterBenchCommand(CLI::App& app) {
  auto args = std::make_shared<BenchArgs>();
  CLI::App* bench = app.add_subcommand("bench", "Benchmarks");
  bench->require_subcommand(1);
  CLI::App* solvers = bench->add_subcommand(
      "solvers",
      "Every minimal solver (and its peers: OpenGV, Eigen) on fixed-seed noise-free "
      "instances: µs per call, solutions, % true pose found, median log10 rotation "
      "error");
  solvers->add_flag("--json", args->json, "Print JSON");
  solvers->add_option("--seed", args->options.seed, "Random seed")->capture_default_str();
  solvers->add_option("--instances", args->options.instances, "Instances per method")
      ->capture_default_str();
  solvers->add_option("--min-time", args->options.min_seconds,
                      "Seconds of timing per solver")
      ->capture_default_str();
  solvers->add_option("--methods", args->options.methods, "Only these methods")
      ->delimiter(',');
  solvers->callback([args] { RunBenchSolvers(*args); });
}

}  // namespace linecloud
