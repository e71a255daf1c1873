// `linecloud bench solvers`: every minimal solver (and the peers available in
// this build: OpenGV, Eigen's umeyama) on the same fixed-seed, noise-free
// random instances, single thread.
#pragma once

#include <nlohmann/json.hpp>

#include <functional>
#include <string>
#include <vector>

#include "linecloud/solvers/minimal_problem.h"

namespace linecloud {

struct SolverBenchOptions {
  uint64_t seed = 2019;
  int instances = 2000;              // distinct instances per method
  double min_seconds = 1.0;          // timing per solver
  std::vector<std::string> methods;  // empty: all implemented
  void Check() const;
};

struct SolverBenchRow {
  std::string method;
  std::string solver;          // "linecloud" or the peer's name
  double us_per_call = 0;      // ours: the solver on prepared inputs
  double api_us_per_call = 0;  // ours: through SolveMinimal (0 for peers)
  double mean_solutions = 0;
  double found_percent = 0;                // true pose among the solutions
  double median_log10_rotation_error = 0;  // best solution per instance
  int instances = 0;

  nlohmann::json ToJson() const;  // a row of `bench solvers --json`
};

// A peer: solves a method's instance, returning query_from_world poses.
struct PeerSolver {
  std::string method;
  std::string name;
  std::function<void(const MinimalSample&, std::vector<Sim3d>*)> solve;
  int correspondences = 0;  // > 0: needs this many (its own instances, same seed)
};

// OpenGV's solvers (opengv_peers.cc; empty when built without OpenGV).
std::vector<PeerSolver> OpenGvPeers();

// Peers compiled into this build (Eigen's umeyama always; OpenGV when found).
std::vector<PeerSolver> AvailablePeers();

std::vector<SolverBenchRow> RunSolverBench(const SolverBenchOptions& options,
                                           const std::function<void(const std::string&)>& progress);

// What `bench solvers` prints: the rows under the options that made them
// (bench_tables.cc).
struct SolverBenchReport {
  SolverBenchOptions options;
  std::vector<SolverBenchRow> rows;  // each method's own solver first, then its peers
};

nlohmann::json ToJson(const SolverBenchReport& report);  // {"seed", "rows"}
// The table: µs per call, solutions, % true, and ours / peer per peer row.
std::string SolverBenchMarkdown(const SolverBenchReport& report);

}  // namespace linecloud
