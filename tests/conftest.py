"""Shared fixtures: a real small catalog built from the procedural library, and synthetic catalog helpers.

Environment for the whole suite (set at import, before any test module imports a library): offline hubs,
no DVC telemetry, headless matplotlib.
"""

from __future__ import annotations

import os

os.environ["HF_HUB_OFFLINE"] = "1"
os.environ["TRANSFORMERS_OFFLINE"] = "1"
os.environ["DVC_NO_ANALYTICS"] = "1"
os.environ["MPLBACKEND"] = "Agg"
os.environ.setdefault("HF_HUB_DISABLE_PROGRESS_BARS", "1")
os.environ.setdefault("TOKENIZERS_PARALLELISM", "false")

import shutil
import subprocess
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest


@pytest.fixture(scope="session")
def small_catalog(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Path of a real catalog: one procedural variant per category, exported files, MiniLM text embeddings.

    Session-scoped: built once per process. Under pytest-xdist every worker is its own process with its own
    base temp directory, so each worker builds its own copy and no two builds share a file. Treat it as
    read-only; copy it (see `copy_catalog`) before changing anything.
    """
    from retrieval.build import build_procedural_catalog

    path = tmp_path_factory.mktemp("small_catalog") / "small.duckdb"
    build_procedural_catalog(path, variants=1, seed=0, progress=False)
    return path


def _copy_catalog(src: Path, dst_dir: Path) -> Path:
    """Copy a catalog file and its asset folder into `dst_dir`; returns the new catalog path."""
    import shutil

    from catalogs.layout import asset_root

    dst = dst_dir / src.name
    shutil.copy2(src, dst)
    if asset_root(src).exists():
        shutil.copytree(asset_root(src), asset_root(dst))
    return dst


@pytest.fixture()
def copy_catalog(tmp_path: Path) -> Callable[[Path], Path]:
    """A function that copies a catalog (file and assets) into this test's tmp dir, for tests that modify it."""
    return lambda src: _copy_catalog(Path(src), tmp_path)


@pytest.fixture(scope="session")
def text_encoder():
    """The packaged all-MiniLM-L6-v2 text encoder, loaded once per process."""
    from retrieval.encoders.text import TextEncoder

    return TextEncoder()


@pytest.fixture()
def make_asset() -> Callable[..., object]:
    """Factory of valid synthetic AssetRecords: make_asset("a1", category="bench", height=0.9, ...)."""
    from catalogs.records import AssetRecord

    def make(asset_id: str, **overrides: object) -> AssetRecord:
        fields: dict[str, object] = dict(
            asset_id=asset_id,
            source="procedural",
            source_id=asset_id,
            category="bench",
            object_class="non_standard",
            zones=["furnishing"],
            depth=0.6,
            width=1.8,
            height=0.85,
            description=f"a wooden bench {asset_id}",
            synonyms=["seat", "park bench"],
            license="CC0-1.0",
            mass=40.0,
            params={"seed": 0},
        )
        fields.update(overrides)
        return AssetRecord(**fields)  # type: ignore[arg-type]

    return make


def unit_vectors(n: int, dim: int = 384, seed: int = 0) -> np.ndarray:
    """`n` random unit vectors (float32), deterministic in `seed`."""
    v = np.random.default_rng(seed).normal(size=(n, dim)).astype(np.float32)
    return v / np.linalg.norm(v, axis=1, keepdims=True)


@pytest.fixture()
def random_unit_vectors() -> Callable[..., np.ndarray]:
    """Factory of deterministic random unit vectors: random_unit_vectors(n, dim=384, seed=0)."""
    return unit_vectors


@pytest.fixture(scope="module")
def x_display() -> Iterator[str]:
    """A real X display from Xvfb where it is installed (the Makefile adds it when apt can), else SDL's dummy
    video driver (the same pygame window code, no X server)."""
    mp = pytest.MonkeyPatch()
    server = None
    if shutil.which("Xvfb"):
        # -displayfd: Xvfb picks a free display (xdist workers start their own) and prints it once it is ready.
        server = subprocess.Popen(
            ["Xvfb", "-displayfd", "1", "-screen", "0", "1024x768x24", "-nolisten", "tcp"],
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        mp.setenv("DISPLAY", f":{server.stdout.readline().strip()}")
        mp.delenv("SDL_VIDEODRIVER", raising=False)
    else:
        mp.setenv("SDL_VIDEODRIVER", "dummy")
    yield "xvfb" if server else "dummy"
    mp.undo()
    if server is not None:
        server.terminate()
        server.wait()
