// Geo-anchored maps for the OSCP GeoPose protocol (`POST /geopose`): a map's
// optional ID.json places its frame on the Earth — an anchor (WGS84 latitude,
// longitude, ellipsoidal height) and enu_from_map, a similarity into the local
// east-north-up frame at the anchor (metres). A camera pose in the map frame
// becomes an OGC GeoPose Basic-Quaternion: the camera centre in WGS84 and the
// camera's orientation (camera axes, COLMAP's x right, y down, z forward) in
// the ENU frame at the anchor.
#pragma once

#include <string>

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "linecloud/geometry/rigid3.h"

namespace linecloud {

struct GeoAnchor {
  double lat_deg = 0, lon_deg = 0, h_m = 0;
  Sim3d enu_from_map;
};

// {"geo_anchor": {"lat", "lon", "h", "enu_from_map": {"q", "t", "scale"}}};
// throws Error naming `source` and the field.
GeoAnchor GeoAnchorFromJson(const nlohmann::json& j, const std::string& source);
// The inverse: {"geo_anchor": {...}} as GeoAnchorFromJson reads it.
nlohmann::ordered_json GeoAnchorToJson(const GeoAnchor& anchor);

struct GeoPose {
  double lat_deg = 0, lon_deg = 0, h_m = 0;
  Eigen::Quaterniond enu_from_camera = Eigen::Quaterniond::Identity();
};

GeoPose GeoPoseOfCamera(const GeoAnchor& anchor, const Rigid3d& cam_from_world);

// WGS84 geodetic (degrees, metres) to Earth-centred Earth-fixed and back.
Eigen::Vector3d EcefFromGeodetic(double lat_deg, double lon_deg, double h_m);
Eigen::Vector3d GeodeticFromEcef(const Eigen::Vector3d& ecef);  // (lat, lon, h)

// A geodetic position in the east-north-up frame at (lat0, lon0, h0), metres.
Eigen::Vector3d EnuFromGeodetic(double lat0_deg, double lon0_deg, double h0_m, double lat_deg,
                                double lon_deg, double h_m);

// The map-frame point at a geodetic position (the inverse of the position
// part of GeoPoseOfCamera).
Eigen::Vector3d MapPointFromGeodetic(const GeoAnchor& anchor, double lat_deg, double lon_deg,
                                     double h_m);

}  // namespace linecloud
