#include "linecloud/serve/geopose_request.h"

#include <gtest/gtest.h>

#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using json = nlohmann::json;

// A GeoPoseReq as OSCP v2's reference client sends it, with every optional part.
json FullRequest() {
  const json privacy = {{"dataRetention", json::array()},
                        {"dataAcceptableUse", json::array()},
                        {"dataSanitizationApplied", json::array()},
                        {"dataSanitizationRequested", json::array()}};
  return {{"id", "req-1"},
          {"timestamp", 1700000000000},
          {"type", "geopose"},
          {"sensors",
           {{{"id", "cam"}, {"type", "camera"}, {"name", "back"}},
            {{"id", "gps"},
             {"type", "geolocation"},
             {"rigRotation", {{"x", 0}, {"y", 0}, {"z", 0}, {"w", 1}}},
             {"rigTranslation", {{"x", 0}, {"y", 0}, {"z", 0}}}}}},
          {"sensorReadings",
           {{"cameraReadings",
             {{{"timestamp", 1700000000000},
               {"sensorId", "cam"},
               {"privacy", privacy},
               {"sequenceNumber", 3},
               {"imageFormat", "RGBA32"},
               {"size", {640, 480}},
               {"imageBytes", "AAAA"},
               {"imageOrientation", {{"mirrored", false}, {"rotation", 0}}},
               {"params", {{"model", "PINHOLE"}, {"modelParams", {500, 500, 320, 240}}}}}}},
            {"geolocationReadings",
             {{{"timestamp", 1}, {"sensorId", "gps"}, {"latitude", 48.8}, {"longitude", 2.3}}}},
            {"accelerometerReadings", {{{"x", 0}, {"y", 0}, {"z", 9.8}}}}}},
          {"priorPoses",
           {{{"id", "p"},
             {"type", "geopose"},
             {"accuracy", {{"position", 1}, {"orientation", 2}}},
             {"geopose",
              {{"position", {{"lat", 48.8}, {"lon", 2.3}, {"h", 30}}},
               {"quaternion", {{"x", 0}, {"y", 0}, {"z", 0}, {"w", 1}}}}}}}}};
}

std::string ErrorOf(const json& request) {
  try {
    CheckGeoPoseReq(request);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

std::string ErrorWith(const json::json_pointer& at, const json& value) {
  json j = FullRequest();
  j[at] = value;
  return ErrorOf(j);
}

TEST(GeoPoseReq, TheProtocolsFieldsAreAccepted) {
  const json j = FullRequest();
  EXPECT_EQ(&CheckGeoPoseReq(j), &j["sensorReadings"]["cameraReadings"][0]);
  json minimal = {{"sensorReadings", {{"cameraReadings", {{{"imageBytes", "AAAA"}}}}}}};
  EXPECT_EQ(ErrorOf(minimal), "");
}

// What the server would otherwise ignore, at every depth, is refused and named.
TEST(GeoPoseReq, FieldsTheProtocolDoesNotHaveAreNamed) {
  using P = json::json_pointer;
  EXPECT_EQ(ErrorWith(P("/sensorReadings/cameraReadings/0/imageOrientation/flip"), true),
            "sensorReadings.cameraReadings[0].imageOrientation: unknown field \"flip\" "
            "(mirrored, rotation)");
  EXPECT_EQ(ErrorWith(P("/sensorReadings/foo"), json::array()),
            "sensorReadings: unknown field \"foo\" (cameraReadings, geolocationReadings, "
            "wiFiReadings, wifiReadings, bluetoothReadings, accelerometerReadings, "
            "gyroscopeReadings, "
            "magnetometerReadings)");
  EXPECT_EQ(ErrorWith(P("/sensors/1/foo"), 1),
            "sensors[1]: unknown field \"foo\" (id, name, model, rigIdentifier, rigRotation, "
            "rigTranslation, type)");
  EXPECT_EQ(ErrorWith(P("/priorPoses/0/geopose/position/alt"), 1),
            "priorPoses[0].geopose.position: unknown field \"alt\" (lat, lon, h)");
  EXPECT_EQ(ErrorWith(P("/priorPose"), {{"scale", 1}}),
            "priorPose: unknown field \"scale\" (id, timestamp, type, accuracy, geopose, "
            "position, quaternion)");
  EXPECT_EQ(ErrorWith(P("/sensorReadings/cameraReadings/0/privacy/keep"), true),
            "sensorReadings.cameraReadings[0].privacy: unknown field \"keep\" (dataRetention, "
            "dataAcceptableUse, dataSanitizationApplied, dataSanitizationRequested)");
  EXPECT_EQ(ErrorWith(P("/sensorReadings/accelerometerReadings/0/w"), 1),
            "sensorReadings.accelerometerReadings[0]: unknown field \"w\" (timestamp, sensorId, "
            "privacy, x, y, z)");
  EXPECT_EQ(ErrorWith(P("/options"), {{"threshold", 2}}),
            "unknown field \"options\" (id, timestamp, type, sensors, sensorReadings, priorPoses, "
            "priorPose)");
}

TEST(GeoPoseReq, FieldsOfTheWrongTypeAreNamed) {
  using P = json::json_pointer;
  EXPECT_EQ(ErrorWith(P("/timestamp"), "x"), "timestamp: \"x\" is not a number");
  // OSCP types timestamps and sequence numbers `number`: its Python client sends
  // time.time() * 1000; its C++ client leaves optional values null.
  EXPECT_EQ(ErrorWith(P("/timestamp"), 1795907585315.311), "");
  EXPECT_EQ(ErrorWith(P("/sensorReadings/cameraReadings/0/sequenceNumber"), 2.5), "");
  EXPECT_EQ(ErrorWith(P("/sensorReadings/cameraReadings/0/params/minMaxDepth"), nullptr), "");
  EXPECT_EQ(ErrorWith(P("/sensorReadings/cameraReadings/0/privacy"), nullptr), "");
  EXPECT_EQ(ErrorWith(P("/priorPoses"), nullptr), "");
  EXPECT_EQ(ErrorWith(P("/sensorReadings/wifiReadings"),
                      {{{"timestamp", 1.5}, {"BSSID", "aa"}, {"RSSI", -40.5}}}),
            "");  // both reference clients' spelling of wiFiReadings
  EXPECT_EQ(ErrorWith(P("/sensorReadings/wifiReadings"), {{{"BSSID", 1}}}),
            "sensorReadings.wifiReadings[0].BSSID: 1 is not a string");
  EXPECT_EQ(ErrorWith(P("/sensorReadings/cameraReadings/0/privacy/dataRetention"), {1}),
            "sensorReadings.cameraReadings[0].privacy.dataRetention: [1] is not an array of "
            "strings");
  EXPECT_EQ(ErrorWith(P("/sensorReadings/cameraReadings/0/params/minMaxDepth"), "0,1"),
            "sensorReadings.cameraReadings[0].params.minMaxDepth: \"0,1\" is not an array of "
            "numbers");
  EXPECT_EQ(ErrorWith(P("/sensorReadings/cameraReadings/0/params/model"), 1),
            "sensorReadings.cameraReadings[0].params.model: 1 is not a string");
  EXPECT_EQ(ErrorWith(P("/sensorReadings/geolocationReadings/0/latitude"), "48"),
            "sensorReadings.geolocationReadings[0].latitude: \"48\" is not a number");
  EXPECT_EQ(ErrorWith(P("/sensorReadings/geolocationReadings/0/heading"), nullptr), "");
  EXPECT_EQ(ErrorWith(P("/sensorReadings/wiFiReadings"), {{{"BSSID", 1}}}),
            "sensorReadings.wiFiReadings[0].BSSID: 1 is not a string");
  EXPECT_EQ(ErrorWith(P("/id"), 5), "id: 5 is not a string");
  EXPECT_EQ(ErrorWith(P("/sensors"), {{"id", "cam"}}), "sensors: {\"id\":\"cam\"} is not an array");
  EXPECT_EQ(ErrorWith(P("/sensors/0"), "cam"), "sensors[0]: \"cam\" is not an object");
  EXPECT_EQ(ErrorWith(P("/sensorReadings/cameraReadings/0/imageOrientation/mirrored"), "no"),
            "sensorReadings.cameraReadings[0].imageOrientation.mirrored: \"no\" is not true or "
            "false");
  EXPECT_EQ(ErrorWith(P("/sensorReadings/cameraReadings/0/size"), "640x480"),
            "sensorReadings.cameraReadings[0].size: \"640x480\" is not an array of numbers");
  EXPECT_EQ(ErrorWith(P("/sensorReadings/cameraReadings"), {{"imageBytes", "AAAA"}}),
            "sensorReadings.cameraReadings: {\"imageBytes\":\"AAAA\"} is not an array");
}

// One photo a request: a second reading would be dropped; a turned photo used as it stands.
TEST(GeoPoseReq, OnePhotoUprightAndPresent) {
  json two = FullRequest();
  two["sensorReadings"]["cameraReadings"].push_back(two["sensorReadings"]["cameraReadings"][0]);
  EXPECT_EQ(ErrorOf(two),
            "sensorReadings.cameraReadings: 2 readings; this server localizes one photo a request "
            "(send them one at a time)");
  using P = json::json_pointer;
  EXPECT_EQ(ErrorWith(P("/sensorReadings/cameraReadings/0/imageOrientation/rotation"), 90),
            "sensorReadings.cameraReadings[0].imageOrientation: {\"mirrored\":false,"
            "\"rotation\":90} is not applied by this server; send the photo upright (rotation 0, "
            "not mirrored)");
  EXPECT_EQ(ErrorWith(P("/sensorReadings/cameraReadings"), json::array()),
            "sensorReadings.cameraReadings[0] is missing");
  json none = FullRequest();
  none.erase("sensorReadings");
  EXPECT_EQ(ErrorOf(none), "sensorReadings.cameraReadings[0] is missing");
  EXPECT_EQ(ErrorOf(json::array()), "the body is not a JSON object");
}

}  // namespace
}  // namespace linecloud
