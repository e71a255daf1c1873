"""[camera]: a wrong camera is "no pose" with a reason naming the camera problem, or a right
pose — never a confident wrong one — through the CLI, Python and the service alike.

A real photo (fountain-P11 0000.jpg) against the held-out map of its group (built without it),
with the mistakes apps make: the focal length 10 % off, the principal point off in x or in y,
another aspect ratio, a wrong distortion, a photo turned with only the camera's width and height
swapped, a photo resized with only them changed, a corner crop with a centred principal point.
Each answer is judged against the photo's true pose, and so is the answer with `refine_focal`
(the advice a focal-length refusal gives).
"""

import json
import math

import numpy as np
import pytest

import linecloud as lc
from conftest import fixed_key, run_cli
from test_schema import Served, _camera_text, _multipart

cv2 = pytest.importorskip("cv2")

# Right: within 1 degree and 2 % of the scene (fountain-P11's cameras span about 8 m: 0.16 m).
RIGHT_DEG, RIGHT_M = 1.0, 0.16


def _centre(pose):
    q = np.asarray(pose["q"], float)
    w, x, y, z = q / np.linalg.norm(q)
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    return -r.T @ np.asarray(pose["t"], float)


def _rotation_deg(q1, q2):
    return math.degrees(2 * math.acos(min(1.0, abs(float(np.dot(q1, q2))))))


def _cases(fountain, tmp):
    """(name, photo path, camera dict, what the reason must say, the pose change of the photo)."""
    cam = fountain["camera"]
    w, h = cam["width"], cam["height"]
    fx, fy, cx, cy = cam["params"]
    photo = fountain["photo"]
    pixels = cv2.imread(str(photo))
    turned = tmp / "turned.jpg"
    cv2.imwrite(str(turned), cv2.rotate(pixels, cv2.ROTATE_90_CLOCKWISE))
    small = tmp / "small.jpg"
    cv2.imwrite(str(small), cv2.resize(pixels, (640, 427), interpolation=cv2.INTER_AREA))
    half = tmp / "half.jpg"
    cv2.imwrite(str(half), cv2.resize(pixels, (w // 2, h // 2), interpolation=cv2.INTER_AREA))
    corner = tmp / "corner.jpg"  # the top-left quarter
    cv2.imwrite(str(corner), pixels[: h // 2, : w // 2])
    crop = tmp / "crop.jpg"  # 900 x 600 of the top left: its camera is the photo's, as it is
    cv2.imwrite(str(crop), pixels[:600, :900])
    return [
        ("true camera", photo, cam, None),
        # An off-centre crop's true camera looks like one made for a larger photo (1.7 times):
        # the data decide, not the camera's look.
        ("top-left 900x600 crop with its true camera", crop, dict(cam, width=900, height=600), None),
        # Two or three parameters off together, each within what one alone may be off by.
        ("focal x0.97 with cx +2 %", photo, dict(cam, params=[0.97 * fx, 0.97 * fy, cx + 0.02 * w, cy]),
         "principal point looks wrong: the inliers fit cx"),
        ("fy -1 % with cy -2 %", photo, dict(cam, params=[fx, 0.99 * fy, cx, cy - 0.02 * h]),
         "looks wrong"),
        # fx alone off is the aspect ratio (its principal-point profile had the larger deviance).
        ("fx alone 6 % short", photo, dict(cam, params=[0.94 * fx, fy, cx, cy]),
         "aspect ratio looks wrong"),
        ("focal x0.9", photo, dict(cam, params=[0.9 * fx, 0.9 * fy, cx, cy]),
         "focal length looks wrong"),
        ("focal x1.1", photo, dict(cam, params=[1.1 * fx, 1.1 * fy, cx, cy]),
         "focal length looks wrong"),
        ("cx +5 %", photo, dict(cam, params=[fx, fy, 1.05 * cx, cy]),
         "principal point looks wrong: the inliers fit cx"),
        ("cy -10 %", photo, dict(cam, params=[fx, fy, cx, 0.9 * cy]),
         "principal point looks wrong: the inliers fit cy"),
        ("cx +15 %", photo, dict(cam, params=[fx, fy, 1.15 * cx, cy]),
         "principal point looks wrong: the inliers fit cx"),
        ("distortion wrong: k1 -0.1 for an undistorted photo", photo,
         dict(cam, model="OPENCV", params=[fx, fy, cx, cy, -0.1, 0, 0, 0]), "looks wrong"),
        ("aspect fy x1.05", photo, dict(cam, params=[fx, 1.05 * fy, cx, cy]), "looks wrong"),
        # Tangential terms the photo does not have, beyond the check's limit (0.004).
        ("tangential p1 +0.008", photo, dict(cam, model="OPENCV", params=[fx, fy, cx, cy, 0, 0, 0.008, 0]),
         "tangential distortion looks wrong"),
        ("turned, width and height swapped only", turned, dict(cam, width=h, height=w),
         "the photo looks turned"),
        ("downscaled to 640 px, width and height changed only", small,
         dict(cam, width=640, height=427), "scale fx, fy, cx and cy with the photo"),
        ("halved, width and height changed only", half, dict(cam, width=w // 2, height=h // 2),
         "made for the photo at about 2 times this size"),
        ("top-left quarter, principal point centred", corner,
         # (49 % of the width off, beyond the ±25 % searched: the joint fit sometimes names
         # the focal length; refining it, as that reason offers, still gives no pose.)
         dict(cam, width=w // 2, height=h // 2, params=[fx, fy, w / 4, h / 4]),
         "looks wrong"),
    ]


@pytest.fixture(scope="module")
def fountain_lcm(fountain, tmp_path_factory):
    """Group g00's map under a fixed key (the answers do not change from run to run)."""
    folder = tmp_path_factory.mktemp("wrong-camera")
    lc.lift(fountain["model"], database=fountain["database"], key_file=fixed_key(folder, "3c"),
            key_store=folder / "keys").write(folder / "fountain.lcm")
    return folder


def test_a_wrong_camera_is_no_pose_naming_it_through_cli_python_and_http(fountain, fountain_lcm,
                                                                         tmp_path):
    truth = fountain["truth"]
    localizer = lc.Localizer(fountain_lcm / "fountain.lcm")
    server = Served(fountain_lcm)
    try:
        for name, photo, camera, expected in _cases(fountain, tmp_path):
            answers = {
                "cli": json.loads(run_cli("localize", "--map", fountain_lcm / "fountain.lcm",
                                          "--image", photo, "--camera", _camera_text(camera),
                                          "--quiet")),
                "python": localizer.localize_image(photo, camera, with_inliers=False),
            }
            status, answers["http"] = server.post(
                "/v1/maps/fountain/localize",
                *_multipart({"image": photo.read_bytes(), "camera": _camera_text(camera)}))
            if status == 400:  # refused from the request alone (a principal point outside)
                assert expected and expected in answers["http"]["error"], (name, answers["http"])
                del answers["http"]
            else:
                assert status == 200, (name, answers["http"])
            # The advice never makes it worse: refining the focal length (what a focal-length
            # refusal offers) gives no pose or a right one, the principal point checked after.
            answers["python refine_focal"] = localizer.localize_image(
                photo, camera, with_inliers=False, refine_focal=True)
            for who, r in answers.items():
                if expected is None and who != "python refine_focal":
                    assert r["success"], (name, who, r.get("reason"))
                if r["success"]:  # a success must be right
                    rot = _rotation_deg(r["q"], truth["q"]) if "turned" not in name else None
                    pos = float(np.linalg.norm(_centre(r) - _centre(truth)))
                    assert rot is not None and rot < RIGHT_DEG and pos < RIGHT_M, \
                        (name, who, rot, pos)
                    # The reported uncertainty covers the error (3 sigma).
                    assert rot <= 3 * r["uncertainty"]["rotation_deg"] + 0.02, (name, who, r)
                    continue
                assert expected is not None or who == "python refine_focal", (name, who)
                if who != "python refine_focal":
                    assert expected in r["reason"], (name, who, r["reason"])
                assert "q" not in r and "t" not in r, (name, who)
    finally:
        server.close()
