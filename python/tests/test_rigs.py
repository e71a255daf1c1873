"""[rigs]: a device's frames through `linecloud serve`, as a HoloLens or a phone with ARKit sends
them: the frames' photos (or their features) with their relative poses from the device's tracking,
optionally its gravity and its own 3D points (Speciale et al., CVPR 2019: the m- methods, +u, +l,
+s).

Three held-out fountain-P11 photos (a map lifted without them) make a rig whose relative poses
come from the ground truth with a device's noise (0.1 deg, 1 cm). Through a real HTTP client and a
real `linecloud serve` process, each method the request implies must give a pose within 0.5 deg /
5 cm of the truth, the same as `linecloud localize --image ... --rig RIG.json` and Python's
Localizer to 1e-9; the local points are triangulated from the frames' own matches."""

import base64
import json
import struct
from pathlib import Path

import numpy as np
import pytest

import linecloud as lc
from conftest import fixed_key, run_cli
from test_schema import Served, _camera_text, _multipart

FRAMES = ["0000.jpg", "0001.jpg", "0002.jpg"]


# --- a COLMAP binary model without some images (the test's own held-out map) -------------------

def _read_images(path: Path):
    data = path.read_bytes()
    (n,), at = struct.unpack_from("<Q", data, 0), 8
    images = []
    for _ in range(n):
        image_id, *pose, camera_id = struct.unpack_from("<I7dI", data, at)
        at += 64
        end = data.index(b"\0", at)
        name = data[at:end].decode()
        at = end + 1
        (m,) = struct.unpack_from("<Q", data, at)
        at += 8
        points = [list(struct.unpack_from("<ddq", data, at + 24 * i)) for i in range(m)]
        at += 24 * m
        images.append({"id": image_id, "pose": pose, "camera": camera_id, "name": name,
                       "points": points})
    return images


def _read_points(path: Path):
    data = path.read_bytes()
    (n,), at = struct.unpack_from("<Q", data, 0), 8
    points = []
    for _ in range(n):
        point_id, x, y, z, r, g, b, error, length = struct.unpack_from("<Q3d3BdQ", data, at)
        at += 43 + 8
        track = [struct.unpack_from("<II", data, at + 8 * i) for i in range(length)]
        at += 8 * length
        points.append({"id": point_id, "xyz": (x, y, z), "rgb": (r, g, b), "error": error,
                       "track": track})
    return points


def _model_without(source: Path, names, out: Path):
    """source's model with the images `names` removed, their observations dropped from the
    tracks, and the points left with fewer than two observations dropped."""
    images = _read_images(source / "images.bin")
    dropped = {im["id"] for im in images if im["name"] in names}
    assert len(dropped) == len(names), [im["name"] for im in images]
    points = []
    for p in _read_points(source / "points3D.bin"):
        p["track"] = [t for t in p["track"] if t[0] not in dropped]
        if len(p["track"]) >= 2:
            points.append(p)
    kept = {p["id"] for p in points}
    out.mkdir(parents=True)
    (out / "cameras.bin").write_bytes((source / "cameras.bin").read_bytes())
    blob = struct.pack("<Q", len(images) - len(dropped))
    for im in images:
        if im["id"] in dropped:
            continue
        blob += struct.pack("<I7dI", im["id"], *im["pose"], im["camera"])
        blob += im["name"].encode() + b"\0" + struct.pack("<Q", len(im["points"]))
        for x, y, pid in im["points"]:
            blob += struct.pack("<ddq", x, y, pid if pid in kept else -1)
    (out / "images.bin").write_bytes(blob)
    blob = struct.pack("<Q", len(points))
    for p in points:
        blob += struct.pack("<Q3d3BdQ", p["id"], *p["xyz"], *p["rgb"], p["error"], len(p["track"]))
        blob += b"".join(struct.pack("<II", *t) for t in p["track"])
    (out / "points3D.bin").write_bytes(blob)


# --- poses ---------------------------------------------------------------------------------------

def _rotation(q):
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _quaternion(r):
    w = np.sqrt(max(0.0, 1 + np.trace(r))) / 2
    x = np.copysign(np.sqrt(max(0.0, 1 + r[0, 0] - r[1, 1] - r[2, 2])) / 2, r[2, 1] - r[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1 - r[0, 0] + r[1, 1] - r[2, 2])) / 2, r[0, 2] - r[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1 - r[0, 0] - r[1, 1] + r[2, 2])) / 2, r[1, 0] - r[0, 1])
    q = np.array([w, x, y, z])
    return q / np.linalg.norm(q)


def _axis_angle(v):
    angle = np.linalg.norm(v)
    if angle == 0:
        return np.eye(3)
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]]) / angle
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def _errors(answer, truth_r, truth_t):
    """Rotation (deg) and centre (m) errors of a rig_from_world answer."""
    r = _rotation(answer["q"])
    s = answer.get("scale", 1.0)
    c = -r.T @ np.asarray(answer["t"]) / s
    c_true = -truth_r.T @ truth_t
    cos = np.clip((np.trace(r @ truth_r.T) - 1) / 2, -1, 1)
    return np.degrees(np.arccos(cos)), np.linalg.norm(c - c_true)


# --- the scene -----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def rig(fountain, tmp_path_factory):
    """The held-out map (served and as a file), the frames, their noisy rig, the truth."""
    work = Path(fountain["model"]).parents[2]
    prepared = json.loads((work / "prepared.json").read_text())
    truth = {im["name"]: im for g in prepared["groups"] for im in g["images"]}
    folder = tmp_path_factory.mktemp("rig")
    # groups/g00/map is the aligned reconstruction without 0000 and 0001; 0002 leaves too.
    _model_without(fountain["model"], ["0002.jpg"], folder / "model")
    maps = folder / "maps"
    maps.mkdir()
    gravity_world = prepared["gravity_world"]
    # A fixed key (the same lines, index and matches on every run).
    lc.lift(folder / "model", database=fountain["database"], key_file=fixed_key(folder, "27"),
            key_store=tmp_path_factory.mktemp("rig-keys")).write(maps / "fountain.lcm")
    # The map's gravity from its owner (ID.json), for the +u methods.
    (maps / "fountain.json").write_text(json.dumps({"options": {"map_gravity": gravity_world}}))
    # The rig: frame 0's camera is the rig frame; the others' relative poses from the truth with
    # a device's tracking noise (0.1 deg about a random axis, 1 cm in a random direction).
    rng = np.random.default_rng(20261127)
    world = [(_rotation(truth[n]["cam_from_world"]["q"]), np.asarray(truth[n]["cam_from_world"]["t"]))
             for n in FRAMES]
    r0, t0 = world[0]
    cam_from_rig = []
    for k, (r, t) in enumerate(world):
        r_rel, t_rel = r @ r0.T, t - r @ r0.T @ t0
        if k > 0:
            axis = rng.normal(size=3)
            r_rel = _axis_angle(np.radians(0.1) * axis / np.linalg.norm(axis)) @ r_rel
            step = rng.normal(size=3)
            t_rel = t_rel + 0.01 * step / np.linalg.norm(step)
        cam_from_rig.append((r_rel, t_rel))
    photos = [Path(fountain["photo"]).parent / n for n in FRAMES]
    # Gravity in the rig frame: frame 0's measured direction (the work's, tilted by ~0.2 deg).
    gravity = truth[FRAMES[0]]["gravity"]
    # The frames' features as a client sends them (`linecloud features --rig`), once.
    rig_path = folder / "plain-rig.json"
    rig_path.write_text(json.dumps(_rig_json({"cam_from_rig": cam_from_rig})))
    run_cli("features", *sum((["--image", p] for p in photos), []), "--camera",
            _camera_text(fountain["camera"]), "--rig", rig_path, "--out", folder / "body.json")
    features = json.loads((folder / "body.json").read_text())
    return {"maps": maps, "map": maps / "fountain.lcm", "photos": photos, "features": features,
            "camera": fountain["camera"], "cam_from_rig": cam_from_rig, "truth": (r0, t0),
            "gravity": gravity, "map_gravity": gravity_world, "folder": folder}


def _rig_json(rig, scale=1.0, **extra):
    return dict({"cam_from_rig": [{"q": list(_quaternion(r)), "t": list(scale * t)}
                                  for r, t in rig["cam_from_rig"]]}, **extra)


@pytest.fixture(scope="module")
def local_points(rig):
    """The device's own 3D points: the frames' features (as `linecloud features` writes them)
    matched frame to frame (mutual nearest neighbours, ratio 0.8) and triangulated with the
    noisy rig poses; kept when in front of both cameras and within 2 px of both keypoints."""
    frames = rig["features"]["frames"]
    cam = rig["camera"]["params"]
    k = np.array([[cam[0], 0, cam[2]], [0, cam[1], cam[3]], [0, 0, 1]])
    # The first 4 000 keypoints of each frame (a device's local map is sparser than SIFT).
    feats = []
    for f in frames:
        d = np.frombuffer(base64.b64decode(f["descriptors"]), np.uint8).reshape(-1, 128)
        feats.append((np.asarray(f["keypoints"], float)[:4000], d[:4000].astype(np.float32)))
    points, seen = [], set()
    for a, b in [(0, 1), (1, 2), (0, 2)]:
        (ka, da), (kb, db) = feats[a], feats[b]
        dist = -2 * da @ db.T + (da * da).sum(1)[:, None] + (db * db).sum(1)[None, :]
        best_b = np.argpartition(dist, 1, axis=1)[:, :2]
        rows = np.arange(len(ka))[:, None]
        best_b = np.take_along_axis(best_b, np.argsort(dist[rows, best_b], axis=1), axis=1)
        best_a = np.argmin(dist, axis=0)
        ra, ta = rig["cam_from_rig"][a]
        rb, tb = rig["cam_from_rig"][b]
        pa, pb = k @ np.hstack([ra, ta[:, None]]), k @ np.hstack([rb, tb[:, None]])
        i = np.arange(len(ka))
        j, j2 = best_b[:, 0], best_b[:, 1]
        keep = (best_a[j] == i) & (dist[i, j] <= 0.64 * dist[i, j2])
        i, j = i[keep], j[keep]
        # COLMAP's pixel convention: the top-left pixel's centre is (0.5, 0.5).
        xa, xb = ka[i] - 0.5, kb[j] - 0.5
        m = np.stack([xa[:, :1] * pa[2] - pa[0], xa[:, 1:] * pa[2] - pa[1],
                      xb[:, :1] * pb[2] - pb[0], xb[:, 1:] * pb[2] - pb[1]], axis=1)
        x = np.linalg.svd(m)[2][:, -1]
        x = x[:, :3] / x[:, 3:]
        ok = np.ones(len(x), bool)
        for p, xy in ((pa, xa), (pb, xb)):
            h = np.hstack([x, np.ones((len(x), 1))]) @ p.T
            ok &= (h[:, 2] > 0) & (np.linalg.norm(h[:, :2] / h[:, 2:] - xy, axis=1) < 2.0)
        for ia, jb, xyz in zip(i[ok], j[ok], x[ok]):
            if (a, ia) in seen or (b, jb) in seen:
                continue
            seen.update({(a, ia), (b, jb)})
            points.append({"frame": a, "keypoint": int(ia), "xyz": xyz.tolist()})
            points.append({"frame": b, "keypoint": int(jb), "xyz": xyz.tolist()})
    assert len(points) > 500, len(points)
    return points


@pytest.fixture(scope="module")
def server(rig):
    """A real `linecloud serve` over the held-out map (its owner's ID.json: the map's gravity)."""
    served = Served(rig["maps"])
    yield served
    served.close()


@pytest.fixture(scope="module")
def localizer(rig):
    return lc.Localizer(rig["map"], map_gravity=rig["map_gravity"])


def _http(server, parts_or_body, features=False):
    if features:
        return server.post("/v1/maps/fountain/localize", json.dumps(parts_or_body).encode(),
                           "application/json")
    return server.post("/v1/maps/fountain/localize", *_multipart(parts_or_body))


def _parts(rig, rig_fields, scale=1.0):
    parts = {"camera": _camera_text(rig["camera"])}
    for k, photo in enumerate(rig["photos"]):
        parts[f"image[{k}]"] = photo.read_bytes()
        r, t = rig["cam_from_rig"][k]
        parts[f"cam_from_rig[{k}]"] = json.dumps({"q": list(_quaternion(r)), "t": list(scale * t)})
    for name, value in rig_fields.items():
        parts[name] = value if isinstance(value, str) else json.dumps(value)
    return parts


def _cli(rig, rig_fields, name, scale=1.0):
    path = rig["folder"] / f"{name}.json"
    path.write_text(json.dumps(_rig_json(rig, scale, **rig_fields)))
    return json.loads(run_cli("localize", "--map", rig["map"], *sum((["--image", p] for p in
                                                                       rig["photos"]), []),
                              "--camera", _camera_text(rig["camera"]), "--rig", path, "--quiet",
                              "--map-gravity", ",".join(map(str, rig["map_gravity"]))))


CASES = {
    # what the device sends -> the method the server chooses
    "m-p6L": lambda rig, pts: {},
    "m-p4L+u": lambda rig, pts: {"gravity": rig["gravity"]},
    "m-P3L+l+s": lambda rig, pts: {"points_local": pts, "scale_known": True},
    "m-P4L+l": lambda rig, pts: {"points_local": pts, "scale_known": False},
    "m-P3L+l+u": lambda rig, pts: {"points_local": pts, "gravity": rig["gravity"]},
    "m-P2L+l+u+s": lambda rig, pts: {"points_local": pts, "scale_known": True,
                                     "gravity": rig["gravity"]},
}
# The unknown-scale devices: their rig and points in their own units (metres x 0.37).
SCALE = {"m-P4L+l": 0.37, "m-P3L+l+u": 0.37}


@pytest.mark.parametrize("method", list(CASES))
def test_a_devices_frames_over_http_give_the_true_pose(rig, local_points, server, localizer,
                                                       method):
    fields = CASES[method](rig, local_points)
    scale = SCALE.get(method, 1.0)
    if "points_local" in fields:
        fields["points_local"] = [dict(p, xyz=list(scale * np.asarray(p["xyz"])))
                                  for p in fields["points_local"]]
    cli = _cli(rig, fields, method, scale)
    assert cli["success"], cli
    assert cli["method"] == method
    answers = {}
    # The photos as multipart parts, the method left to the server (keypoint indices of local
    # points are the server's own SIFT's: `linecloud features`' with the map's options).
    if method in ("m-p6L", "m-P3L+l+s"):
        status, answers["http photos"] = _http(
            server, _parts(rig, {k: v if k != "gravity" else ",".join(map(str, v))
                                 for k, v in fields.items()}, scale))
        assert status == 200, answers["http photos"]
    # The frames' features as JSON (as `linecloud features --rig` writes them), the rig's fields
    # beside them.
    body = dict(json.loads(json.dumps(rig["features"])), **fields)
    for frame, pose in zip(body["frames"], _rig_json(rig, scale)["cam_from_rig"]):
        frame["cam_from_rig"] = pose
    status, answers["http features"] = _http(server, body, features=True)
    assert status == 200, answers["http features"]
    # Python: one call, lists in (the frames' features: their photos' SIFT is the CLI's).
    frames = rig["features"]["frames"]
    answers["python"] = localizer.localize_features(
        [np.asarray(f["keypoints"]) for f in frames],
        [np.frombuffer(base64.b64decode(f["descriptors"]), np.uint8).reshape(-1, 128)
         for f in frames],
        rig["camera"], cam_from_rig=_rig_json(rig, scale)["cam_from_rig"], **fields)
    for who, r in answers.items():
        assert r["success"], (who, r)
        assert r["method"] == method, (who, r["method"])
        np.testing.assert_allclose(r["q"], cli["q"], rtol=0, atol=1e-9, err_msg=who)
        np.testing.assert_allclose(r["t"], cli["t"], rtol=0, atol=1e-9, err_msg=who)
    assert answers["http features"]["pose"] == "rig_from_world"
    assert ("scale" in answers["http features"]) == (method in SCALE)
    rotation_deg, centre_m = _errors(cli, *rig["truth"])
    print(f"{method}: {cli['num_inliers']} inliers of {cli['num_correspondences']}, "
          f"{rotation_deg:.3f} deg, {100 * centre_m:.1f} cm")
    assert rotation_deg < 0.5 and centre_m < 0.05, (method, rotation_deg, centre_m)
    if method in SCALE:
        # X_local = s R X_world + t: the device's units are 0.37 of the map's metres.
        assert abs(cli["scale"] / scale - 1) < 0.02, cli["scale"]


def test_the_features_body_writer_carries_the_rigs_fields(rig, local_points):
    fields = {"points_local": local_points[:10], "scale_known": True, "gravity": rig["gravity"]}
    rig_path = rig["folder"] / "full-rig.json"
    rig_path.write_text(json.dumps(_rig_json(rig, **fields)))
    out = rig["folder"] / "full-body.json"
    run_cli("features", *sum((["--image", p] for p in rig["photos"]), []), "--camera",
            _camera_text(rig["camera"]), "--rig", rig_path, "--out", out)
    body = json.loads(out.read_text())
    assert set(body) == {"frames", "points_local", "scale_known", "gravity"}
    assert body["points_local"] == fields["points_local"]
    assert body["scale_known"] is True
    np.testing.assert_allclose(body["gravity"], rig["gravity"], rtol=0, atol=1e-15)
    for mine, plain, pose in zip(body["frames"], rig["features"]["frames"],
                                 _rig_json(rig)["cam_from_rig"]):
        assert mine["keypoints"] == plain["keypoints"]
        assert mine["descriptors"] == plain["descriptors"]
        np.testing.assert_allclose(mine["cam_from_rig"]["q"], pose["q"], rtol=0, atol=1e-15)
        np.testing.assert_allclose(mine["cam_from_rig"]["t"], pose["t"], rtol=0, atol=1e-15)


def test_a_rig_request_that_is_wrong_is_refused_naming_the_part(rig, local_points, server):
    """Bad rigs get 400 / 413 naming the part or field, before any photo is decoded."""
    frames = rig["features"]["frames"]
    poses = _rig_json(rig)["cam_from_rig"]

    def body(**fields):
        b = {"frames": [dict(f, cam_from_rig=p) for f, p in zip(frames, poses)]}
        b.update(fields)
        return b

    def features(b):
        status, answer = _http(server, b, features=True)
        return status, answer.get("error", answer)

    photo = rig["photos"][0].read_bytes()
    camera = _camera_text(rig["camera"])
    pose = json.dumps(poses[1])
    cases = [
        # multipart
        (_http(server, {"image[1]": photo, "camera": camera, "cam_from_rig[1]": pose}),
         400, "multipart: image[1] without image[0] (frames are image[0], image[1], ... in order)"),
        (_http(server, {"image": photo, "image[0]": photo, "camera": camera}), 400,
         "multipart: give 'image' (one photo) or image[0], image[1], ..."),
        (_http(server, {"image[0]": photo, "image[1]": photo, "camera": camera,
                        "cam_from_rig[0]": pose}), 400,
         "multipart: the 'cam_from_rig[1]' part is missing"),
        (_http(server, {"image[0]": photo, "camera[0]": camera, "camera[3]": camera}), 400,
         "multipart: camera[3] has no image[3]"),
        (_http(server, {"image[01]": photo, "camera": camera}), 400,
         "multipart: part \"image[01]\": expected image[0], image[1], ..."),
        (_http(server, {**{f"image[{k}]": b"x" for k in range(9)}, "camera": camera}), 413,
         "9 frames: this server takes at most 8 in one request (serve --max-frames)"),
        (_http(server, {"image[0]": photo, "camera": camera, "scale_known": "maybe"}), 400,
         "scale_known: expected true or false, got \"maybe\""),
        (_http(server, {"image[0]": b"", "image[1]": photo, "camera": camera,
                        "cam_from_rig[0]": pose, "cam_from_rig[1]": pose}), 400,
         "image[0]: an empty part, not a photo"),
        (_http(server, {"image": b"", "camera": camera}), 400, "image: an empty part, not a photo"),
        (_http(server, {"image[0]": photo, "camera": camera, "cam_from_rig[0]": pose,
                        "method": "p6L"}), 400,
         "image[0] has a cam_from_rig: a photo in a rig needs an m- method"),
        # JSON frames
        (features(body(points_local=local_points[:20], method="m-p6L")), 400,
         "points_local: m-p6L does not use the query's own points (the +l methods do: "),
        (features(body(points_local=[{"frame": 3, "keypoint": 0, "xyz": [0, 0, 1]}])), 400,
         "points_local[0]: frame 3 is not one of the 3 photos"),
        (features(body(points_local=[{"frame": 0, "keypoint": 10 ** 6, "xyz": [0, 0, 1]}])), 400,
         "points_local[0]: frames[0] has"),
        (features(body(points_local=[{"frame": 0, "keypoint": 1, "xyz": [0, 0, 1], "w": 1}])),
         400, "points_local[0]: unknown field \"w\" (frame, keypoint, xyz)"),
        (features(body(points_local=local_points[:20], scale_known=True, method="m-P4L+l")), 400,
         "scale_known is true but m-P4L+l estimates the scale"),
        (features(body(method="m-P3L+l+s")), 400,
         "m-P3L+l+s localizes the photos' own 3D points: give points_local (frame, keypoint, xyz)"),
        (features(body(method="p6L")), 400,
         "3 photos make one generalized camera: use an m- method (m-p6L, m-p3P, ...), not p6L"),
        (features({"frames": [dict(f, cam_from_rig=p) for f, p in zip(frames, poses)][:2] +
                   [{k: v for k, v in frames[2].items() if k != "cam_from_rig"}]}), 400,
         "frames[2]: field 'cam_from_rig' is missing (the frame's pose in the rig)"),
        (features(dict(body(), keypoints=[])), 400,
         "body: 'keypoints' goes in each of 'frames', not beside them"),
        (features({"frames": [dict(frames[0], extra=1)]}), 400,
         "frames[0]: unknown field \"extra\""),
        (features({"frames": [{"camera": rig["camera"], "keypoints": [[1, 1]],
                               "descriptors": base64.b64encode(bytes(128)).decode(),
                               "cam_from_rig": poses[0]}] * 9}), 413,
         "9 frames: this server takes at most 8 in one request (serve --max-frames)"),
        (features(body(gravity=[0, 0, 0])), 400, "gravity: expected a finite non-zero direction"),
        (features(body(scale_known=True)), 400,
         "scale_known is the scale of the local points: it goes with points_local"),
    ]
    for (status, answer), want_status, want in cases:
        message = answer.get("error", answer) if isinstance(answer, dict) else answer
        assert status == want_status, (want, status, answer)
        assert want in message, (want, message)


def test_a_rigs_pixels_count_together(rig, tmp_path):
    """--max-pixels bounds a request's photos together: two 1536 x 1024 frames (3.1 M pixels)
    pass one at a time under a 3 M cap, and are refused (413) together."""
    server = Served(rig["maps"], "--max-pixels", 3_000_000)
    try:
        camera = _camera_text(rig["camera"])
        photos = [p.read_bytes() for p in rig["photos"][:2]]
        poses = _rig_json(rig)["cam_from_rig"]
        status, answer = _http(server, {"image[0]": photos[0], "image[1]": photos[1],
                                        "camera": camera,
                                        "cam_from_rig[0]": json.dumps(poses[0]),
                                        "cam_from_rig[1]": json.dumps(poses[1])})
        assert status == 413, answer
        assert answer["error"] == ("2 frames of 3145728 pixels together exceed this server's "
                                   "limit of 3000000 pixels a request"), answer
        status, answer = _http(server, {"image": photos[0], "camera": camera})
        assert status == 200 and answer["success"], answer
    finally:
        server.close()


def test_one_frame_in_a_rig_gives_the_rigs_pose(rig, server, localizer):
    """A device's one frame with its cam_from_rig (frame 1 of the rig alone) is a rig of one: the
    answer is rig_from_world (m-p6L), not the camera's pose with its rig pose dropped."""
    pose = _rig_json(rig)["cam_from_rig"][1]
    status, answer = _http(server, {"image[0]": rig["photos"][1].read_bytes(),
                                    "camera": _camera_text(rig["camera"]),
                                    "cam_from_rig[0]": json.dumps(pose)})
    assert status == 200 and answer["success"], answer
    assert (answer["method"], answer["pose"]) == ("m-p6L", "rig_from_world")
    rotation_deg, centre_m = _errors(answer, *rig["truth"])
    assert rotation_deg < 0.5 and centre_m < 0.05, (rotation_deg, centre_m)
    # A +u method on a map without gravity says so (not a field name of the query file).
    with pytest.raises(ValueError, match=r"m-p4L\+u needs the map's gravity direction, which "
                                         r"this map has none of"):
        lc.Localizer(rig["map"]).localize_image(rig["photos"][0], rig["camera"], method="m-p4L+u",
                                                gravity=rig["gravity"])
