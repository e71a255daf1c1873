"""attack and audit: what a line cloud gives away, as the CLI measures it."""

import json
import re

import numpy as np
import pytest

import linecloud as lc
from conftest import run_cli


def test_attack_recovers_points_on_the_lines(demo):
    cloud = lc.LineCloud.read(demo / "map.lcm")
    points = lc.attack(cloud, threads=2)
    assert points.shape == (len(cloud), 3) and points.dtype == np.float64
    # Each recovered point lies on its line: |X x v - w| = 0.
    v, w = cloud.lines[:, :3], cloud.lines[:, 3:]
    np.testing.assert_allclose(np.cross(points, v) - w, 0, atol=1e-6)
    # The same from the path, whatever the thread count.
    assert np.array_equal(lc.attack(demo / "map.lcm", threads=1), points)


def test_audit_equals_the_cli(demo, tmp_path):
    report = lc.audit(demo / "map.lcm", demo / "model", threads=2, out=tmp_path / "audit")
    cli = json.loads(run_cli("audit", "--map", demo / "map.lcm", "--model", demo / "model",
                             "--threads", 2, "--quiet"))
    for r in (report, cli):
        r["density_attack"].pop("seconds")  # the one field that differs run to run
    assert report["density_attack"] == cli["density_attack"]
    assert report["lines"] == len(lc.LineCloud.read(demo / "map.lcm"))
    # Far more points recovered within 2 % of the scene diagonal than a point
    # drawn along its line would land there by chance (~4 %; measured 22 %).
    assert report["density_attack"]["recovery"]["within_diagonal_percent"]["2"] > 0.1
    assert (tmp_path / "audit" / "report.json").exists()
    assert (tmp_path / "audit" / "audit.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _without_seconds(report):
    """The report without its timings (the fields that differ run to run)."""
    if isinstance(report, dict):
        return {k: _without_seconds(v) for k, v in report.items() if k != "seconds"}
    return report


def test_audit_takes_every_option_of_the_cli(demo, tmp_path):
    """attack's and audit's options are one table each: the CLI's flags and defaults are the
    table's, Python takes each, and both give the same report."""
    for command, table in (("attack", lc.attack_options()), ("audit", lc.audit_options())):
        help_text = run_cli(command, "--help")
        flags = set(re.findall(r"^\s+(--[a-z-]+)", help_text, re.M))
        assert {o["flag"] for o in table} <= flags, command
        own = {"--help", "--map", "--model", "--quiet", "--out", "--other", "--key-file",
               "--key-store"}
        assert flags - own == {o["flag"] for o in table}, command
        for o in table:
            if o["type"] != "true or false":
                shown = re.search(rf"^\s+{o['flag']} \S+=(\S+)", help_text, re.M)
                assert shown and float(shown.group(1)) == o["default"], (command, o["name"])
    with pytest.raises(ValueError, match=r"audit: crossing_tolerance must be a number in \(0, 0.1\)"):
        lc.audit(demo / "map.lcm", demo / "model", crossing_tolerance=0.2)
    options = {"crossing_tolerance": 2e-3, "recovered_within": 2e-4, "metric_scale": 0.5,
               "threads": 2, "neighbours": 12}
    report = lc.audit(demo / "map.lcm", demo / "model", **options)
    cli = json.loads(run_cli("audit", "--map", demo / "map.lcm", "--model", demo / "model",
                             "--crossing-tolerance", 2e-3, "--recovered-within", 2e-4,
                             "--metric-scale", 0.5, "--threads", 2, "--neighbours", 12,
                             "--quiet"))
    assert _without_seconds(report) == _without_seconds(cli)
    assert report["pairing_attacks"]["crossing_tolerance_diagonal"] == 2e-3
    assert report["density_attack"]["line_neighbours"] == 12
    with pytest.raises(ValueError, match="recovered-within|recovered_within"):
        lc.audit(demo / "map.lcm", demo / "model", recovered_within=0.5)


def test_attack_and_audit_reject_bad_options(demo, tmp_path):
    with pytest.raises(TypeError, match="unknown option 'neighbors'"):
        lc.attack(demo / "map.lcm", neighbors=5)
    with pytest.raises(ValueError, match=r"refine_rounds must be a whole number in \[0, 20\], got -1"):
        lc.attack(demo / "map.lcm", refine_rounds=-1)
    tiny = lc.LineCloud(np.array([[1.0, 0, 0, 0, 0, 0]] * 3) + [[0, 0, 0, 0, i, 0] for i in range(3)],
                        np.arange(3))
    with pytest.raises(ValueError, match="needs at least 10"):
        lc.attack(tiny)
    with pytest.raises(ValueError, match="key store .* has no key for this model"):
        lc.audit(lc.lift(demo / "model", key_store=tmp_path / "a"), demo / "model",
                 key_store=tmp_path / "b")
