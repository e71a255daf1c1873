"""LineCloud, lift and read_colmap_model: the CLI's files and rules, from Python."""

import json
import os
import sys

from pathlib import Path

import numpy as np
import pytest

import linecloud as lc
from conftest import run_cli


def test_read_write_round_trip_and_arrays(demo, tmp_path):
    cloud = lc.LineCloud.read(demo / "map.lcm")
    n = len(cloud)
    assert n > 500 and cloud.lines.shape == (n, 6) and cloud.lines.dtype == np.float64
    assert cloud.ids.shape == (n,) and cloud.ids.dtype == np.uint64
    v = cloud.lines[:, :3]
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1, atol=1e-12)
    np.testing.assert_allclose(np.einsum("ij,ij->i", v, cloud.lines[:, 3:]), 0, atol=1e-9)
    cloud.write(tmp_path / "copy.lcm")
    assert (tmp_path / "copy.lcm").read_bytes() == (demo / "map.lcm").read_bytes()
    again = lc.LineCloud.read(str(tmp_path / "copy.lcm"))
    assert np.array_equal(again.lines, cloud.lines) and np.array_equal(again.ids, cloud.ids)


def test_info_is_the_clis(demo):
    cloud = lc.LineCloud.read(demo / "map.lcm")
    cli = json.loads(run_cli("info", "--map", demo / "map.lcm", "--json"))
    for key in ("file", "file_bytes", "bytes_per_line"):
        cli.pop(key)
    assert cloud.info() == cli


def test_a_cloud_from_arrays_is_checked(tmp_path):
    rng = np.random.default_rng(0)
    v = rng.normal(size=(20, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    lines = np.hstack([v, np.cross(rng.normal(size=(20, 3)), v)])
    desc = rng.integers(0, 255, size=(20, 128), dtype=np.uint8)
    cloud = lc.LineCloud(lines, np.arange(20, dtype=np.uint64), desc)
    cloud.write(tmp_path / "a.lcm")
    back = lc.LineCloud.read(tmp_path / "a.lcm")
    assert np.array_equal(back.descriptors, desc)
    bad = lines.copy()
    bad[3, 0] = np.nan
    with pytest.raises(ValueError, match=r"lines\[3, 0\]: not a finite number"):
        lc.LineCloud(bad, np.arange(20))
    with pytest.raises(ValueError, match="line id 0 appears twice"):
        lc.LineCloud(lines, np.zeros(20, dtype=np.uint64))
    with pytest.raises(ValueError, match="ids: 19 ids for 20 lines"):
        lc.LineCloud(lines, np.arange(19))
    with pytest.raises(TypeError, match="descriptors: expected uint8"):
        lc.LineCloud(lines, np.arange(20), desc.astype(np.float32))
    with pytest.raises(ValueError, match="expected an N x 6 array"):
        lc.LineCloud(lines[:, :5], np.arange(20))
    # Strided input is read as the same lines.
    wide = np.zeros((20, 12))
    wide[:, ::2] = lines
    assert np.array_equal(lc.LineCloud(wide[:, ::2], np.arange(20)).lines,
                          lc.LineCloud(lines, np.arange(20)).lines)


def test_bad_files_raise_oserror_or_valueerror_naming_them(tmp_path, demo):
    with pytest.raises(FileNotFoundError, match="missing.lcm"):
        lc.LineCloud.read(tmp_path / "missing.lcm")
    with pytest.raises(IsADirectoryError):
        lc.LineCloud.read(tmp_path)
    truncated = tmp_path / "truncated.lcm"
    truncated.write_bytes((demo / "map.lcm").read_bytes()[:1000])
    with pytest.raises(ValueError, match="truncated.lcm"):
        lc.LineCloud.read(truncated)
    with pytest.raises(TypeError):
        lc.LineCloud.read(42)


def test_lift_follows_the_key_store_rules(demo, tmp_path, key_store):
    out = tmp_path / "py.lcm"
    cloud = lc.lift(demo / "model", out=out)
    assert out.exists() and len(cloud) == len(lc.LineCloud.read(out))
    # The CLI with the same store: the model's one key, the same lines.
    run_cli("lift", "--model", demo / "model", "--out", tmp_path / "cli.lcm", "--quiet",
            env={"LINECLOUD_KEY_STORE": str(key_store)})
    cli = lc.LineCloud.read(tmp_path / "cli.lcm")
    assert np.array_equal(cli.lines, cloud.lines) and np.array_equal(cli.ids, cloud.ids)
    # Lifting again without an output: the same lines, nothing written.
    again = lc.lift(demo / "model")
    assert np.array_equal(again.lines, cloud.lines)
    # Another key for the same model is refused: its lines would meet the first ones.
    with pytest.raises(ValueError, match="lifted before with the key"):
        lc.lift(demo / "model", key_file=tmp_path / "other.key")
    assert not (tmp_path / "other.key").exists()
    # A different store: a different key, different lines.
    other = lc.lift(demo / "model", key_store=tmp_path / "other-store")
    assert not np.allclose(other.lines[:, :3], cloud.lines[:, :3])


def test_lift_takes_a_pycolmap_reconstruction(demo, tmp_path):
    """[newcomer] lift(pycolmap.Reconstruction): any object that writes a COLMAP model into a
    folder (Reconstruction.write(path)) is lifted as that folder is — the same key, the same
    lines — and its temporary folder is gone afterwards."""
    import shutil

    class Reconstruction:  # pycolmap's interface, without pycolmap (no PyPI here)
        written = []

        def write(self, path):
            shutil.copytree(demo / "model", path, dirs_exist_ok=True)
            self.written.append(Path(path))

    store = tmp_path / "store"
    from_folder = lc.lift(demo / "model", key_store=store)
    from_object = lc.lift(Reconstruction(), key_store=store)
    assert np.array_equal(from_object.lines, from_folder.lines)
    assert np.array_equal(from_object.ids, from_folder.ids)
    assert Reconstruction.written and not Reconstruction.written[0].exists()
    # help() names what lift and the Localizer take (pybind11 showed "handle").
    assert "pycolmap.Reconstruction" in lc.lift.__doc__.splitlines()[0]
    for f in (lc.lift, lc.Localizer.localize_image, lc.Localizer.localize_features, lc.estimate_pose,
              lc.attack, lc.audit):
        assert "handle" not in f.__doc__.splitlines()[0], f.__doc__.splitlines()[0]
    assert "numpy.ndarray" in lc.Localizer.localize_image.__doc__.splitlines()[0]
    # An object that is neither a path nor writes a model: a TypeError naming what is taken.
    with pytest.raises(TypeError, match=r"folder \(str or os.PathLike\) or a pycolmap.Reconstruction, got int"):
        lc.lift(42, key_store=store)


def test_warnings_go_to_the_log_sink(demo, tmp_path, capfd, monkeypatch):
    key = tmp_path / "shared.key"
    lc.lift(demo / "model", key_store=tmp_path / "store", key_file=key)
    os.chmod(key, 0o644)
    said = []
    lc.set_log_sink(lambda level, line: said.append((level, line)))
    try:
        lc.lift(demo / "model", key_store=tmp_path / "store", key_file=key, allow_shared_key=True)
    finally:
        lc.set_log_sink(None)
    # (the key is read by the key store's check and by the lifting: one warning each time)
    assert said and set(said) == {("warning", f"{key} is readable by other users; run chmod 600 on it")}
    assert capfd.readouterr().err == ""
    # A sink that raises does not stop the work (its exception is reported as unraisable); None
    # put the default back (stderr).
    unraisable = []
    monkeypatch.setattr(sys, "unraisablehook", unraisable.append)
    lc.set_log_sink(lambda level, line: 1 / 0)
    try:
        cloud = lc.lift(demo / "model", key_store=tmp_path / "store", key_file=key, allow_shared_key=True)
    finally:
        lc.set_log_sink(None)
    assert len(cloud) > 0
    assert unraisable and all(u.exc_type is ZeroDivisionError for u in unraisable)
    lc.lift(demo / "model", key_store=tmp_path / "store", key_file=key, allow_shared_key=True)
    assert f"warning: {key} is readable by other users" in capfd.readouterr().err
    with pytest.raises(TypeError, match="callable"):
        lc.set_log_sink("stderr")


def test_read_colmap_model(demo):
    model = lc.read_colmap_model(demo / "model")
    points = model["points3D"]
    assert points["xyz"].shape == (len(points["ids"]), 3) and len(points["ids"]) > 500
    assert len(model["images"]) == 12
    image = next(iter(model["images"].values()))
    assert set(image) == {"name", "camera_id", "cam_from_world", "points2D", "point3D_ids"}
    assert image["points2D"].shape == (len(image["point3D_ids"]), 2)
    camera = model["cameras"][image["camera_id"]]
    assert set(camera) == {"model", "width", "height", "params"}
    # Every observed point id is a point of the model.
    observed = image["point3D_ids"][image["point3D_ids"] >= 0].astype(np.uint64)
    assert np.isin(observed, points["ids"]).all()
    with pytest.raises(OSError):
        lc.read_colmap_model(demo / "no-such-model")
