"""Read API of the catalog for the simulator and the scene generator; imports only duckdb and numpy.

The asset table is loaded into memory once (arrays), so sampling thousands of objects per scene costs
microseconds rather than one SQL round trip each.
"""

from __future__ import annotations

import copy
import functools
import json
import re
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import duckdb
import numpy as np

from catalogs.layout import resolve_stored
from catalogs.records import AssetRecord
from catalogs.schema import (
    ASSET_COLUMNS,
    SCHEMA_VERSION,
    CatalogCorrupt,
    CatalogError,
    CatalogLocked,
    CatalogMissing,
    CatalogSchemaError,
    stored_version,
)


class CatalogWriteFailed(CatalogError):
    """The catalog could not be written (a full disk, a size limit): the input is fine, the machine is not; exit 1."""


def catalog_error(exc: BaseException, path: str | Path) -> CatalogError:
    """The accurate CatalogError for a DuckDB failure on the catalog at `path`: locked, corrupt or not a catalog."""
    p = Path(path)
    msg = " ".join(str(exc).split())
    if "Could not set lock" in msg or "Conflicting lock" in msg:
        holder = re.search(r"Conflicting lock is held in (.+?) \(PID (\d+)\)", msg)
        who = f"process {holder.group(2)} ({holder.group(1)})" if holder else "another process"
        # Never suggest a rebuild here: the file is healthy and the other process is probably filling it.
        return CatalogLocked(
            f"catalog {p} is locked: {who} has it open for writing (an ingest or build still running?); the file is "
            f"not damaged; wait for that process to finish (or stop it), then retry"
        )
    if any(words in msg for words in ("No space left", "File too large", "Disk quota", "Could not write")):
        return CatalogWriteFailed(
            f"cannot write catalog {p}: the disk is full or the file passes a size limit ({msg}); free space or pass "
            f"a --catalog on another disk, then rerun (a catalog already at {p} is unchanged)"
        )
    if "Corrupt database file" in msg or "checksum" in msg:
        detail = re.search(r"in block at location \d+", msg)
        return CatalogCorrupt(
            f"catalog {p} is corrupt (checksum mismatch{', ' + detail.group(0) if detail else ''}): its data cannot "
            f"be read; rebuild it with `curbside catalog build --catalog {p}` (or re-run the ingest that made it) "
            f"or restore a backup"
        )
    if "not a valid DuckDB database file" in msg:
        return CatalogCorrupt(
            f"{p} is not a DuckDB database file (wrong path, or a damaged copy); pass a catalog made by "
            f"`curbside catalog build --catalog {p}` to --catalog"
        )
    if "does not exist" in msg and ("Table" in msg or "Catalog Error" in msg):
        return CatalogSchemaError(
            f"{p} is a DuckDB file but not a curbside catalog ({msg}); check --catalog, or build one with "
            f"`curbside catalog build --catalog {p}`"
        )
    return CatalogError(f"cannot read catalog {p} ({msg}); check the file and its permissions")


@contextmanager
def catalog_errors(path: str | Path) -> Iterator[None]:
    """Turn any DuckDB error raised in the block into the accurate CatalogError for the catalog at `path`."""
    try:
        yield
    except duckdb.Error as e:
        raise catalog_error(e, path) from e


def first_value(row: tuple[Any, ...] | None) -> Any:
    """The first column of a `fetchone()` row (an aggregate such as count(*) always returns one)."""
    if row is None:
        raise CatalogError("a catalog query returned no row where one was expected")
    return row[0]


def read_meta(con: duckdb.DuckDBPyConnection) -> dict[str, str]:
    """The catalog's meta table as a dict (schema version, embedding model and width, build parameters)."""
    return dict(con.execute("SELECT key, value FROM meta").fetchall())


def asset_categories(con: duckdb.DuckDBPyConnection) -> dict[str, str]:
    """Category of every asset, by asset id."""
    return dict(con.execute("SELECT asset_id, category FROM assets ORDER BY asset_id").fetchall())


def category_names(con: duckdb.DuckDBPyConnection) -> set[str]:
    """The categories that have at least one asset."""
    return {r[0] for r in con.execute("SELECT DISTINCT category FROM assets").fetchall()}


def descriptions(con: duckdb.DuckDBPyConnection) -> list[tuple[str, str, str | None]]:
    """(description_id, text, category) of the description pool, sorted by id."""
    return con.execute("SELECT description_id, text, category FROM descriptions ORDER BY description_id").fetchall()


def ranked_matches(con: duckdb.DuckDBPyConnection) -> list[tuple[str, str | None, float]]:
    """(asset_id, description category, score) of every match, best first within each category (ties by id)."""
    return con.execute(
        "SELECT m.asset_id, d.category, m.score FROM matches m JOIN descriptions d USING "
        "(description_id) ORDER BY d.category, m.score DESC, m.asset_id"
    ).fetchall()


def open_catalog(path: str | Path) -> duckdb.DuckDBPyConnection:
    """Open a catalog read-only after checking it exists and has this curbside's schema version."""
    p = Path(path)
    if not p.exists():
        raise CatalogMissing(f"no catalog at {p}; build it with `curbside catalog build --catalog {p}`")
    if p.is_dir():
        raise CatalogMissing(f"{p} is a directory, not a catalog file; pass the .duckdb file to --catalog")
    con = None
    try:
        con = duckdb.connect(str(p), read_only=True)
        meta = read_meta(con)
    except duckdb.Error as e:
        if con is not None:
            con.close()
        raise catalog_error(e, p) from e
    version = stored_version(meta)
    if version != SCHEMA_VERSION:
        con.close()
        raise CatalogSchemaError(
            f"catalog {p} has schema version {version}, this curbside reads version {SCHEMA_VERSION}; "
            f"rebuild it with `curbside catalog build --catalog {p}`"
        )
    return con


_NONE = np.empty(0, dtype=np.int64)
_NONE.setflags(write=False)
_MAX_ANSWERS = 4096
_SMALL = 64  # categories with at most this many assets are filtered in Python


@dataclass(frozen=True)
class AssetTable:
    """Column arrays of the assets table, sorted by asset_id for deterministic sampling."""

    asset_id: np.ndarray
    category: np.ndarray
    object_class: np.ndarray
    zones: list[frozenset[str]]
    size: np.ndarray  # (n, 3): depth, width, height in metres

    def __len__(self) -> int:
        return len(self.asset_id)


class CatalogReader:
    """Read-only view of a catalog: categories, sampling by category/zone/size, and file resolution."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.root = self.path.parent
        con = open_catalog(self.path)
        try:
            with catalog_errors(self.path):  # a damaged data block only shows when the rows are read
                self.meta = read_meta(con)
                cols = ", ".join(ASSET_COLUMNS)
                rows = con.execute(f"SELECT {cols} FROM assets ORDER BY asset_id").fetchall()
        finally:
            con.close()
        records: dict[str, AssetRecord] = {}
        for row in rows:
            d = dict(zip(ASSET_COLUMNS, row))
            d["params"] = json.loads(d["params"]) if d["params"] else {}
            d["zones"] = list(d["zones"])
            d["synonyms"] = list(d["synonyms"])
            records[d["asset_id"]] = AssetRecord(**d)
        self._split_views: dict[tuple[str, tuple[str, ...]], CatalogReader] = {}
        self._index(records)

    def _index(self, records: dict[str, AssetRecord]) -> None:
        """The lookup tables of `records` (all of the catalog's, or one side of its asset split)."""
        self._records = records
        recs = list(self._records.values())
        self.table = AssetTable(
            asset_id=np.array([r.asset_id for r in recs], dtype=object),
            category=np.array([r.category for r in recs], dtype=object),
            object_class=np.array([r.object_class for r in recs], dtype=object),
            zones=[frozenset(r.zones) for r in recs],
            size=np.array([r.size for r in recs], dtype=np.float64).reshape(-1, 3),
        )
        categories = self.table.category.astype(str)
        self._by_category: dict[str, np.ndarray] = {
            str(c): np.flatnonzero(categories == c) for c in np.unique(categories)
        }
        # Per category: its sizes and, per zone, which of its assets allow it, so a query is a few array
        # comparisons; answers are cached because the generator asks the same few questions thousands of times.
        self._sizes = {c: self.table.size[ix] for c, ix in self._by_category.items()}
        self._rows = {
            c: [(int(i), *map(float, self.table.size[i]), self.table.zones[i]) for i in ix]
            for c, ix in self._by_category.items()
            if len(ix) <= _SMALL
        }
        self._in_zone: dict[tuple[str, str], np.ndarray] = {}
        self._answers: dict[tuple[Any, ...], np.ndarray] = {}
        self._fits: dict[tuple[tuple[str, ...], str | None], tuple[np.ndarray, np.ndarray]] = {}

    def __len__(self) -> int:
        return len(self.table)

    def asset_split(self, side: str, held_out_categories: tuple[str, ...] = ()) -> CatalogReader:
        """A view of one side of the catalog's asset split: `held_out` (what the unseen and finetune scene splits draw
        from) or `seen` (train and test). Per category, the assets are ordered by the CRC-32 of their id and the first
        fifth (rounded up; none for a category of one asset) is held out: deterministic, whatever the catalog's order,
        and an asset keeps its side when others are added. Categories in `held_out_categories` (which seen scenes
        never place) are held out whole. Views are kept: a dataset asks for the same side scene after scene."""
        if side not in ("seen", "held_out"):
            raise ValueError(f"unknown asset split side {side!r}; valid: seen, held_out")
        key = (side, tuple(sorted(held_out_categories)))
        if key in self._split_views:
            return self._split_views[key]
        held: set[str] = set()
        for category, ix in self._by_category.items():
            ids = sorted((str(self.table.asset_id[i]) for i in ix), key=lambda a: (zlib.crc32(a.encode()), a))
            if category in held_out_categories:
                held.update(ids)
            elif len(ids) >= 2:
                held.update(ids[: -(-len(ids) // 5)])
        view = copy.copy(self)
        view._split_views = {}
        view._index({a: r for a, r in self._records.items() if (a in held) == (side == "held_out")})
        self._split_views[key] = view
        return view

    def categories(self) -> dict[str, int]:
        """Number of assets per category, sorted by category name."""
        return {c: len(ix) for c, ix in sorted(self._by_category.items())}

    def get(self, asset_id: str) -> AssetRecord:
        """Return one asset by id, or raise KeyError naming it."""
        try:
            return self._records[asset_id]
        except KeyError:
            raise KeyError(f"asset {asset_id!r} is not in catalog {self.path}") from None

    def candidates(
        self,
        category: str,
        *,
        zone: str | None = None,
        max_depth: float | None = None,
        max_width: float | None = None,
        max_height: float | None = None,
    ) -> np.ndarray:
        """Indices (into `table`) of the assets of `category` that fit the zone and the size limits (read-only)."""
        key = (category, zone, max_depth, max_width, max_height)
        hit = self._answers.get(key)
        if hit is not None:
            return hit
        ix = self._by_category.get(category)
        if ix is None or len(ix) == 0:
            return _NONE
        if len(ix) <= _SMALL:
            # A few assets: a Python filter costs less than building numpy masks.
            out = np.array(
                [
                    i
                    for i, d, w, h, zs in self._rows[category]
                    if (zone is None or zone in zs)
                    and (max_depth is None or d <= max_depth)
                    and (max_width is None or w <= max_width)
                    and (max_height is None or h <= max_height)
                ],
                dtype=np.int64,
            )
        else:
            keep = np.ones(len(ix), dtype=bool)
            size = self._sizes[category]
            for axis, limit in enumerate((max_depth, max_width, max_height)):
                if limit is not None:
                    keep &= size[:, axis] <= limit
            if zone is not None:
                in_zone = self._in_zone.get((category, zone))
                if in_zone is None:
                    in_zone = np.array([zone in self.table.zones[i] for i in ix], dtype=bool)
                    self._in_zone[(category, zone)] = in_zone
                keep &= in_zone
            out = ix[keep]
        out.setflags(write=False)  # shared by every caller asking the same question
        if len(self._answers) >= _MAX_ANSWERS:
            self._answers.clear()  # size limits vary per scene; a long dataset run must not grow without bound
        self._answers[key] = out
        return out

    def sample(
        self,
        rng: np.random.Generator,
        category: str,
        *,
        zone: str | None = None,
        max_depth: float | None = None,
        max_width: float | None = None,
        max_height: float | None = None,
    ) -> AssetRecord | None:
        """Draw one asset of `category` that fits, uniformly with `rng`; None when nothing fits."""
        ix = self.candidates(category, zone=zone, max_depth=max_depth, max_width=max_width, max_height=max_height)
        if len(ix) == 0:
            return None
        return self._records[self.table.asset_id[ix[int(rng.integers(len(ix)))]]]

    def by_depth(self, categories: tuple[str, ...], zone: str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Per category of `categories`, its assets allowed in `zone` sorted by depth: table indices [C, M] (-1 pads)
        and sizes [C, M, 3] (inf pads), so "the assets no deeper than d" is a prefix of each row (read-only)."""
        hit = self._fits.get((categories, zone))
        if hit is not None:
            return hit
        rows = [self.candidates(c, zone=zone) for c in categories]
        m = max([len(r) for r in rows] + [1])
        index = np.full((len(categories), m), -1, dtype=np.int64)
        size = np.full((len(categories), m, 3), np.inf)
        for k, r in enumerate(rows):
            r = r[np.argsort(self.table.size[r, 0], kind="stable")]  # ties keep the table's (asset id) order
            index[k, : len(r)] = r
            size[k, : len(r)] = self.table.size[r]
        index.setflags(write=False)
        size.setflags(write=False)
        self._fits[(categories, zone)] = (index, size)
        return index, size

    def resolve(self, relative: str | None) -> Path | None:
        """Absolute path of a file recorded relative to the catalog's directory (None stays None)."""
        return resolve_stored(relative, self.root)


def read_catalog(path: str | Path) -> CatalogReader:
    """The catalog at `path`, read once a process: envs generate and build a scene at every reset from the same file,
    and reading it costs a tenth of a second. The file's mtime and size key the read, so a rebuilt catalog is read
    again. A reader's state is its lookups' memo, so sharing one changes no scene."""
    try:
        stat = Path(path).stat()
    except OSError:  # the reader names what is missing and how to build it
        return CatalogReader(path)
    return _read_catalog(str(path), stat.st_mtime_ns, stat.st_size)


@functools.lru_cache(maxsize=4)
def _read_catalog(path: str, mtime_ns: int, size: int) -> CatalogReader:
    return CatalogReader(path)
