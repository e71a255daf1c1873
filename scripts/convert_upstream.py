#!/usr/bin/env python3
"""Makes the data folder (docs/data.md) from the public upstream repositories, for
scripts/get_data.sh --upstream.

    convert_upstream.py SRC OUT

SRC holds checkouts of the three upstream repositories:
  SRC/SfM_quality_evaluation  openMVG's copy of Strecha et al., "On benchmarking camera calibration
                              and multi-view stereo for high resolution imagery", CVPR 2008:
                              fountain-P11, Herz-Jesus-P8, entry-P10 (3072x2048 JPEG, K.txt,
                              gt_dense_cameras/*.camera)
  SRC/kapture                 naver/kapture: samples/maupertuis/colmap (a COLMAP project, BSD-3)
  SRC/Kimera-VIO              MIT-SPARK/Kimera-VIO: tests/data/MicroEurocDataset (EuRoC V1_01_easy,
                              Burri et al., IJRR 2016; the data belong to ASL, ETH Zurich)

OUT receives the layout `linecloud eval prepare` reads. Text files, COLMAP files and sensor files
come out byte for byte as scripts/data.sha256 lists them. Images are re-encoded (Strecha at half
size, EuRoC's PNG frames as JPEG), so their bytes depend on the JPEG library; get_data.sh checks
them by count, size and pixels instead.
"""
import functools
import importlib.util
import os
import shutil
import sys

import cv2
import numpy as np

STRECHA = ["fountain-P11", "Herz-Jesus-P8", "entry-P10"]
STRECHA_SIZE = (1536, 1024)  # half of the original 3072 x 2048
STRECHA_JPEG_QUALITY = 92
EUROC_JPEG_QUALITY = 95   # gives the same pixels as the copy the tests were calibrated on
EUROC_STEP = 3            # every 3rd frame of the 95 in the micro sequence
EUROC_QUERY_EVERY = 4     # every 4th kept frame, from the 3rd, is a query pair
EUROC_IMU_ROWS = 1048     # the IMU samples kept in meta/imu0_window.csv


def fail(message):
    print(f"error: {message}", file=sys.stderr)
    sys.exit(1)


def read_text(path):
    if not os.path.isfile(path):
        fail(f"{path}: missing (is the upstream checkout complete?)")
    with open(path, encoding="utf-8") as f:
        return f.read()


def write_text(path, text):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(text)


def write_jpeg(path, image, quality):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    if not cv2.imwrite(path, image, [cv2.IMWRITE_JPEG_QUALITY, quality]):
        fail(f"{path}: could not write the JPEG")


def read_image(path):
    image = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if image is None:
        fail(f"{path}: not an image OpenCV can read")
    return image


@functools.cache
def _load_pose_module():
    """The package's pose conversions (python/linecloud/pose.py: numpy only, no compiled module)."""
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python", "linecloud", "pose.py")
    spec = importlib.util.spec_from_file_location("linecloud_pose", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def rotation_to_quaternion(R):
    """(w, x, y, z), w >= 0, of the rotation nearest R (Shepperd's method, then normalised: the
    laser-scan rotations are stored to 6 digits)."""
    q = _load_pose_module()._quaternion_from_matrix(R)
    return q / np.linalg.norm(q)


def read_strecha_camera(path):
    """A .camera file: K (3 rows), distortion, R = world_from_cam (3 rows), centre, width height."""
    rows = [line.split() for line in read_text(path).splitlines() if line.strip()]
    try:
        values = [[float(v) for v in row] for row in rows]
    except ValueError:
        fail(f"{path}: a value is not a number")
    if len(values) != 9 or any(len(r) != 3 for r in values[:8]) or len(values[8]) != 2:
        fail(f"{path}: expected 3 rows of K, distortion, 3 rows of R, the centre, width height")
    K = np.array(values[0:3])
    world_from_cam = np.array(values[4:7])
    centre = np.array(values[7])
    cam_from_world = world_from_cam.T
    return K, cam_from_world, -cam_from_world @ centre, values[8]


def strecha_scene(src, out, scene):
    folder = os.path.join(src, "SfM_quality_evaluation", "Benchmarking_Camera_Calibration_2008", scene)
    names = sorted(n for n in os.listdir(os.path.join(folder, "images")) if n.endswith(".jpg"))
    if not names:
        fail(f"{folder}/images: no .jpg images")
    K = None
    gt = ["# Ground-truth cam_from_world of every image (COLMAP images.txt layout, no 2D points).",
          "# Units: metres (Strecha laser-scan frame).",
          "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME"]
    for image_id, name in enumerate(names, start=1):
        K_i, R, t, size = read_strecha_camera(os.path.join(folder, "gt_dense_cameras", name + ".camera"))
        K = K_i if K is None else K
        scale = STRECHA_SIZE[0] / size[0]
        if abs(STRECHA_SIZE[1] / size[1] - scale) > 1e-12:
            fail(f"{folder}/gt_dense_cameras/{name}.camera: size {size} is not {STRECHA_SIZE} scaled")
        q = rotation_to_quaternion(R)
        gt.append(f"{image_id} " + " ".join(f"{v:.12f}" for v in q) + " "
                  + " ".join(f"{v:.9f}" for v in t) + f" 1 {name}")
        gt.append("")
        image = read_image(os.path.join(folder, "images", name))
        if (image.shape[1], image.shape[0]) != tuple(int(v) for v in size):
            fail(f"{folder}/images/{name}: {image.shape[1]}x{image.shape[0]}, the .camera says {size}")
        write_jpeg(os.path.join(out, "strecha", scene, "images", name),
                   cv2.resize(image, STRECHA_SIZE, interpolation=cv2.INTER_AREA), STRECHA_JPEG_QUALITY)
    # Pixel centres at half-integers: x' = (x + 0.5) * s - 0.5.
    fx, fy = K[0, 0] * scale, K[1, 1] * scale
    cx, cy = (K[0, 2] + 0.5) * scale - 0.5, (K[1, 2] + 0.5) * scale - 0.5
    write_text(os.path.join(out, "strecha", scene, "cameras.txt"),
               "# Camera list with one line of data per camera:\n"
               "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
               f"1 PINHOLE {STRECHA_SIZE[0]} {STRECHA_SIZE[1]} {fx:.6f} {fy:.6f} {cx:.6f} {cy:.6f}\n")
    write_text(os.path.join(out, "strecha", scene, "gt", "images.txt"), "\n".join(gt) + "\n")
    groups = [" ".join(names[i:i + 2]) for i in range(0, len(names), 2)]
    write_text(os.path.join(out, "strecha", scene, "queries.txt"),
               "# One query group per line (consecutive images). Each group is localized against the map\n"
               "# built from all images outside that group. Single-image methods use each image of a group.\n"
               + "\n".join(groups) + "\n")


def maupertuis(src, out):
    folder = os.path.join(src, "kapture", "samples", "maupertuis", "colmap")
    for rel in ["colmap.db", "reconstruction/cameras.txt", "reconstruction/images.txt",
                "reconstruction/points3D.txt"] + [f"images/{i:02d}.jpg" for i in range(4)]:
        source = os.path.join(folder, rel)
        if not os.path.isfile(source):
            fail(f"{source}: missing (is the kapture checkout complete?)")
        os.makedirs(os.path.dirname(os.path.join(out, "colmap-maupertuis", rel)), exist_ok=True)
        shutil.copyfile(source, os.path.join(out, "colmap-maupertuis", rel))


def opencv_camera_line(camera_id, sensor_yaml):
    """cameras.txt's OPENCV line from a EuRoC sensor.yaml (intrinsics, distortion, resolution)."""
    fields = {}
    for line in read_text(sensor_yaml).splitlines():
        if ":" in line and "[" in line and not line.lstrip().startswith("#"):
            key, value = line.split(":", 1)
            fields[key.strip()] = value.split("#")[0].strip().strip("[]").replace(" ", "").split(",")
    try:
        fu, fv, cu, cv = fields["intrinsics"]
        width, height = fields["resolution"]
        distortion = fields["distortion_coefficients"]
    except (KeyError, ValueError):
        fail(f"{sensor_yaml}: no intrinsics, resolution or distortion_coefficients")
    return f"{camera_id} OPENCV {width} {height} {fu} {fv} {cu} {cv} " + " ".join(distortion)


def euroc(src, out):
    folder = os.path.join(src, "Kimera-VIO", "tests", "data", "MicroEurocDataset")
    mav = os.path.join(folder, "mav0")
    dest = os.path.join(out, "euroc-v101-micro")
    stamps = [line.split(",")[0] for line in read_text(os.path.join(mav, "cam0", "data.csv")).splitlines()
              if line and not line.startswith("#")]
    kept = stamps[::EUROC_STEP]
    for stamp in kept:
        for cam in (0, 1):
            image = read_image(os.path.join(mav, f"cam{cam}", "data", stamp + ".png"))
            write_jpeg(os.path.join(dest, "images", f"{stamp}_c{cam}.jpg"), image, EUROC_JPEG_QUALITY)
    write_text(os.path.join(dest, "cameras.txt"),
               "# CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[] (from meta/cam0_sensor.yaml, meta/cam1_sensor.yaml)\n"
               + opencv_camera_line(1, os.path.join(mav, "cam0", "sensor.yaml")) + "\n"
               + opencv_camera_line(2, os.path.join(mav, "cam1", "sensor.yaml")) + "\n")
    write_text(os.path.join(dest, "image_cameras.txt"),
               "# NAME CAMERA_ID  (images *_c0 are camera 1, *_c1 camera 2)\n"
               + "".join(f"{s}_c0.jpg 1\n{s}_c1.jpg 2\n" for s in kept))
    write_text(os.path.join(dest, "queries.txt"),
               "# One query group per line: a stereo pair (a calibrated 2-camera rig, see meta/*_sensor.yaml T_BS)\n"
               + "".join(f"{s}_c0.jpg {s}_c1.jpg\n" for s in kept[2::EUROC_QUERY_EVERY]))
    os.makedirs(os.path.join(dest, "meta"), exist_ok=True)
    for source, name in [("body.yaml", "body.yaml"), ("cam0/sensor.yaml", "cam0_sensor.yaml"),
                         ("cam1/sensor.yaml", "cam1_sensor.yaml"), ("imu0/sensor.yaml", "imu0_sensor.yaml")]:
        shutil.copyfile(os.path.join(mav, source), os.path.join(dest, "meta", name))
    shutil.copyfile(os.path.join(folder, "LICENSE.md"), os.path.join(dest, "meta", "LICENSE_from_KimeraVIO.md"))
    imu = read_text(os.path.join(mav, "imu0", "data.csv")).splitlines(keepends=True)
    write_text(os.path.join(dest, "meta", "imu0_window.csv"), "".join(imu[:1 + EUROC_IMU_ROWS]))


def main():
    if len(sys.argv) != 3:
        fail("usage: convert_upstream.py SRC OUT (see the docstring)")
    src, out = sys.argv[1], sys.argv[2]
    try:
        convert(src, out)
    except OSError as e:  # e.g. a file where a folder of the layout goes
        fail(f"{e.filename or out}: {e.strerror}")


def convert(src, out):
    for scene in STRECHA:
        print(f"  strecha/{scene}", flush=True)
        strecha_scene(src, out, scene)
    print("  colmap-maupertuis", flush=True)
    maupertuis(src, out)
    print("  euroc-v101-micro", flush=True)
    euroc(src, out)


if __name__ == "__main__":
    main()
