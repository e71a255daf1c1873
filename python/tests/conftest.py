"""Fixtures of the Python suite: the built CLI (to compare with), a seeded
demo scene, a key store per test, and fountain-P11 when CI's work exists."""

import json
import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _binary() -> Path:
    """The package's own command-line tool (installed with it), or LINECLOUD_BINARY."""
    if os.environ.get("LINECLOUD_BINARY"):
        path = Path(os.environ["LINECLOUD_BINARY"])
    else:
        import linecloud
        path = Path(linecloud.cli_path())
    if not path.exists():
        pytest.fail(f"the linecloud tool is not at {path}")
    return path


@pytest.fixture(scope="session")
def binary() -> Path:
    return _binary()


def run_cli(*args, env=None) -> str:
    """Runs the CLI, returns its standard output; fails the test on an error."""
    full_env = dict(os.environ, **(env or {}))
    r = subprocess.run([str(_binary()), *map(str, args)], capture_output=True, text=True,
                       env=full_env, check=False)
    assert r.returncode == 0, f"linecloud {' '.join(map(str, args))}: {r.stderr}"
    return r.stdout


@pytest.fixture(scope="session")
def demo(tmp_path_factory) -> Path:
    """`linecloud demo` (seed 42): a COLMAP model, its line cloud under the public
    demo key and query files."""
    out = tmp_path_factory.mktemp("demo") / "demo"
    run_cli("demo", "--out", out, "--points", 1500, "--images", 12, "--queries", 4)
    return out


@pytest.fixture(autouse=True)
def key_store(tmp_path, monkeypatch) -> Path:
    """Each test its own key store (never the user's)."""
    store = tmp_path / "keys"
    monkeypatch.setenv("LINECLOUD_KEY_STORE", str(store))
    return store


def fixed_key(folder: Path, byte: str = "5a") -> Path:
    """A fixed, public test key in `folder` (lines, matches and answers the same on every run;
    a random key made some answers key-dependent). Never for a real map."""
    key = Path(folder) / f"fixed-{byte}.key"
    key.write_text(f"# fixed public test key\ndirections sphere\n{byte * 32}\n")
    key.chmod(0o600)
    return key


def data_dir() -> Path:
    """The real data sets, by the rule of docs/data.md: $LINECLOUD_DATA, else ../shared/data
    beside the checkout where it exists, else data/ in the checkout (scripts/get_data.sh)."""
    if os.environ.get("LINECLOUD_DATA"):
        return Path(os.environ["LINECLOUD_DATA"])
    beside = REPO.parent / "shared" / "data"
    return beside if beside.is_dir() else REPO / "data"


def skip_or_fail(reason: str):
    """A missing prerequisite: a skip, or a failure under the test command
    (LINECLOUD_REQUIRE_ALL=1: a part that could not run is an error there)."""
    if os.environ.get("LINECLOUD_REQUIRE_ALL") == "1":
        pytest.fail(f"required but absent: {reason}")
    pytest.skip(reason)


@pytest.fixture(scope="session")
def fountain():
    """CI's `eval prepare` work of fountain-P11 (LINECLOUD_FOUNTAIN_WORK, else
    build/eval/fountain-P11): group g00's map (built without 0000.jpg), its
    database, the photo and its true pose."""
    work = Path(os.environ.get("LINECLOUD_FOUNTAIN_WORK", REPO / "build" / "eval" / "fountain-P11"))
    if not (work / "prepared.json").exists():
        skip_or_fail(f"no eval prepare work of fountain-P11 at {work} (scripts/run.sh test "
                     "prepares it; or set LINECLOUD_FOUNTAIN_WORK)")
    prepared = json.loads((work / "prepared.json").read_text())
    image = prepared["groups"][0]["images"][0]
    assert image["name"] == "0000.jpg"
    # Through the data locator: the work's dataset_dir is where the data was when it was
    # prepared, and data folders move.
    photo = data_dir() / "strecha" / "fountain-P11" / "images" / "0000.jpg"
    if not photo.exists():
        skip_or_fail(f"the fountain-P11 photo is absent: {photo} (scripts/get_data.sh, or set "
                     "LINECLOUD_DATA)")
    return {
        "model": work / "groups" / "g00" / "map",
        "database": work / "colmap" / "database.db",
        "photo": photo,
        "truth": image["cam_from_world"],
        "camera": {"model": "PINHOLE", "width": 1536, "height": 1024,
                   "params": [1379.74, 1382.08, 760.095, 503.155]},
    }
