#include "linecloud/synthetic/surfaces.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <random>

#include "linecloud/util/error.h"

namespace linecloud {
namespace {

// A surface patch sampled uniformly: area and a sampler of (u, v) ∈ [0, 1)².
struct Patch {
  double area;
  std::function<Eigen::Vector3d(double, double)> at;
};

Patch Rectangle(const Eigen::Vector3d& origin, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return {a.cross(b).norm(),
          [=](double u, double v) { return Eigen::Vector3d(origin + u * a + v * b); }};
}

// The visible faces of an axis-aligned block standing on the wall (z = 0).
void Block(const Eigen::Vector3d& min, const Eigen::Vector3d& max, std::vector<Patch>* patches) {
  const Eigen::Vector3d d = max - min;
  const Eigen::Vector3d ex(d.x(), 0, 0), ey(0, d.y(), 0), ez(0, 0, d.z());
  patches->push_back(Rectangle(Eigen::Vector3d(min.x(), min.y(), max.z()), ex, ey));  // front
  patches->push_back(Rectangle(min, ey, ez));                                         // left
  patches->push_back(Rectangle(Eigen::Vector3d(max.x(), min.y(), min.z()), ey, ez));  // right
  patches->push_back(Rectangle(Eigen::Vector3d(min.x(), max.y(), min.z()), ex, ez));  // top
  patches->push_back(Rectangle(min, ex, ez));                                         // bottom
}

// A half cylinder (column) of radius r on the wall, axis along y at x = cx.
Patch Column(double cx, double r, double y0, double y1) {
  return {std::numbers::pi * r * (y1 - y0), [=](double u, double v) {
            const double phi = std::numbers::pi * u;
            return Eigen::Vector3d(cx + r * std::cos(phi), y0 + v * (y1 - y0), r * std::sin(phi));
          }};
}

// A half sphere (dome) of radius r on the wall at (cx, cy); uniform by area
// (Archimedes: z = r·u is uniform on a sphere's zone).
Patch Dome(double cx, double cy, double r) {
  return {2 * std::numbers::pi * r * r, [=](double u, double v) {
            const double z = r * u, rho = std::sqrt(std::max(0.0, r * r - z * z));
            const double phi = 2 * std::numbers::pi * v;
            return Eigen::Vector3d(cx + rho * std::cos(phi), cy + rho * std::sin(phi), z);
          }};
}

}  // namespace

void FacadeOptions::Check() const {
  if (num_points < 1 || num_points > 50'000'000) Fail("facade: num_points must be in [1, 5e7]");
  if (!(texture_share >= 0 && texture_share <= 1)) Fail("facade: texture_share must be in [0, 1]");
  if (texture_spots < 1 || !(spot_sigma > 0 && spot_sigma < 1)) {
    Fail("facade: texture_spots must be >= 1 and spot_sigma in (0, 1)");
  }
  if (!(width >= 1 && width <= 1e4) || !(height >= 1 && height <= 1e4)) {
    Fail("facade: width and height must be in [1, 1e4] m");
  }
}

std::vector<Eigen::Vector3d> SampleFacade(const FacadeOptions& o) {
  o.Check();
  const double w = o.width, h = o.height;
  std::vector<Patch> patches;
  patches.push_back(
      Rectangle(Eigen::Vector3d::Zero(), Eigen::Vector3d(w, 0, 0), Eigen::Vector3d(0, h, 0)));
  // Ground in front of the wall.
  patches.push_back(
      Rectangle(Eigen::Vector3d::Zero(), Eigen::Vector3d(w, 0, 0), Eigen::Vector3d(0, 0, 0.3 * h)));
  // Window sills / blocks, a door frame, two columns and a dome (a fountain's basin).
  for (int i = 0; i < 4; ++i) {
    const double x = (0.1 + 0.22 * i) * w;
    Block({x, 0.62 * h, 0}, {x + 0.12 * w, 0.70 * h, 0.05 * h}, &patches);
  }
  Block({0.42 * w, 0, 0}, {0.58 * w, 0.05 * h, 0.25 * h}, &patches);
  patches.push_back(Column(0.2 * w, 0.03 * w, 0, 0.55 * h));
  patches.push_back(Column(0.8 * w, 0.03 * w, 0, 0.55 * h));
  patches.push_back(Dome(0.5 * w, 0.35 * h, 0.1 * h));

  double total = 0;
  for (const Patch& p : patches) total += p.area;
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::vector<Eigen::Vector3d> points;
  points.reserve(o.num_points);
  struct Spot {
    size_t patch;
    double u, v;
  };
  auto uniform_spot = [&] {
    double pick = uniform(rng) * total;
    size_t i = 0;
    while (i + 1 < patches.size() && pick >= patches[i].area) pick -= patches[i++].area;
    return Spot{i, uniform(rng), uniform(rng)};
  };
  std::vector<Spot> spots;
  for (int s = 0; s < o.texture_spots && o.texture_share > 0; ++s) spots.push_back(uniform_spot());
  std::normal_distribution<double> gauss(0.0, o.spot_sigma);
  std::uniform_int_distribution<size_t> spot_index(0, spots.empty() ? 0 : spots.size() - 1);
  for (int k = 0; k < o.num_points; ++k) {
    Spot p;
    if (!spots.empty() && uniform(rng) < o.texture_share) {
      p = spots[spot_index(rng)];
      p.u = std::clamp(p.u + gauss(rng), 0.0, 1.0);
      p.v = std::clamp(p.v + gauss(rng), 0.0, 1.0);
    } else {
      p = uniform_spot();
    }
    points.push_back(patches[p.patch].at(p.u, p.v));
  }
  return points;
}

}  // namespace linecloud
