"""[interop]: `linecloud serve` as the world's clients speak to it, not only ours.

* OSCP GeoPose: requests shaped field by field as the protocol's own type definitions
  (github.com/OpenArCloud/oscp-geopose-protocol, README: GeoPoseReq, v2) and its two reference
  clients (python/demo_client.py with python/oscp/geoposeprotocol.py; cpp/oscp-gpp-demo with
  cpp/oscp-gpp) build them, sent to the real binary over a held-out fountain-P11 map with a
  geo-anchor; each answer read back by the reference client's own parsing rules, its pose
  compared with the ground truth. Written from reading them: none of their code is here.
* Early answers: a status decided from the request's head (401, 403, 404, 413, 429) reaches
  Python's urllib, which sends its whole body before it reads anything.
"""

import base64
import hashlib
import json
import math
import struct
import time
import urllib.error
import urllib.request
import uuid

import pytest

from conftest import run_cli
from test_schema import Served

CAMERA = [1379.74, 1382.08, 760.095, 503.155]
ANCHOR = {"lat": 46.5191, "lon": 6.5668, "h": 400.0}


@pytest.fixture(scope="module")
def maps(fountain, tmp_path_factory):
    """The held-out map (group g00, built without 0000.jpg) with a geo-anchor whose ENU frame
    is the map's own, and a second map, "closed", whose lines are not published."""
    root = tmp_path_factory.mktemp("interop")
    out = root / "maps"
    out.mkdir()
    env = {"LINECLOUD_KEY_STORE": str(root / "keys")}
    run_cli("lift", "--model", fountain["model"], "--database", fountain["database"],
            "--out", out / "fountain.lcm", env=env)
    anchor = dict(ANCHOR, enu_from_map={"q": [1, 0, 0, 0], "t": [0, 0, 0], "scale": 1.0})
    (out / "fountain.json").write_text(json.dumps({"geo_anchor": anchor}))
    tokens = {"tokens": [
        {"id": "reader", "sha256": hashlib.sha256(b"reader-secret").hexdigest(),
         "maps": ["fountain"]},
        {"id": "slow", "sha256": hashlib.sha256(b"slow-secret").hexdigest(),
         "maps": ["fountain"], "requests_per_minute": 1},
    ]}
    (root / "tokens.json").write_text(json.dumps(tokens))
    return {"maps": out, "tokens": root / "tokens.json"}


@pytest.fixture(scope="module")
def open_server(maps):
    served = Served(maps["maps"])
    yield served
    served.close()


def _post(port, path, body: bytes, headers):
    """urllib as the reference Python client's `requests` would send it: the whole body, then
    the answer. (status, body bytes); a broken pipe or reset fails the test."""
    req = urllib.request.Request(f"http://127.0.0.1:{port}{path}", data=body, headers=headers,
                                 method="POST")
    try:
        with urllib.request.urlopen(req, timeout=60) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.read()


# --- the protocol's geodesy, to read a GeoPose back into the map's frame ---------------------

def _ecef(lat, lon, h):
    a, f = 6378137.0, 1 / 298.257223563
    e2 = f * (2 - f)
    la, lo = math.radians(lat), math.radians(lon)
    n = a / math.sqrt(1 - e2 * math.sin(la) ** 2)
    return [(n + h) * math.cos(la) * math.cos(lo), (n + h) * math.cos(la) * math.sin(lo),
            (n * (1 - e2) + h) * math.sin(la)]


def _enu(lat, lon, h):
    """East, north, up of (lat, lon, h) in the anchor's tangent frame."""
    p, o = _ecef(lat, lon, h), _ecef(ANCHOR["lat"], ANCHOR["lon"], ANCHOR["h"])
    d = [p[i] - o[i] for i in range(3)]
    la, lo = math.radians(ANCHOR["lat"]), math.radians(ANCHOR["lon"])
    east = -math.sin(lo) * d[0] + math.cos(lo) * d[1]
    north = (-math.sin(la) * math.cos(lo) * d[0] - math.sin(la) * math.sin(lo) * d[1]
             + math.cos(la) * d[2])
    up = (math.cos(la) * math.cos(lo) * d[0] + math.cos(la) * math.sin(lo) * d[1]
          + math.sin(la) * d[2])
    return [east, north, up]


def _rotate(q, v):  # q = (w, x, y, z)
    w, x, y, z = q
    r = [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
         [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
         [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]
    return [sum(r[i][k] * v[k] for k in range(3)) for i in range(3)]


def _check_pose(geopose, truth):
    """The GeoPose (ENU = the map's frame here) against COLMAP's cam_from_world."""
    q = geopose["quaternion"]
    enu_from_cam = (q["w"], q["x"], q["y"], q["z"])
    tq = truth["q"]
    # the angle between enu_from_cam and the truth's world_from_cam = inverse(cam_from_world)
    inverse = (tq[0], -tq[1], -tq[2], -tq[3])
    dot = abs(sum(a * b for a, b in zip(enu_from_cam, inverse)))
    angle = math.degrees(2 * math.acos(min(1.0, dot)))
    centre = [-c for c in _rotate(inverse, truth["t"])]
    p = geopose["position"]
    error = math.dist(_enu(p["lat"], p["lon"], p["h"]), centre)
    assert angle < 0.5 and error < 0.05, (angle, error)


# --- the Python reference client (demo_client.py) ----------------------------------------------

def _python_privacy():
    return {"dataRetention": [], "dataAcceptableUse": [], "dataSanitizationApplied": [],
            "dataSanitizationRequested": []}


def _python_client_request(photo: bytes, width, height):
    """What demo_client.py sends: its objects dumped whole (json.dumps(o.__dict__)), so every
    optional field is present; timestamps are datetime.now().timestamp() * 1000 (floats);
    imageFormat RGBA32 whatever the bytes; the readings lists as its SensorReadings has them
    (wifiReadings, not the text's wiFiReadings)."""
    now = time.time() * 1000
    empty_sensor = {"name": "", "model": "", "rigIdentifier": "",
                    "rigRotation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
                    "rigTranslation": {"x": 0.0, "y": 0.0, "z": 0.0}}
    camera_reading = {
        "timestamp": now, "sensorId": "my_camera_sensor", "privacy": _python_privacy(),
        "sequenceNumber": 1, "imageFormat": "RGBA32", "size": [width, height],
        "imageBytes": base64.b64encode(photo).decode(),
        "imageOrientation": {"mirrored": False, "rotation": 0.0},
        "params": {"model": "PINHOLE", "modelParams": CAMERA, "minMaxDepth": [],
                   "minMaxDisparity": []}}
    geolocation_reading = {
        "timestamp": now, "sensorId": "my_gps_sensor", "privacy": _python_privacy(),
        "latitude": ANCHOR["lat"], "longitude": ANCHOR["lon"], "altitude": ANCHOR["h"],
        "accuracy": 0.0, "altitudeAccuracy": 0.0, "heading": 0.0, "speed": 0.0}
    return {
        "type": "geopose", "id": str(uuid.uuid4()), "timestamp": now,
        "sensors": [dict(empty_sensor, type="camera", id="my_camera_sensor"),
                    dict(empty_sensor, type="geolocation", id="my_gps_sensor")],
        "sensorReadings": {"cameraReadings": [camera_reading],
                           "geolocationReadings": [geolocation_reading],
                           "accelerometerReadings": [], "gyroscopeReadings": [],
                           "magnetometerReadings": [], "wifiReadings": [],
                           "bluetoothReadings": []},
        "priorPoses": []}


def _python_client_reads(answer):
    """GeoPoseResponse.fromJson's rules: type, id, timestamp indexed; GeoPoseAccuracy(**a),
    Position(**p), Quaternion(**q) take exactly their own keyword arguments."""
    for key in ("type", "id", "timestamp", "accuracy", "geopose"):
        assert key in answer, key
    assert set(answer["accuracy"]) <= {"position", "orientation"}
    assert set(answer["geopose"]["position"]) <= {"lat", "lon", "h"}
    assert set(answer["geopose"]["quaternion"]) <= {"x", "y", "z", "w"}
    return answer["geopose"]


# --- the C++ reference client (oscp-gpp-demo, main_client.cpp with oscp-gpp's JSON) ----------

def _float32(x):
    return struct.unpack("f", struct.pack("f", x))[0]


def _cpp_client_request(photo: bytes, width, height):
    """What oscp-gpp-demo sends: an integer timestamp (steady_clock ms), one camera sensor with
    name and model, imageFormat JPG, the camera as OPENCV with eight float32 parameters (its
    camera_params file), a geolocation reading whose timestamp is never set (any integer) and
    whose sensorId is empty, empty reading lists and priorPoses left out."""
    stamp = int(time.monotonic() * 1000)
    privacy = _python_privacy()
    params = [_float32(v) for v in CAMERA + [0.0, 0.0, 0.0, 0.0]]
    return {
        "type": "geopose", "id": str(uuid.uuid4()), "timestamp": stamp,
        "sensors": [{"type": "camera", "id": "camera_01", "name": "test_client",
                     "model": "OPENCV"}],
        "sensorReadings": {
            "cameraReadings": [{
                "timestamp": stamp, "sensorId": "camera_01", "privacy": privacy,
                "sequenceNumber": 0, "imageFormat": "JPG", "size": [width, height],
                "imageBytes": base64.b64encode(photo).decode(),
                "imageOrientation": {"mirrored": False, "rotation": 0.0},
                "params": {"model": "OPENCV", "modelParams": params}}],
            "geolocationReadings": [{
                "timestamp": -6917529027641081856, "sensorId": "", "privacy": privacy,
                "latitude": _float32(ANCHOR["lat"]), "longitude": _float32(ANCHOR["lon"]),
                "altitude": _float32(ANCHOR["h"]), "accuracy": 0.0, "altitudeAccuracy": 0.0,
                "heading": 0.0, "speed": 0.0}]}}


def _cpp_client_reads(answer):
    """from_json(GeoPoseResponse): .at() of type, id (strings), timestamp (a number into
    time_t), accuracy.position / orientation and every coordinate (numbers into float / double:
    null throws)."""
    assert isinstance(answer["type"], str) and isinstance(answer["id"], str)
    assert isinstance(answer["timestamp"], (int, float))
    for key in ("position", "orientation"):
        assert isinstance(answer["accuracy"][key], (int, float)), key
    g = answer["geopose"]
    for key in ("x", "y", "z", "w"):
        assert isinstance(g["quaternion"][key], (int, float)), key
    for key in ("lat", "lon", "h"):
        assert isinstance(g["position"][key], (int, float)), key
    return g


@pytest.mark.parametrize("client", ["python", "cpp"])
def test_the_reference_clients_requests_get_the_true_pose(client, maps, open_server, fountain):
    photo = fountain["photo"].read_bytes()
    build, read = ((_python_client_request, _python_client_reads) if client == "python"
                   else (_cpp_client_request, _cpp_client_reads))
    request = build(photo, 1536, 1024)
    headers = {"Content-Type": "application/json",
               "Accept": "application/vnd.oscp+json;version=2.0;"}
    status, body = _post(open_server.port, "/geopose", json.dumps(request).encode(), headers)
    assert status == 200, body
    answer = json.loads(body)
    assert answer["id"] == request["id"]
    _check_pose(read(answer), fountain["truth"])


def test_what_the_protocol_allows_is_not_refused(maps, open_server, fountain):
    """Fields the protocol types `number` take any number; optional fields may be null (the
    C++ library writes an empty optional so); a size of 1536.0; the text's wiFiReadings."""
    request = _python_client_request(fountain["photo"].read_bytes(), 1536.0, 1024.0)
    readings = request["sensorReadings"]
    readings["cameraReadings"][0]["sequenceNumber"] = 2.5
    readings["cameraReadings"][0]["params"]["minMaxDepth"] = None
    readings["cameraReadings"][0]["imageOrientation"] = None
    readings["geolocationReadings"][0]["heading"] = None
    readings["wiFiReadings"] = [{"timestamp": 1.5, "sensorId": "w", "BSSID": "aa", "SSID": "x",
                                 "frequency": 2412, "RSSI": -40.5, "scanTimeStart": 0.5,
                                 "scanTimeEnd": 1.5}]
    request["priorPoses"] = None
    status, body = _post(open_server.port, "/geopose", json.dumps(request).encode(),
                         {"Content-Type": "application/json"})
    assert status == 200, body
    # What it does not allow is still refused, naming the field.
    request["sensorReadings"]["cameraReadings"][0]["timestamp"] = "x"
    status, body = _post(open_server.port, "/geopose", json.dumps(request).encode(),
                         {"Content-Type": "application/json"})
    assert status == 400
    assert "cameraReadings[0].timestamp" in json.loads(body)["error"]


# --- early answers through urllib ------------------------------------------------------------

@pytest.fixture(scope="module")
def token_server(maps):
    served = Served(maps["maps"], "--tokens", maps["tokens"])
    yield served
    served.close()


def _features_body(size):
    """A features body of `size` bytes (the shape is never read: the head decides)."""
    pad = "A" * (size - 200)
    return json.dumps({"camera": {"model": "PINHOLE", "width": 1536, "height": 1024,
                                  "params": CAMERA},
                       "keypoints": [], "descriptors": pad}).encode()


@pytest.mark.parametrize("case", ["401 wrong token", "404 no such map", "429 over its rate"])
def test_urllib_reads_a_refusal_decided_from_the_head(case, token_server):
    body = _features_body(3 << 20)
    token = {"401 wrong token": "nobody", "404 no such map": "reader-secret",
             "429 over its rate": "slow-secret"}[case]
    path = "/v1/maps/nowhere/localize" if case.startswith("404") else "/v1/maps/fountain/localize"
    headers = {"Content-Type": "application/json", "Authorization": f"Bearer {token}"}
    statuses = []
    for _ in range(3 if case.startswith("429") else 1):  # the bucket's first request passes
        status, answer = _post(token_server.port, path, body, headers)
        statuses.append(status)
    expected = int(case[:3])
    assert statuses[-1] == expected, (statuses, answer)
    assert json.loads(answer)["error"]


def test_urllib_reads_the_403_of_a_body_on_unpublished_lines(token_server):
    req = urllib.request.Request(
        f"http://127.0.0.1:{token_server.port}/v1/maps/fountain/segments",
        data=b"x" * (3 << 20), headers={"Authorization": "Bearer reader-secret"}, method="GET")
    with pytest.raises(urllib.error.HTTPError) as e:
        urllib.request.urlopen(req, timeout=60)
    assert e.value.code == 403
    assert "admin" in json.loads(e.value.read())["error"]


@pytest.mark.parametrize("size_mb, cap_mb", [(3, 2), (20, 16)])
def test_urllib_reads_the_413_of_a_body_over_the_cap(size_mb, cap_mb, maps):
    served = Served(maps["maps"], "--max-body-mb", cap_mb)
    try:
        status, answer = _post(served.port, "/v1/maps/fountain/localize",
                               _features_body(size_mb << 20), {"Content-Type": "application/json"})
        assert status == 413, answer
        assert f"{cap_mb:g} MB" in json.loads(answer)["error"]
    finally:
        served.close()
