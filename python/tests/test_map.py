"""lc.map: photos to a served map from Python, as `linecloud map` (docs/map.md)."""
import json

import pytest

import linecloud as lc
from conftest import data_dir, fixed_key, skip_or_fail

CAMERA = "PINHOLE 1536 1024 1379.74 1382.08 760.095 503.155"


def fountain_photos(first, last):
    folder = data_dir() / "strecha" / "fountain-P11" / "images"
    if not folder.is_dir():
        skip_or_fail(f"no fountain-P11 photos at {folder}")
    return [folder / f"{k:04d}.jpg" for k in range(first, last + 1)]


def test_map_returns_the_report_and_serves_three_files(tmp_path):
    photos = fountain_photos(0, 3)
    report = lc.map(photos, tmp_path / "project", camera=CAMERA, out=tmp_path / "maps" / "f",
                    key_file=fixed_key(tmp_path), threads=2)
    assert report["registered"] == 4 and report["photos"] == 4
    assert report["lines"] == report["points"] > 1000
    assert report["unregistered"] == []
    assert sorted(p.name for p in (tmp_path / "maps").iterdir()) == ["f.audit.json", "f.json", "f.lcm"]
    assert report == json.loads((tmp_path / "project" / "report.json").read_text())
    cloud = lc.LineCloud.read(str(tmp_path / "maps" / "f.lcm"))
    assert len(cloud) == report["lines"]
    # The same call again: every stage kept.
    again = lc.map(photos, tmp_path / "project", camera=CAMERA, out=tmp_path / "maps" / "f",
                   key_file=fixed_key(tmp_path), threads=2)
    assert [s["reused"] for s in again["stages"] if s["name"] != "photos"] == [True] * 5


def test_map_refuses_bad_input_naming_it(tmp_path):
    photos = fountain_photos(0, 1)
    with pytest.raises(ValueError, match="one photo"):
        lc.map(photos[:1], tmp_path / "p")
    cut = tmp_path / "cut.jpg"
    cut.write_bytes(photos[1].read_bytes()[:50000])
    with pytest.raises(ValueError, match=f"{cut}: the JPEG file is truncated"):
        lc.map([photos[0], cut], tmp_path / "p")
    with pytest.raises(ValueError, match="unknown option .pairz."):
        lc.map(photos, tmp_path / "p", pairz="exhaustive")
    assert not (tmp_path / "p" / "database.db").exists()
