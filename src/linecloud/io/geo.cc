#include "linecloud/io/geo.h"

#include <cmath>
#include <numbers>

#include "linecloud/io/json_util.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

constexpr double kA = 6378137.0;            // WGS84 semi-major axis, m
constexpr double kF = 1.0 / 298.257223563;  // flattening
constexpr double kE2 = kF * (2.0 - kF);     // first eccentricity squared
constexpr double kDeg = std::numbers::pi / 180.0;

// Rows: east, north, up at (lat, lon) in ECEF axes (enu_from_ecef rotation).
Eigen::Matrix3d EnuFromEcef(double lat_deg, double lon_deg) {
  const double sl = std::sin(lat_deg * kDeg), cl = std::cos(lat_deg * kDeg);
  const double so = std::sin(lon_deg * kDeg), co = std::cos(lon_deg * kDeg);
  Eigen::Matrix3d r;
  r << -so, co, 0, -sl * co, -sl * so, cl, cl * co, cl * so, sl;
  return r;
}

double Number(const nlohmann::json& j, const char* key, const std::string& where) {
  if (!j.contains(key) || !j[key].is_number() || !std::isfinite(j[key].get<double>())) {
    Fail("{}.{}: expected a finite number", where, key);
  }
  return j[key].get<double>();
}

}  // namespace

Eigen::Vector3d EcefFromGeodetic(double lat_deg, double lon_deg, double h_m) {
  const double sl = std::sin(lat_deg * kDeg), cl = std::cos(lat_deg * kDeg);
  const double n = kA / std::sqrt(1.0 - kE2 * sl * sl);
  return {(n + h_m) * cl * std::cos(lon_deg * kDeg), (n + h_m) * cl * std::sin(lon_deg * kDeg),
          (n * (1.0 - kE2) + h_m) * sl};
}

Eigen::Vector3d GeodeticFromEcef(const Eigen::Vector3d& x) {
  const double lon = std::atan2(x.y(), x.x());
  const double p = std::hypot(x.x(), x.y());
  // Fixed-point iteration on the latitude (converges to < 1e-12 rad in a few
  // steps anywhere near the surface).
  double lat = std::atan2(x.z(), p * (1.0 - kE2)), h = 0;
  for (int i = 0; i < 8; ++i) {
    const double sl = std::sin(lat);
    const double n = kA / std::sqrt(1.0 - kE2 * sl * sl);
    h = p / std::cos(lat) - n;
    lat = std::atan2(x.z(), p * (1.0 - kE2 * n / (n + h)));
  }
  return {lat / kDeg, lon / kDeg, h};
}

GeoAnchor GeoAnchorFromJson(const nlohmann::json& j, const std::string& source) {
  if (!j.is_object() || !j.contains("geo_anchor") || !j["geo_anchor"].is_object()) {
    Fail("{}: expected {{\"geo_anchor\": {{...}}}}", source);
  }
  const nlohmann::json& a = j["geo_anchor"];
  const std::string where = source + ": geo_anchor";
  GeoAnchor g;
  g.lat_deg = Number(a, "lat", where);
  g.lon_deg = Number(a, "lon", where);
  g.h_m = Number(a, "h", where);
  if (std::abs(g.lat_deg) > 90 || std::abs(g.lon_deg) > 180) {
    Fail("{}: lat {} / lon {} out of range", where, g.lat_deg, g.lon_deg);
  }
  if (!a.contains("enu_from_map") || !a["enu_from_map"].is_object()) {
    Fail("{}.enu_from_map: expected {{\"q\", \"t\", \"scale\"}}", where);
  }
  const nlohmann::json& p = a["enu_from_map"];
  const std::string pw = where + ".enu_from_map";
  // Another field (a misspelt "Q", a "center") would be ignored: refused, named.
  RefuseUnknownFields(p, {"q", "t", "scale"}, pw);
  auto vec = [&](const char* key, int n) {
    if (!p.contains(key)) Fail("{}.{}: missing", pw, key);
    if (!p[key].is_array() || p[key].size() != static_cast<size_t>(n)) {
      Fail("{}.{}: expected {} numbers", pw, key, n);
    }
    Eigen::VectorXd v(n);
    for (int i = 0; i < n; ++i) {
      if (!p[key][i].is_number() || !std::isfinite(p[key][i].get<double>())) {
        Fail("{}.{}[{}]: expected a finite number", pw, key, i);
      }
      v[i] = p[key][i].get<double>();
    }
    return v;
  };
  const Eigen::VectorXd q = vec("q", 4), t = vec("t", 3);
  if (!(q.norm() > 0.5)) Fail("{}.q: not a unit quaternion", pw);
  g.enu_from_map.rotation = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized();
  g.enu_from_map.translation = t;
  g.enu_from_map.scale = p.contains("scale") ? Number(p, "scale", pw) : 1.0;
  if (!(g.enu_from_map.scale > 0)) Fail("{}.scale: must be positive", pw);
  return g;
}

nlohmann::ordered_json GeoAnchorToJson(const GeoAnchor& a) {
  const Eigen::Quaterniond& q = a.enu_from_map.rotation;
  const Eigen::Vector3d& t = a.enu_from_map.translation;
  nlohmann::ordered_json enu_from_map = {{"q", {q.w(), q.x(), q.y(), q.z()}},
                                         {"t", {t.x(), t.y(), t.z()}},
                                         {"scale", a.enu_from_map.scale}};
  return {{"geo_anchor",
           {{"lat", a.lat_deg}, {"lon", a.lon_deg}, {"h", a.h_m}, {"enu_from_map", enu_from_map}}}};
}

Eigen::Vector3d EnuFromGeodetic(double lat0_deg, double lon0_deg, double h0_m, double lat_deg,
                                double lon_deg, double h_m) {
  const Eigen::Vector3d d =
      EcefFromGeodetic(lat_deg, lon_deg, h_m) - EcefFromGeodetic(lat0_deg, lon0_deg, h0_m);
  return EnuFromEcef(lat0_deg, lon0_deg) * d;
}

GeoPose GeoPoseOfCamera(const GeoAnchor& anchor, const Rigid3d& cam_from_world) {
  const Eigen::Vector3d centre_map = cam_from_world.Inverse().translation;
  const Eigen::Vector3d centre_enu = anchor.enu_from_map * centre_map;
  const Eigen::Matrix3d ecef_from_enu = EnuFromEcef(anchor.lat_deg, anchor.lon_deg).transpose();
  const Eigen::Vector3d ecef =
      EcefFromGeodetic(anchor.lat_deg, anchor.lon_deg, anchor.h_m) + ecef_from_enu * centre_enu;
  const Eigen::Vector3d geo = GeodeticFromEcef(ecef);
  GeoPose out;
  out.lat_deg = geo.x();
  out.lon_deg = geo.y();
  out.h_m = geo.z();
  out.enu_from_camera =
      (anchor.enu_from_map.rotation * cam_from_world.rotation.inverse()).normalized();
  return out;
}

Eigen::Vector3d MapPointFromGeodetic(const GeoAnchor& anchor, double lat_deg, double lon_deg,
                                     double h_m) {
  return anchor.enu_from_map.Inverse() *
         EnuFromGeodetic(anchor.lat_deg, anchor.lon_deg, anchor.h_m, lat_deg, lon_deg, h_m);
}

}  // namespace linecloud
