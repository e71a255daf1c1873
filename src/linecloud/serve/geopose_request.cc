#include "linecloud/serve/geopose_request.h"

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <string>
#include <string_view>

#include <fmt/format.h>

#include "linecloud/io/json_util.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using json = nlohmann::json;

std::string Path(const std::string& where, std::string_view key) {
  return where.empty() ? std::string(key) : where + "." + std::string(key);
}

// `key` is in `j` and not null: OSCP's optional fields may be left out or, as its reference C++
// client writes an empty optional, null.
bool Has(const json& j, const char* key) { return j.contains(key) && !j[key].is_null(); }

// `j` is an object whose fields are among `known`.
void Only(const json& j, const std::string& where, std::initializer_list<std::string_view> known) {
  if (!j.is_object()) Fail("{}: {} is not an object", where, ShownInMessage(j));
  RefuseUnknownFields(j, known, where);
}

enum class Type { kString, kNumber, kBool, kArray, kObject, kStrings, kNumbers };

// Each of `keys` present in `j` has type `type`.
void Typed(const json& j, const std::string& where, Type type,
           std::initializer_list<const char*> keys) {
  static constexpr const char* kNames[] = {"a string",           "a number",  "true or false",
                                           "an array",           "an object", "an array of strings",
                                           "an array of numbers"};
  const auto all_of = [](const json& a, bool (json::*is)() const noexcept) {
    return a.is_array() &&
           std::all_of(a.begin(), a.end(), [&](const json& x) { return (x.*is)(); });
  };
  for (const char* key : keys) {
    if (!Has(j, key)) continue;
    const json& v = j[key];
    const bool ok = type == Type::kString    ? v.is_string()
                    : type == Type::kNumber  ? v.is_number()
                    : type == Type::kBool    ? v.is_boolean()
                    : type == Type::kArray   ? v.is_array()
                    : type == Type::kObject  ? v.is_object()
                    : type == Type::kStrings ? all_of(v, &json::is_string)
                                             : all_of(v, &json::is_number);
    if (!ok) {
      Fail("{}: {} is not {}", Path(where, key), ShownInMessage(v), kNames[static_cast<int>(type)]);
    }
  }
}

// Calls `check(element, "where[k]")` for each element of the array `j[key]`, if present.
template <typename Check>
void EachOf(const json& j, const std::string& where, const char* key, Check check) {
  if (!Has(j, key)) return;
  Typed(j, where, Type::kArray, {key});
  const json& a = j[key];
  for (size_t k = 0; k < a.size(); ++k) check(a[k], fmt::format("{}[{}]", Path(where, key), k));
}

void CheckPrivacy(const json& reading, const std::string& where) {
  if (!Has(reading, "privacy")) return;
  const std::string at = Path(where, "privacy");
  Only(reading["privacy"], at,
       {"dataRetention", "dataAcceptableUse", "dataSanitizationApplied",
        "dataSanitizationRequested"});
  Typed(reading["privacy"], at, Type::kStrings,
        {"dataRetention", "dataAcceptableUse", "dataSanitizationApplied",
         "dataSanitizationRequested"});
}

// A reading the server does not use: its fields as the protocol names them.
// Its fields are numbers but for the text ones (`strings`).
void CheckOtherReading(const json& r, const std::string& where,
                       std::initializer_list<std::string_view> fields,
                       std::initializer_list<std::string_view> strings = {}) {
  Only(r, where, fields);
  Typed(r, where, Type::kNumber, {"timestamp"});
  Typed(r, where, Type::kString, {"sensorId"});
  CheckPrivacy(r, where);
  for (const std::string_view field : fields) {
    const std::string key(field);
    // null too: a browser's Geolocation API gives null heading and speed when standing still.
    if (key == "timestamp" || key == "sensorId" || key == "privacy") continue;
    const bool text = std::find(strings.begin(), strings.end(), field) != strings.end();
    Typed(r, where, text ? Type::kString : Type::kNumber, {key.c_str()});
  }
}

void CheckCameraReading(const json& r, const std::string& where) {
  Only(r, where,
       {"timestamp", "sensorId", "privacy", "sequenceNumber", "imageFormat", "size", "imageBytes",
        "imageOrientation", "params"});
  // number, as OSCP types them: its Python client sends time.time() * 1000 (1795907585315.311).
  Typed(r, where, Type::kNumber, {"timestamp", "sequenceNumber"});
  Typed(r, where, Type::kString, {"sensorId", "imageFormat", "imageBytes"});
  Typed(r, where, Type::kNumbers, {"size"});
  Typed(r, where, Type::kObject, {"params"});
  if (Has(r, "params")) {
    // A distortion or size given here would be dropped: refused, like a camera's other fields
    // (minMaxDepth and minMaxDisparity are OSCP's, accepted and not used).
    RefuseUnknownFields(r["params"], {"model", "modelParams", "minMaxDepth", "minMaxDisparity"},
                        Path(where, "params"));
    Typed(r["params"], Path(where, "params"), Type::kString, {"model"});
    Typed(r["params"], Path(where, "params"), Type::kNumbers,
          {"modelParams", "minMaxDepth", "minMaxDisparity"});
  }
  CheckPrivacy(r, where);
  if (Has(r, "imageOrientation")) {
    const json& o = r["imageOrientation"];
    const std::string at = Path(where, "imageOrientation");
    Only(o, at, {"mirrored", "rotation"});
    Typed(o, at, Type::kBool, {"mirrored"});
    Typed(o, at, Type::kNumber, {"rotation"});
    if ((Has(o, "mirrored") && o["mirrored"].get<bool>()) ||
        (Has(o, "rotation") && std::fmod(o["rotation"].get<double>(), 360.0) != 0)) {
      Fail(
          "{}: {} is not applied by this server; send the photo upright (rotation 0, not "
          "mirrored)",
          at, ShownInMessage(o));
    }
  }
}

void CheckSensor(const json& s, const std::string& where) {
  Only(s, where, {"id", "name", "model", "rigIdentifier", "rigRotation", "rigTranslation", "type"});
  Typed(s, where, Type::kString, {"id", "name", "model", "rigIdentifier", "type"});
  if (Has(s, "rigRotation")) {
    Only(s["rigRotation"], Path(where, "rigRotation"), {"x", "y", "z", "w"});
    Typed(s["rigRotation"], Path(where, "rigRotation"), Type::kNumber, {"x", "y", "z", "w"});
  }
  if (Has(s, "rigTranslation")) {
    Only(s["rigTranslation"], Path(where, "rigTranslation"), {"x", "y", "z"});
    Typed(s["rigTranslation"], Path(where, "rigTranslation"), Type::kNumber, {"x", "y", "z"});
  }
}

// A prior pose: a GeoPoseResp (v2's priorPoses) or a bare GeoPose. Not used by this server.
void CheckPriorPose(const json& p, const std::string& where) {
  Only(p, where, {"id", "timestamp", "type", "accuracy", "geopose", "position", "quaternion"});
  Typed(p, where, Type::kString, {"id", "type"});
  Typed(p, where, Type::kNumber, {"timestamp"});
  const auto check_geopose = [](const json& g, const std::string& at) {
    if (Has(g, "position")) {
      Only(g["position"], Path(at, "position"), {"lat", "lon", "h"});
      Typed(g["position"], Path(at, "position"), Type::kNumber, {"lat", "lon", "h"});
    }
    if (Has(g, "quaternion")) {
      Only(g["quaternion"], Path(at, "quaternion"), {"x", "y", "z", "w"});
      Typed(g["quaternion"], Path(at, "quaternion"), Type::kNumber, {"x", "y", "z", "w"});
    }
  };
  check_geopose(p, where);
  if (Has(p, "geopose")) {
    Only(p["geopose"], Path(where, "geopose"), {"position", "quaternion"});
    check_geopose(p["geopose"], Path(where, "geopose"));
  }
  if (Has(p, "accuracy")) {
    Only(p["accuracy"], Path(where, "accuracy"), {"position", "orientation"});
    Typed(p["accuracy"], Path(where, "accuracy"), Type::kNumber, {"position", "orientation"});
  }
}

}  // namespace

const json& CheckGeoPoseReq(const json& j) {
  if (!j.is_object()) Fail("the body is not a JSON object");
  Only(j, "", {"id", "timestamp", "type", "sensors", "sensorReadings", "priorPoses", "priorPose"});
  Typed(j, "", Type::kString, {"id", "type"});
  Typed(j, "", Type::kNumber, {"timestamp"});
  EachOf(j, "", "sensors", CheckSensor);
  EachOf(j, "", "priorPoses", CheckPriorPose);
  if (Has(j, "priorPose")) CheckPriorPose(j["priorPose"], "priorPose");
  if (!Has(j, "sensorReadings")) Fail("sensorReadings.cameraReadings[0] is missing");
  const json& readings = j["sensorReadings"];
  Only(readings, "sensorReadings",
       {"cameraReadings", "geolocationReadings", "wiFiReadings", "wifiReadings",
        "bluetoothReadings", "accelerometerReadings", "gyroscopeReadings", "magnetometerReadings"});
  EachOf(readings, "sensorReadings", "cameraReadings", CheckCameraReading);
  EachOf(readings, "sensorReadings", "geolocationReadings",
         [](const json& r, const std::string& w) {
           CheckOtherReading(r, w,
                             {"timestamp", "sensorId", "privacy", "latitude", "longitude",
                              "altitude", "accuracy", "altitudeAccuracy", "heading", "speed"});
         });
  // wiFiReadings in the protocol's text, wifiReadings in both its reference clients.
  for (const char* wifi : {"wiFiReadings", "wifiReadings"}) {
    EachOf(readings, "sensorReadings", wifi, [](const json& r, const std::string& w) {
      CheckOtherReading(r, w,
                        {"timestamp", "sensorId", "privacy", "BSSID", "frequency", "RSSI", "SSID",
                         "scanTimeStart", "scanTimeEnd"},
                        {"BSSID", "SSID"});
    });
  }
  EachOf(readings, "sensorReadings", "bluetoothReadings", [](const json& r, const std::string& w) {
    CheckOtherReading(r, w, {"timestamp", "sensorId", "privacy", "address", "RSSI", "name"},
                      {"address", "name"});
  });
  for (const char* motion :
       {"accelerometerReadings", "gyroscopeReadings", "magnetometerReadings"}) {
    EachOf(readings, "sensorReadings", motion, [](const json& r, const std::string& w) {
      CheckOtherReading(r, w, {"timestamp", "sensorId", "privacy", "x", "y", "z"});
    });
  }
  if (!Has(readings, "cameraReadings") || readings["cameraReadings"].empty())
    Fail("sensorReadings.cameraReadings[0] is missing");
  const json& cameras = readings["cameraReadings"];
  if (cameras.size() > 1) {
    Fail(
        "sensorReadings.cameraReadings: {} readings; this server localizes one photo a request "
        "(send them one at a time)",
        cameras.size());
  }
  return cameras[0];
}

}  // namespace linecloud
