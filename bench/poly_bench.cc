// Real-root finders on the polynomials the degree-8 solvers (p4L+u, m-p4L+u,
// m-p3P, m-P3L+l+s) produce: 2000 fixed-seed degree-8 polynomials with four
// real roots and two complex pairs, roots ~N(0, 1), random scale. Sturm
// sequences (what the solvers use) against the companion-matrix eigenvalues
// (Eigen's EigenSolver, the textbook peer) and the monotone-interval finder.
#include <array>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "linecloud/solvers/polynomial.h"

namespace linecloud {
namespace {

using Degree8 = std::array<double, 9>;

const std::vector<Degree8>& Degree8Polynomials() {
  static const std::vector<Degree8> polynomials = [] {
    std::mt19937_64 rng(1);
    std::normal_distribution<double> g;
    std::vector<Degree8> out;
    for (int k = 0; k < 2000; ++k) {
      poly::Poly p = {g(rng)};
      for (int i = 0; i < 4; ++i) p = poly::Mul(p, {-g(rng), 1.0});
      for (int i = 0; i < 2; ++i) {
        const double re = g(rng), im = g(rng);
        p = poly::Mul(p, {re * re + im * im, -2 * re, 1.0});
      }
      Degree8 a;
      std::copy(p.begin(), p.end(), a.begin());
      out.push_back(a);
    }
    return out;
  }();
  return polynomials;
}

void BM_Degree8Sturm(benchmark::State& state) {
  const auto& polynomials = Degree8Polynomials();
  double roots[8];
  size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(poly::SturmRealRoots(polynomials[i].data(), 8, roots));
    benchmark::ClobberMemory();
    if (++i == polynomials.size()) i = 0;
  }
}
BENCHMARK(BM_Degree8Sturm);

// The vector-based finders, one polynomial per iteration.
void RunVectorFinder(benchmark::State& state,
                     void (*finder)(const poly::Poly&, std::vector<double>*)) {
  const auto& polynomials = Degree8Polynomials();
  std::vector<double> roots;
  roots.reserve(8);
  size_t i = 0;
  for (auto _ : state) {
    roots.clear();
    finder(poly::Poly(polynomials[i].begin(), polynomials[i].end()), &roots);
    benchmark::DoNotOptimize(roots.data());
    if (++i == polynomials.size()) i = 0;
  }
}

void BM_Degree8Monotone(benchmark::State& state) {
  RunVectorFinder(state, poly::MonotoneRealRoots);
}
BENCHMARK(BM_Degree8Monotone);

void BM_PeerDegree8Companion(benchmark::State& state) {
  RunVectorFinder(
      state, [](const poly::Poly& p, std::vector<double>* roots) { poly::RealRoots(p, roots); });
}
BENCHMARK(BM_PeerDegree8Companion);

}  // namespace
}  // namespace linecloud
