// An OSCP GeoPose Protocol v2 request (`POST /geopose`,
// github.com/OpenArCloud/oscp-geopose-protocol) checked against the
// protocol's fields before it is used: a field the protocol does not have, at
// any depth, would be ignored (a client's "options", a misspelt "mirored"),
// so it is refused, naming its path; so is a field of the wrong type, a
// second camera reading (one photo a request) and an imageOrientation other
// than upright (the photo is used as its pixels stand).
#pragma once

#include <nlohmann/json.hpp>

namespace linecloud {

// The request's one camera reading (sensorReadings.cameraReadings[0]); throws
// Error naming the field's path (e.g. "sensors[1]: unknown field \"foo\" (id, ...)").
const nlohmann::json& CheckGeoPoseReq(const nlohmann::json& request);

}  // namespace linecloud
