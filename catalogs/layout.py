"""Where a catalog and its files live: the default catalog path and the layout of its asset folder.

Every file path a catalog stores is relative to the directory that holds the catalog file; the files themselves
sit in `<stem>_assets/` beside it: procedural assets in `<category>/<seed>/`, retrieved ones in
`retrieval/<source>/<slug of source_id>/`. Only pathlib and re: cheap to import from the CLI and the simulator.
"""

from __future__ import annotations

import re
from pathlib import Path

DEFAULT_CATALOG = "catalogs/default.duckdb"
# The retrieval pipeline keeps a CLIP image embedding here when its width differs from the catalog's vectors.
IMAGE_EMBEDDING_FILE = "image_embedding.npy"


def asset_root(catalog_path: str | Path) -> Path:
    """Directory that holds the files (meshes, views) of the catalog at `catalog_path`."""
    p = Path(catalog_path)
    return p.parent / f"{p.stem}_assets"


def procedural_asset_dir(root: str | Path, category: str, seed: int) -> Path:
    """Folder of one procedural asset under an asset root (named like its id, procedural/<category>/<seed>)."""
    return Path(root) / category / f"{int(seed):04d}"


def retrieved_asset_dir(root: str | Path, source: str, source_id: str) -> Path:
    """Folder of one retrieved asset under an asset root (or a pipeline stage's folder laid out the same way)."""
    slug = re.sub(r"[^A-Za-z0-9._-]+", "_", source_id).strip("_")[:80] or "asset"
    return Path(root) / "retrieval" / source / slug


def stored_path(path: str | Path, catalog_dir: str | Path) -> str:
    """The posix path a catalog stores for `path`: relative to `catalog_dir`; ValueError when outside it."""
    try:
        return Path(path).relative_to(catalog_dir).as_posix()
    except ValueError:
        pass
    # One side relative and the other absolute (or a symlinked folder): compare the real locations.
    root = Path(catalog_dir).resolve()
    try:
        return Path(path).resolve().relative_to(root).as_posix()
    except ValueError as e:
        raise ValueError(f"{path} is not inside the catalog directory {root}; export assets under it") from e


def resolve_stored(relative: str | None, catalog_dir: str | Path) -> Path | None:
    """Path of a file recorded relative to `catalog_dir` (absolute paths kept, None stays None)."""
    if relative is None:
        return None
    p = Path(relative)
    return p if p.is_absolute() else Path(catalog_dir) / p
