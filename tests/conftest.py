"""Shared fixtures: a small synthetic venue rendered once per session, and a modelled store.

The data is generated at test time by our own renderer (deterministic by seed), never committed.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from omninav.lens import load_lens
from omninav.model_venue import model_video
from omninav.store import Store
from omninav.synth import Dataset, equirect_lens, make_dataset
from omninav.track import load_track

OMNINAV = str(Path(sys.executable).with_name("omninav"))


@pytest.fixture(scope="session")
def small_ds(tmp_path_factory: pytest.TempPathFactory) -> Dataset:
    """The small L-shaped venue at half resolution (480x360 donut): modelling + query walk."""
    return make_dataset(tmp_path_factory.mktemp("small"), seed=3, layout="small", scale=0.5)


@pytest.fixture(scope="session")
def modelled(small_ds: Dataset, tmp_path_factory: pytest.TempPathFactory) -> tuple[Store, str]:
    """A store with venue 'lab' modelled from the small venue's walk (default preset)."""
    st = Store(tmp_path_factory.mktemp("store"))
    st.create("lab", name="Lab", places=small_ds.scene.places)
    model_video(
        st, "lab", small_ds.model_video, load_track(small_ds.model_track), load_lens(small_ds.root / "model_lens.json")
    )
    return st, "lab"


@pytest.fixture(scope="session")
def equirect_ds(tmp_path_factory: pytest.TempPathFactory) -> Dataset:
    """The small venue modelled with a 360-camera (equirectangular) instead of the donut."""
    return make_dataset(
        tmp_path_factory.mktemp("equi"), seed=3, layout="small", scale=0.5, model_lens=equirect_lens(720)
    )


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


@pytest.fixture
def copy_store(modelled: tuple[Store, str], tmp_path: Path) -> tuple[Store, str]:
    """A private copy of the modelled store, for tests that change it."""
    st, vid = modelled
    dst = tmp_path / "data"
    shutil.copytree(st.root, dst)
    return Store(dst), vid
