"""The `paper` density model's rows of objects, drawn and placed a batch at a time.

A row walks one band of a zone from one end to the other: each step is an object of a category designated for
the zone (or, with probability `fill_clutter`, a clutter item) at a random lateral offset, then a gap
~ Gamma(2, gap_mean / 2). Drawing a step needs nothing placed before it, so a batch of steps is drawn at once (the
categories, the assets, the offsets, the gaps) and the positions follow by a cumulative sum; only the overlap
test against what is already placed runs object by object, in row order.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import shapely

from catalogs.categories import CATEGORIES, NAMES
from sim.scene.occupancy import GAP, rects
from sim.scene.sidewalks import Sidewalk, Zone
from sim.scene.spec import round_array

if TYPE_CHECKING:
    from catalogs.reader import CatalogReader
    from sim.scene.placement import Placer

_INDEX = {c: k for k, c in enumerate(NAMES)}
_CLASS = [CATEGORIES[c].object_class for c in NAMES]
_FALLBACK = np.array([CATEGORIES[c].size for c in NAMES], dtype=np.float64)
_MAX_BATCH = 256
_NO_ASSETS = np.zeros(0, dtype=object)  # asset ids without a catalog: its indices are all -1, none is looked up


class Fits:
    """Per category (NAMES order), the assets that may stand in a zone sorted by depth, with the
    catalog-wide ones for categories the zone has none of; categories without catalog assets get their
    fallback box (index -1). Built once per catalog and zone kind (`fits_for`)."""

    def __init__(self, catalog: CatalogReader | None, zone: str) -> None:
        num_cats = len(NAMES)
        if catalog is None:
            self.zone_index = self.any_index = np.full((num_cats, 1), -1, dtype=np.int64)
            self.zone_size = self.any_size = _FALLBACK[:, None, :].copy()
            return
        zi, zs = catalog.by_depth(NAMES, zone)
        ai, as_ = catalog.by_depth(NAMES, None)
        num_cols = max(zi.shape[1], ai.shape[1])
        self.zone_index, self.zone_size = _pad(zi, zs, num_cols)
        self.any_index, self.any_size = _pad(ai, as_, num_cols)
        for k in np.flatnonzero(self.any_index[:, 0] < 0).tolist():  # not in the catalog: the fallback box
            for index, size in ((self.zone_index, self.zone_size), (self.any_index, self.any_size)):
                index[k] = -1
                size[k] = np.inf
                size[k, 0] = _FALLBACK[k]

    def pick(self, cat: np.ndarray, u: np.ndarray, max_depth: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For each drawn category: (found, table index or -1, size) of an asset no deeper than `max_depth`, drawn
        uniformly with the uniforms `u` among those allowed in the zone, else among all of the category's (the
        depth limit is per step)."""
        limit = np.asarray(max_depth, dtype=np.float64).reshape(-1, 1)
        in_zone = (self.zone_size[cat, :, 0] <= limit).sum(axis=1)
        anywhere = (self.any_size[cat, :, 0] <= limit).sum(axis=1)
        use_zone = in_zone > 0
        count = np.where(use_zone, in_zone, anywhere)
        j = np.minimum((u * count).astype(np.int64), np.maximum(count - 1, 0))
        index = np.where(use_zone, self.zone_index[cat, j], self.any_index[cat, j])
        size = np.where(use_zone[:, None], self.zone_size[cat, j], self.any_size[cat, j])
        return count > 0, index, size


_FITS: weakref.WeakKeyDictionary[Any, dict[str, Fits]] = weakref.WeakKeyDictionary()
_FITS_NO_CATALOG: dict[str, Fits] = {}


def fits_for(catalog: CatalogReader | None, zone: str) -> Fits:
    """The `Fits` of `catalog` (None: fallback boxes only) for `zone`, built on first use and kept with the catalog."""
    per_zone = _FITS_NO_CATALOG if catalog is None else _FITS.setdefault(catalog, {})
    fits = per_zone.get(zone)
    if fits is None:
        fits = per_zone[zone] = Fits(catalog, zone)
        for table in (fits.zone_index, fits.zone_size, fits.any_index, fits.any_size):
            table.setflags(write=False)  # shared by every scene drawn from this catalog
    return fits


def _pad(index: np.ndarray, size: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    extra = m - index.shape[1]
    return (
        np.pad(index, ((0, 0), (0, extra)), constant_values=-1),
        np.pad(size, ((0, 0), (0, extra), (0, 0)), constant_values=np.inf),
    )


def _cdf(placer: Placer, object_class: str, allowed: tuple[str, ...] | None) -> tuple[np.ndarray, np.ndarray] | None:
    made = placer.sampler.cdf(object_class, allowed)
    if made is None:
        return None
    return np.array([_INDEX[name] for name in made[0]], dtype=np.int64), made[1]


@dataclass(frozen=True)
class Row:
    """One band [d0, d1] of `zone` walked with mean gap `gap_mean` and clutter share `p_clutter`."""

    zone: Zone
    d0: float
    d1: float
    gap_mean: float
    p_clutter: float


def fill_rows(placer: Placer, sw: Sidewalk, rows: list[Row]) -> None:
    """Line every row of `rows` with objects (see the module docstring), all rows of the sidewalk in one pass."""
    if not rows:
        return
    rng, cl, side = placer.rng, sw.roadway.centerline, sw.side
    n_rows = len(rows)
    d0 = np.array([row_spec.d0 for row_spec in rows])
    d1 = np.array([row_spec.d1 for row_spec in rows])
    gap = np.array([row_spec.gap_mean for row_spec in rows])
    p_clutter = np.array([row_spec.p_clutter for row_spec in rows])
    max_depth = d1 - d0 - 0.05
    kinds = [row_spec.zone.kind for row_spec in rows]
    # Per row: the CDF its non-clutter steps are drawn from (rows with none draw clutter only).
    mains: dict[tuple[str, ...], int] = {}
    main_of = np.full(n_rows, -1, dtype=np.int64)
    faces = np.empty(n_rows)
    for k, row_spec in enumerate(rows):
        zkind = "furnishing" if row_spec.zone.kind == "near_road_buffer" else row_spec.zone.kind
        faces[k] = side * math.pi / 2 * (1 if zkind == "furnishing" else -1)  # furnishing faces the walkway
        allowed = tuple(
            cat_idx
            for cat_idx, row in CATEGORIES.items()
            if row.object_class != "clutter"
            and zkind in row.zones
            and cat_idx != "building_facade"
            and placer.min_depth[cat_idx] <= max_depth[k]
        )
        ns = tuple(cat_idx for cat_idx in allowed if CATEGORIES[cat_idx].object_class == "non_standard")
        if allowed:
            main_of[k] = mains.setdefault(ns or allowed, len(mains))
    p_clutter[main_of < 0] = 1.0
    main_cdfs = [
        _cdf(placer, "non_standard" if CATEGORIES[key[0]].object_class == "non_standard" else "standard", key)
        for key in mains
    ]
    clutter_cdf = _cdf(placer, "clutter", None)
    s0, s1 = sw.s_range
    at = s0 + gap * rng.random(n_rows)
    active = at < s1
    while active.any():
        batch = np.where(active, np.minimum(((s1 - at) / (gap + 0.3)).astype(np.int64) + 4, _MAX_BATCH), 0)
        row = np.repeat(np.arange(n_rows), batch)
        draws = rng.random((5, len(row)))
        gaps = rng.gamma(2.0, gap[row] / 2.0)
        clutter = draws[0] < p_clutter[row]
        cat, drawn = _draw(clutter, draws[1], main_of[row], main_cdfs, clutter_cdf)
        found, index, size = _pick(placer, kinds, row, cat, draws[2], max_depth[row])
        found &= drawn
        depth, wid = size[:, 0], size[:, 1]
        big = np.maximum(depth, wid)
        along = np.where(clutter, big, wid)
        half = np.where(clutter, big, depth) / 2
        step = np.where(found, along + gaps, gap[row])  # a step with nothing that fits moves on by gap_mean (> 0)
        ends = np.cumsum(step)
        before = ends - step
        first = np.minimum(np.concatenate([[0], np.cumsum(batch)[:-1]]), len(row) - 1)  # rows without steps: unused
        start = at[row] + before - np.repeat(before[first], batch)  # each row's steps from its own position
        inside = start < s1
        last = np.maximum(first + batch - 1, 0)
        done = (batch == 0) | ~inside[last]
        at = np.where(done, s1, start[last] + step[last])
        active = at < s1  # a row whose last step started inside but ended past its end is done too
        lo, hi = d0[row] + half + 0.02, d1[row] - half - 0.02
        ok = np.flatnonzero(inside & found & (hi >= lo))
        if not len(ok):
            continue
        off = lo[ok] + (hi[ok] - lo[ok]) * draws[3, ok]
        x, y, heading = cl.points_xy(start[ok] + along[ok] / 2, side * off)
        yaw = np.where(clutter[ok], -math.pi + 2 * math.pi * draws[4, ok], heading + faces[row[ok]])
        placer.note_fallback(cat[ok][index[ok] < 0])  # found, with no catalog index: a fallback box
        place_many(placer, sw, [row_spec.zone for row_spec in rows], row[ok], cat[ok], index[ok], size[ok], x, y, yaw)


def _pick(
    placer: Placer, kinds: list[str], row: np.ndarray, cat: np.ndarray, u: np.ndarray, max_depth: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`Fits.pick` for steps of rows in several zones: each zone kind's steps from its own table."""
    found = np.zeros(len(row), dtype=bool)
    index = np.full(len(row), -1, dtype=np.int64)
    size = np.zeros((len(row), 3))
    kind_of = np.array([sorted(set(kinds)).index(k) for k in kinds], dtype=np.int64)[row]
    for kind_idx, kind in enumerate(sorted(set(kinds))):
        mask = kind_of == kind_idx
        found[mask], index[mask], size[mask] = fits_for(placer.catalog, kind).pick(cat[mask], u[mask], max_depth[mask])
    return found, index, size


def _draw(
    clutter: np.ndarray,
    u: np.ndarray,
    main_of: np.ndarray,
    mains: list[tuple[np.ndarray, np.ndarray] | None],
    clutter_cdf: tuple[np.ndarray, np.ndarray] | None,
) -> tuple[np.ndarray, np.ndarray]:
    """(category index, drawn) per step: clutter steps from the clutter CDF, the others from their row's CDF."""
    cat = np.zeros(len(u), dtype=np.int64)
    drawn = np.zeros(len(u), dtype=bool)
    for mask, cdf in [(clutter, clutter_cdf)] + [
        (~clutter & (main_of == main_idx), main_cdf) for main_idx, main_cdf in enumerate(mains)
    ]:
        if cdf is not None and mask.any():
            cat[mask] = cdf[0][np.searchsorted(cdf[1], u[mask], side="right")]
            drawn |= mask
    return cat, drawn


def place_many(
    placer: Placer,
    sw: Sidewalk,
    zones: list[Zone],
    zone_of: np.ndarray,
    cat: np.ndarray,
    index: np.ndarray,
    size: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    yaw: np.ndarray,
) -> None:
    """`Placer.try_place` for a batch in order (object k in zones[zone_of[k]]): the zone and keep-out tests run on
    all at once, the overlap test against the objects placed so far (earlier ones of the batch too) one by one."""
    yl = yaw.tolist()
    cos_yaw = np.array([math.cos(yaw_k) for yaw_k in yl])
    sn = np.array([math.sin(yaw_k) for yaw_k in yl])
    depth, width = size[:, 0], size[:, 1]
    corners, pb = rects(x, y, cos_yaw, sn, depth, width)
    shapes = [placer.zone_shape(z) for z in zones]
    zb = np.array([box for _, box in shapes])[zone_of]
    cand = np.flatnonzero(
        (pb[:, 0] >= zb[:, 0]) & (pb[:, 1] >= zb[:, 1]) & (pb[:, 2] <= zb[:, 2]) & (pb[:, 3] <= zb[:, 3])
    )
    ok = np.zeros(len(x), dtype=bool)
    if len(cand):
        polys = shapely.polygons(corners[cand])
        zp = np.array([placed_idx for placed_idx, _ in shapes], dtype=object)[zone_of[cand]]
        inside = shapely.contains(zp, polys) & ~placer.occupied.keep_out_hits(polys)
        ok[cand[inside]] = True
    check, cb = rects(x, y, cos_yaw, sn, depth + GAP, width + GAP)
    keep = np.flatnonzero(ok)
    checks, cbs = check[keep].tolist(), cb[keep].tolist()
    occupied, placed = placer.occupied, []
    for k, i in enumerate(keep.tolist()):
        if occupied.clear_of_placed(checks[k], cbs[k]):
            occupied.add(checks[k], tuple(cbs[k]))
            placed.append(i)
        else:
            ok[i] = False
    for k in cat[~ok].tolist():
        placer.refused[NAMES[k]] += 1
    if not placed:
        return
    placed_idx = np.array(placed, dtype=np.int64)
    for z, depth_k, width_k in zip(
        zone_of[placed_idx].tolist(), depth[placed_idx].tolist(), width[placed_idx].tolist()
    ):
        if zones[z].kind != "building":
            placer.object_area += depth_k * width_k
    wrapped = [math.atan2(math.sin(yaw_k), math.cos(yaw_k)) for yaw_k in yaw[placed_idx].tolist()]  # (-pi, pi]
    pos, yw = round_array(np.stack([x[placed_idx], y[placed_idx]], axis=1)), round_array(np.array(wrapped))
    sz, fp = round_array(size[placed_idx]), round_array(corners[placed_idx], rows=True)
    ids = placer.catalog.table.asset_id if placer.catalog is not None else _NO_ASSETS
    objects, z, sid = placer.objects, placer.z, sw.id
    for k, (i, ci, zi) in enumerate(
        zip(index[placed_idx].tolist(), cat[placed_idx].tolist(), zone_of[placed_idx].tolist())
    ):
        objects.append(
            {
                "id": f"o{len(objects)}",
                "asset_id": ids[i] if i >= 0 else None,
                "category": NAMES[ci],
                "object_class": _CLASS[ci],
                "zone": zones[zi].kind,
                "sidewalk_id": sid,
                "position": [*pos[k], z],
                "yaw": yw[k],
                "size": sz[k],
                "footprint": fp[k],
            }
        )
