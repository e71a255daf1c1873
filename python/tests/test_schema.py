"""[schema]: one option table for the command line, Python and the service.

The tests walk `lc.localizer_options()` (the table the CLI's flags, Python's keyword arguments and
the service's request fields are made from) and check, through the real `linecloud` binary, the
module and a real `linecloud serve` process, that the three take the same names, defaults and
ranges, and give the same pose for the same photo and options (to 1e-12)."""

import json
import os
import re
import subprocess
import sys
import textwrap
import threading
import urllib.error
import urllib.request
import uuid
from pathlib import Path

import numpy as np
import pytest

import linecloud as lc
from conftest import _binary, fixed_key, run_cli

TABLE = lc.localizer_options()
BY_NAME = {o["name"]: o for o in TABLE}

# A valid value other than the default for every option. An option added to the table without
# a value here fails test_every_option_has_a_test_value.
OTHER = {
    "features": "opencv", "max_image_size": 2000, "max_num_features": 4000,
    "max_pixels": 10_000_000, "max_ratio": 0.7, "cross_check": True, "approximate_from": 100,
    "exact_matching": True, "index": "flann", "nprobe": 8, "threads": 2,
    "map_gravity": [0.0, -1.0, 0.0], "threshold": 3.0, "seed": 7, "confidence": 0.999,
    "min_iterations": 20, "max_iterations": 5000, "max_seconds": 5.0, "uniform_sampling": True,
    "local_optimization": False, "refine": False, "refine_focal": True, "min_inliers": 40,
    "min_inlier_ratio": 0.2, "max_rotation_uncertainty": 2.0, "max_focal_discrepancy": 0.2,
    "max_principal_discrepancy": 0.02, "max_position_uncertainty": 0.03,
}


def _bad(o):
    """A value the option refuses (outside its range, not a choice, not a direction)."""
    if "choices" in o:
        return "nope"
    if o["type"].startswith("true or false"):
        return "maybe"
    if o["type"].startswith("a finite non-zero direction"):
        return [0.0, 0.0, 0.0]
    if o["type"].startswith("a whole number"):
        return int(o["max"]) * 2 + 1
    return o["max"] * 2 + 1


def _text(value):
    """A value as a flag or a multipart part writes it."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list):
        return ",".join(map(str, value))
    return str(value)


def _flag_args(options):
    args = []
    for name, value in options.items():
        o = BY_NAME[name]
        if o["type"].startswith("true or false"):
            assert value != o["default"], f"{name}: a switch only turns its default round"
            args.append(o["flag"])
        else:
            args += [o["flag"], _text(value)]
    return args


def test_every_option_has_a_test_value():
    assert set(OTHER) == set(BY_NAME)
    assert len(BY_NAME) == len(TABLE), "names are unique"
    for o in TABLE:
        assert re.fullmatch(r"[a-z][a-z_]*", o["name"]), o["name"]
        dashed = "--" + o["name"].replace("_", "-")
        assert o["flag"] in (dashed, "--no-" + dashed[2:]), o
        assert o["scope"] in ("map", "request")
        assert OTHER[o["name"]] != o["default"], o["name"]


def test_python_defaults_are_the_tables(demo):
    options = lc.Localizer(demo / "map.lcm").options
    assert options == {o["name"]: o["default"] for o in TABLE}


def test_cli_help_lists_every_option_with_its_default():
    text = run_cli("localize", "--help")
    serve = run_cli("serve", "--help")
    for o in TABLE:
        assert o["flag"] in text, o["name"]
        if o["name"] not in ("threads", "max_pixels"):  # the server's own flags, not a map's
            assert o["flag"] in serve, o["name"]
        if o["default"] is not None and not isinstance(o["default"], bool):
            shown = o["default"] if isinstance(o["default"], str) else json.dumps(o["default"])
            line = next(line for line in text.splitlines() if o["flag"] + " " in line + " ")
            assert f"={shown}" in line, (o["name"], line)


def test_every_option_is_taken_and_checked_by_python_and_the_cli(demo, tmp_path):
    query_path = sorted((demo / "queries").glob("*.json"))[0]
    query = json.loads(query_path.read_text())
    base = ["localize", "--map", demo / "map.lcm", "--query", query_path, "--quiet"]
    for o in TABLE:
        name, value, bad = o["name"], OTHER[o["name"]], _bad(o)
        # Python: the Localizer takes every option; requests take the request-scope ones.
        localizer = lc.Localizer(demo / "map.lcm", **{name: value})
        assert localizer.options[name] == value, name
        with pytest.raises(ValueError, match=rf"Localizer: {name} must be"):
            lc.Localizer(demo / "map.lcm", **{name: bad})
        if o["scope"] == "request":
            lc.Localizer(demo / "map.lcm").localize_query(query, **{name: value})
            with pytest.raises(ValueError, match=rf"localize_query: {name} must be"):
                lc.Localizer(demo / "map.lcm").localize_query(query, **{name: bad})
        elif name != "threads":  # a call's own threads= (its matching threads) is allowed
            with pytest.raises(ValueError, match=rf"'{name}' is fixed when the map is loaded"):
                lc.Localizer(demo / "map.lcm").localize_query(query, **{name: value})
        # The command line: the same option, the same check.
        out = subprocess.run([str(_binary()), *map(str, base + _flag_args({name: value}))],
                             capture_output=True, text=True, check=False)
        assert out.returncode == 0, (name, out.stderr)
        if not o["type"].startswith("true or false"):
            out = subprocess.run([str(_binary()), *map(str, base), o["flag"], _text(bad)],
                                 capture_output=True, text=True, check=False)
            assert out.returncode != 0, name
            assert f"{o['flag']}: {name} must be" in out.stderr, (name, out.stderr)
    with pytest.raises(TypeError, match="unexpected keyword argument 'thresold'"):
        lc.Localizer(demo / "map.lcm", thresold=3)
    # A switch takes no value (--uniform-sampling=0 used to turn it on).
    for flag in ("--uniform-sampling=0", "--no-refine=false", "--refine-focal=banana"):
        out = subprocess.run([str(_binary()), *map(str, base), flag], capture_output=True,
                             text=True, check=False)
        assert out.returncode != 0 and flag.split("=")[0].lstrip("-") in out.stderr, (flag,
                                                                                     out.stderr)
        assert "internal" not in out.stderr, out.stderr


# --- the service: a real `linecloud serve` on 127.0.0.1 ---------------------------------

class Served:
    def __init__(self, maps: Path, *flags):
        self.proc = subprocess.Popen(
            [str(_binary()), "serve", "--maps", str(maps), "--listen", "127.0.0.1:0",
             "--threads", "1", *map(str, flags)],
            stderr=subprocess.PIPE, text=True)
        self.port = None
        lines = []
        for line in self.proc.stderr:
            lines.append(line)
            m = re.search(r"listening on http://127\.0\.0\.1:(\d+)", line)
            if m:
                self.port = int(m.group(1))
                break
        assert self.port, "".join(lines)
        # Keep reading its log so that it never blocks on a full pipe.
        threading.Thread(target=lambda: [None for _ in self.proc.stderr], daemon=True).start()

    def post(self, path, body: bytes, content_type: str):
        req = urllib.request.Request(f"http://127.0.0.1:{self.port}{path}", data=body,
                                     headers={"Content-Type": content_type}, method="POST")
        try:
            with urllib.request.urlopen(req, timeout=60) as r:
                return r.status, json.loads(r.read())
        except urllib.error.HTTPError as e:
            return e.code, json.loads(e.read())

    def close(self):
        self.proc.terminate()
        self.proc.wait(timeout=30)


def _multipart(parts):
    boundary = uuid.uuid4().hex
    body = b""
    for name, value in parts.items():
        body += f"--{boundary}\r\nContent-Disposition: form-data; name=\"{name}\"".encode()
        if isinstance(value, bytes):
            body += b"; filename=\"photo.jpg\"\r\nContent-Type: image/jpeg\r\n\r\n" + value
        else:
            body += b"\r\n\r\n" + value.encode()
        body += b"\r\n"
    body += f"--{boundary}--\r\n".encode()
    return body, f"multipart/form-data; boundary={boundary}"


@pytest.fixture(scope="module")
def fountain_map(fountain, tmp_path_factory):
    folder = tmp_path_factory.mktemp("schema-maps")
    keys = tmp_path_factory.mktemp("schema-keys")
    lc.lift(fountain["model"], database=fountain["database"], key_file=fixed_key(keys),
            key_store=keys / "store").write(folder / "fountain.lcm")
    return folder


def _camera_text(camera):
    return " ".join([camera["model"], str(camera["width"]), str(camera["height"]),
                     *map(str, camera["params"])])


def test_every_request_option_is_taken_and_checked_by_the_service(fountain, fountain_map,
                                                                  tmp_path):
    body_path = tmp_path / "body.json"
    run_cli("features", "--image", fountain["photo"], "--camera", _camera_text(fountain["camera"]),
            "--out", body_path)
    body = json.loads(body_path.read_text())
    server = Served(fountain_map)
    try:
        status, plain = server.post("/v1/maps/fountain/localize", json.dumps(body).encode(),
                                    "application/json")
        assert status == 200 and plain["success"], plain
        for o in TABLE:
            name = o["name"]
            sent = json.dumps(dict(body, **{name: OTHER[name]})).encode()
            status, answer = server.post("/v1/maps/fountain/localize", sent, "application/json")
            if o["scope"] == "map":
                assert status == 400, (name, answer)
                assert answer["error"] == (f"body: '{name}' is fixed when the map is loaded, not "
                                           "set per request")
                continue
            assert status == 200, (name, answer)
            assert set(answer) <= {"success", "reason", "method", "pose", "q", "t", "center", "num_matches",
                                   "num_inliers", "inlier_ratio", "uncertainty", "times_ms"}
            sent = json.dumps(dict(body, **{name: _bad(o)})).encode()
            status, answer = server.post("/v1/maps/fountain/localize", sent, "application/json")
            assert status == 400, (name, answer)
            assert answer["error"].startswith(f"body: {name} must be "), answer
        # One request option changes the answer as it does in Python: seed and threshold.
        sent = json.dumps(dict(body, threshold=2.0, seed=3)).encode()
        status, answer = server.post("/v1/maps/fountain/localize", sent, "application/json")
        kp = np.array(body["keypoints"], dtype=np.float64)
        desc = np.frombuffer(__import__("base64").b64decode(body["descriptors"]),
                             np.uint8).reshape(-1, 128)
        ours = lc.Localizer(fountain_map / "fountain.lcm").localize_features(
            kp, desc, fountain["camera"], threshold=2.0, seed=3)
        np.testing.assert_allclose(answer["q"], ours["q"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(answer["t"], ours["t"], rtol=0, atol=1e-12)
        status, answer = server.post("/v1/maps/fountain/localize",
                                     json.dumps(dict(body, thresold=2)).encode(),
                                     "application/json")
        assert status == 400 and 'unknown option "thresold"' in answer["error"], answer
        # An outsider's findings: a field name with a NUL is shown escaped; a huge value is
        # cut short; an impossible combination is refused before any work, naming the options.
        status, answer = server.post("/v1/maps/fountain/localize",
                                     json.dumps(dict(body, **{"seed\u0000x": 1})).encode(),
                                     "application/json")
        assert status == 400 and '"seed\\u0000x"' in answer["error"], answer
        status, answer = server.post("/v1/maps/fountain/localize",
                                     json.dumps(dict(body, threshold="9" * 100000)).encode(),
                                     "application/json")
        assert status == 400 and len(answer["error"]) < 200, answer
        status, answer = server.post("/v1/maps/fountain/localize",
                                     json.dumps(dict(body, max_iterations=1)).encode(),
                                     "application/json")
        assert status == 400, answer
        assert answer["error"].startswith("body: RANSAC iterations: min_iterations (10)"), answer
    finally:
        server.close()


# Every option changed from its default at once (values that still localize the photo).
MAP_OPTIONS = {"max_ratio": 0.75, "nprobe": 8, "max_num_features": 6000, "max_image_size": 3000,
               "approximate_from": 1000, "index": "ivf", "features": "colmap"}
REQUEST_OPTIONS = {"threshold": 3.5, "seed": 7, "confidence": 0.9995, "min_iterations": 20,
                   "max_iterations": 4000, "uniform_sampling": True, "min_inliers": 40,
                   "min_inlier_ratio": 0.2, "max_rotation_uncertainty": 2.0,
                   "max_focal_discrepancy": 0.2, "max_principal_discrepancy": 0.02,
                   "max_position_uncertainty": 0.03}


def test_the_same_pose_through_cli_python_and_http(fountain, fountain_map, tmp_path):
    camera = fountain["camera"]
    cli = json.loads(run_cli("localize", "--map", fountain_map / "fountain.lcm", "--image",
                             fountain["photo"], "--camera", _camera_text(camera), "--quiet",
                             *_flag_args(MAP_OPTIONS), *_flag_args(REQUEST_OPTIONS)))
    assert cli["success"], cli
    # Python: every option on the Localizer, or the request's on each call.
    whole = lc.Localizer(fountain_map / "fountain.lcm", **MAP_OPTIONS, **REQUEST_OPTIONS)
    per_call = lc.Localizer(fountain_map / "fountain.lcm", **MAP_OPTIONS)
    answers = {"python": whole.localize_image(fountain["photo"], camera),
               "python per call": per_call.localize_image(fountain["photo"], camera,
                                                          **REQUEST_OPTIONS)}
    # The service: the map's options in its owner's ID.json, the request's as multipart parts.
    maps = tmp_path / "maps"
    maps.mkdir()
    (maps / "fountain.lcm").symlink_to(fountain_map / "fountain.lcm")
    (maps / "fountain.json").write_text(json.dumps({"options": MAP_OPTIONS}))
    server = Served(maps)
    try:
        parts = {"image": fountain["photo"].read_bytes(), "camera": _camera_text(camera)}
        parts.update({k: _text(v) for k, v in REQUEST_OPTIONS.items()})
        status, answers["http"] = server.post("/v1/maps/fountain/localize", *_multipart(parts))
        assert status == 200, answers["http"]
    finally:
        server.close()
    for who, r in answers.items():
        assert r["success"], (who, r)
        np.testing.assert_allclose(r["q"], cli["q"], rtol=0, atol=1e-12, err_msg=who)
        np.testing.assert_allclose(r["t"], cli["t"], rtol=0, atol=1e-12, err_msg=who)
    assert answers["python"]["num_inliers"] == cli["num_inliers"]
    # The options did change the answer: the defaults give another run.
    default = lc.Localizer(fountain_map / "fountain.lcm").localize_image(fountain["photo"], camera)
    assert default["stats"]["sampling"] == "progressive"
    assert cli["stats"]["sampling"] == "uniform"


def test_generated_files_are_the_tables():
    """The stub's Localizer signatures, docs/options.md and the OpenAPI document's request
    options are generated from the table (scripts/gen_schema.py)."""
    tool = Path(__file__).resolve().parents[2] / "scripts" / "gen_schema.py"
    r = subprocess.run([__import__("sys").executable, str(tool), "--check", "--cli",
                        str(_binary())], capture_output=True, text=True, check=False)
    assert r.returncode == 0, r.stderr


def test_lift_takes_every_option_of_the_cli(demo, tmp_path):
    """lift's options are one table: the CLI's flags and defaults are the table's, Python takes
    each keyword, and both give the same map."""
    table = lc.lift_options()
    help_text = run_cli("lift", "--help")
    flags = set(re.findall(r"^\s+(--[a-z-]+)", help_text, re.M))
    own = {"--help", "--quiet", "--model", "--out", "--database", "--key-file", "--key-store"}
    assert flags - own == {o["flag"] for o in table}
    for o in table:
        if o["type"].startswith("a number") and not o.get("null_means"):
            shown = re.search(rf"^\s+{o['flag']} \S+=(\S+)", help_text, re.M)
            assert shown and float(shown.group(1)) == o["default"], o["name"]
    with pytest.raises(TypeError, match="lift: unknown option 'sparsity'"):
        lc.lift(demo / "model", sparsity=0.3)
    with pytest.raises(ValueError, match=r"lift: same_place must be a number in \(0, 0.1\)"):
        lc.lift(demo / "model", same_place=0.5)
    # The same lifting through both: sparsified (balanced), attack-aware, with gravity.
    options = {"sparsify": 0.3, "sparsify_mode": "balanced", "resist_attack": 0.5,
               "gravity": [0.0, 0.0, -1.0], "descriptor": "mean"}
    run_cli("lift", "--model", demo / "model", "--out", tmp_path / "cli.lcm", "--quiet",
            "--sparsify", 0.3, "--sparsify-mode", "balanced", "--resist-attack", 0.5,
            "--gravity", "0,0,-1", "--descriptor", "mean")
    cli = lc.LineCloud.read(tmp_path / "cli.lcm")
    ours = lc.lift(demo / "model", **options)
    assert 0 < len(ours) < 0.75 * len(lc.lift(demo / "model"))
    np.testing.assert_array_equal(ours.ids, cli.ids)
    np.testing.assert_array_equal(ours.lines, cli.lines)
    assert ours.gravity == cli.gravity == (0.0, 0.0, -1.0)
    with pytest.raises(ValueError, match="sparsify_mode"):
        lc.lift(demo / "model", sparsify=0.3, sparsify_mode="dense")


def _interrupted_after(seconds, call):
    """Runs `call` with Ctrl-C (SIGINT) sent `seconds` after it starts; asserts it raised
    KeyboardInterrupt and returns how long it took. Python's own Ctrl-C handler, whatever the
    runner inherited: a shell's background job starts with SIGINT ignored, and Python then
    installs none (a call ran for hours)."""
    import signal
    import time
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(seconds, lambda: os.kill(os.getpid(), signal.SIGINT))
    start = time.monotonic()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            call()
    finally:
        signal.signal(signal.SIGINT, previous)
    elapsed = time.monotonic() - start
    timer.join()
    return elapsed


def test_ctrl_c_stops_a_long_localization(demo):
    """A call runs without the GIL and polls Python's signal handlers: Ctrl-C (SIGINT) ends a
    RANSAC run that would take hours within a fraction of a second."""
    query = json.loads(sorted((demo / "queries").glob("*.json"))[0].read_text())
    localizer = lc.Localizer(demo / "map.lcm")
    # max_seconds: a signal that never comes fails the test in 30 s, never hangs it.
    elapsed = _interrupted_after(0.5, lambda: localizer.localize_query(
        query, method="p6L", min_iterations=10_000_000, max_iterations=10_000_000,
        uniform_sampling=True, max_seconds=30))
    assert 0.5 <= elapsed < 3, elapsed
    # The Localizer is still fine afterwards.
    assert localizer.localize_query(query)["success"]


def test_python_and_the_cli_share_the_index_cache(fountain, fountain_map, tmp_path, monkeypatch):
    """Localizer(path) caches the map's approximate index where the CLI does: one build."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    path = fountain_map / "fountain.lcm"
    ours = lc.Localizer(path).localize_image(fountain["photo"], fountain["camera"])
    cached = list((tmp_path / "cache" / "linecloud" / "index").glob("*.index"))
    assert len(cached) == 1, cached
    stamp = cached[0].stat().st_mtime_ns
    out = subprocess.run([str(_binary()), "localize", "--map", str(path), "--image",
                          str(fountain["photo"]), "--camera", _camera_text(fountain["camera"])],
                         capture_output=True, text=True, check=True)
    assert "building the descriptor index" not in out.stderr, out.stderr
    assert cached[0].stat().st_mtime_ns == stamp
    assert json.loads(out.stdout)["q"] == ours["q"]
    # And the other way round: a second Python Localizer reads it too.
    assert lc.Localizer(path).localize_image(fountain["photo"], fountain["camera"])["q"] == ours["q"]
    assert cached[0].stat().st_mtime_ns == stamp


def test_null_is_the_maps_value_and_the_memory_estimate_uses_the_maps_sift(fountain, fountain_map,
                                                                             tmp_path):
    """A request field set to null is "not set": the map owner's value (ID.json), never the
    table's default. And a photo's SIFT memory is estimated with the map's max_image_size: under a
    64 MB budget a 1536 x 1024 photo (~500 MB of scale space at 3 200 px) is refused, and taken when
    the map's owner downscales its photos to 400 px."""
    camera = fountain["camera"]
    photo = fountain["photo"].read_bytes()
    for max_image_size, budget, want in [(None, 64, 413), (400, 64, 200)]:
        maps = tmp_path / f"maps-{max_image_size}"
        maps.mkdir()
        (maps / "fountain.lcm").symlink_to(fountain_map / "fountain.lcm")
        options = {"min_inliers": 100000}
        if max_image_size:
            options["max_image_size"] = max_image_size
        (maps / "fountain.json").write_text(json.dumps({"options": options}))
        server = Served(maps, "--memory-budget-mb", budget)
        try:
            parts = {"image": photo, "camera": _camera_text(camera)}
            status, answer = server.post("/v1/maps/fountain/localize", *_multipart(parts))
            assert status == want, answer
            if want == 413:
                assert answer["error"].startswith("image: SIFT on a 1536x1024 photo needs "), answer
                continue
            # The owner's min_inliers (100 000) holds: no pose, and null keeps it.
            assert not answer["success"] and "(option min_inliers)" in answer["reason"], answer
            for sent in ({"min_inliers": None}, {}):
                body = json.loads(run_cli_features(fountain, tmp_path))
                body.update(sent)
                status, answer = server.post("/v1/maps/fountain/localize",
                                             json.dumps(body).encode(), "application/json")
                assert status == 200 and not answer["success"], answer
                assert "(option min_inliers)" in answer["reason"], answer
            body["min_inliers"] = 30  # and a value replaces it
            status, answer = server.post("/v1/maps/fountain/localize", json.dumps(body).encode(),
                                         "application/json")
            assert status == 200 and answer["success"], answer
        finally:
            server.close()


def run_cli_features(fountain, tmp_path):
    out = tmp_path / "features.json"
    if not out.exists():
        run_cli("features", "--image", fountain["photo"], "--camera",
                _camera_text(fountain["camera"]), "--out", out)
    return out.read_text()


def test_exit_with_a_daemon_thread_inside_a_long_call(demo, tmp_path):
    """The interpreter exits cleanly (status 0, no SIGABRT) while a daemon thread is inside a
    long call: the thread, back from the call, must not take the GIL of an exiting
    interpreter (it parks; the process ends without it)."""
    script = tmp_path / "exit_inside_call.py"
    script.write_text(textwrap.dedent(f"""
        import json, sys, threading, time
        import linecloud as lc
        query = json.loads(open({str(sorted((demo / "queries").glob("*.json"))[0])!r}).read())
        localizer = lc.Localizer({str(demo / "map.lcm")!r})
        def long_call():
            localizer.localize_query(query, method="p6L", min_iterations=10_000_000,
                                     max_iterations=10_000_000, uniform_sampling=True,
                                     max_seconds=1.5)
        for _ in range(2):
            threading.Thread(target=long_call, daemon=True).start()
        time.sleep(0.3)
        print("exiting", flush=True)
        sys.exit(0)
    """))
    for _ in range(3):
        out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                             timeout=60, env=dict(os.environ))
        assert out.returncode == 0, (out.returncode, out.stderr[-2000:])
        assert out.stdout == "exiting\n", out.stdout


def test_ctrl_c_stops_a_photo_during_sift(fountain, tmp_path):
    """Ctrl-C during a photo's SIFT extraction is heard there (between the scale space's
    octaves and levels), not after it: it took 5.9 s on a large photo."""
    cv2 = pytest.importorskip("cv2")
    cloud = lc.lift(fountain["model"], database=fountain["database"], key_file=fixed_key(tmp_path),
                    key_store=tmp_path / "keys")
    localizer = lc.Localizer(cloud)
    big = tmp_path / "big.png"  # 3072 x 2048: seconds of SIFT
    cv2.imwrite(str(big), cv2.resize(cv2.imread(str(fountain["photo"])), (3072, 2048),
                                     interpolation=cv2.INTER_CUBIC))
    camera = {"model": "PINHOLE", "width": 3072, "height": 2048,
              "params": [2 * v for v in fountain["camera"]["params"]]}
    whole = localizer.localize_image(big, camera, with_inliers=False)
    extract_s = whole["times_ms"]["extract"] / 1000
    elapsed = _interrupted_after(
        0.3, lambda: localizer.localize_image(big, camera, with_inliers=False))
    # Heard within a fraction of a second of the signal, long before SIFT's end.
    assert extract_s > 1.5, whole["times_ms"]
    assert 0.3 <= elapsed < min(0.3 + 0.5, 0.6 * extract_s), (elapsed, extract_s)
    assert localizer.localize_image(fountain["photo"], fountain["camera"])["success"]


def test_ctrl_c_stops_a_photo_waiting_for_memory(fountain, tmp_path):
    """Ctrl-C is heard while a photo waits for room under set_memory_limit (polled every 50 ms),
    not only once the other photo's SIFT has finished (~0.5 s later)."""
    import time
    cloud = lc.lift(fountain["model"], database=fountain["database"], key_file=fixed_key(tmp_path),
                    key_store=tmp_path / "keys")
    localizer = lc.Localizer(cloud)
    photo, camera = fountain["photo"], fountain["camera"]
    lc.set_memory_limit(lc.photo_memory_mb(1536, 1024) * 1.2)  # room for one photo at a time
    try:
        other = threading.Thread(target=lambda: localizer.localize_image(photo, camera))
        other.start()
        time.sleep(0.15)  # the other photo is in SIFT: this one waits for room
        elapsed = _interrupted_after(0.1, lambda: localizer.localize_image(photo, camera))
        other.join()
    finally:
        lc.set_memory_limit(0)
    assert elapsed < 0.3, f"Ctrl-C heard after {elapsed:.2f} s"
