"""Walkable-network connectivity: seam patches between blocks and the crosswalks that join sidewalk groups."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import shapely
from shapely.geometry import Polygon
from shapely.strtree import STRtree

from sim.scene.geometry import clean
from sim.scene.roads import Block, Roadway

if TYPE_CHECKING:  # sidewalks imports this module's helpers; the type is all this module needs of it
    from sim.scene.sidewalks import Sidewalk

SEAM_HALF = 3.0  # m each side of a seam that a patch may cover: the width of the joint a walker gets
MIN_SHARED = 0.5  # m of common boundary for two sidewalks to count as joined (a wheelchair needs more; corners give it)


def _ending_at(block: Block, p: np.ndarray) -> Roadway | None:
    """The two-sided roadway of `block` that ends at point `p` (the socket a child block was grown on)."""
    for w in block.roadways:
        if w.sides != (1,) and float(np.hypot(*(w.centerline.points[-1] - p))) < 1e-6:
            return w
    return None


def _merge(poly: Polygon, piece: Polygon) -> Polygon:
    """`poly` grown by the touching `piece`; a closing of 1 mm bridges rounding gaps along their common edge."""
    merged = shapely.union(poly, piece).buffer(1e-3, join_style="mitre").buffer(-1e-3, join_style="mitre")
    # The opening in clean() drops the hair-thin spikes a union leaves, which rounding to 0.1 mm would make invalid.
    return clean(merged) or poly


def join_seams(blocks: list[Block], sidewalks: list[Sidewalk], roads: list[Polygon]) -> list[Polygon]:
    """Grow sidewalks across block seams so both sides of every seam stay walkable; returns the added pieces.

    Where a child block's road is wider or narrower than its parent's, the two sidewalks start at different
    offsets from the centerline and may not touch. A patch spanning both bands, a few metres each side of the
    seam, minus roads and sidewalks, fills the step; it joins the child's sidewalk (or the parent's).
    """
    by_way = {(sw.roadway.id, sw.side): sw for sw in sidewalks}
    added: list[Polygon] = []
    for b in blocks:
        if b.parent is None:
            continue
        child_way = b.roadways[0]
        p, h = child_way.centerline.points[0], float(child_way.centerline.heading[0])
        parent_way = _ending_at(blocks[b.parent], p)
        if parent_way is None:
            continue
        t = np.array([np.cos(h), np.sin(h)])
        n = np.array([-t[1], t[0]])
        for side in (1, -1):
            swc, swp = by_way.get((child_way.id, side)), by_way.get((parent_way.id, side))
            if swc is None or swp is None:
                continue
            lo = min(child_way.half_width, parent_way.half_width)
            hi = max(swc.outer, swp.outer)
            rect = Polygon([p + a * SEAM_HALF * t + side * d * n for a, d in ((-1, lo), (1, lo), (1, hi), (-1, hi))])
            near = [q for q in roads + [sw.polygon for sw in sidewalks] if q.intersects(rect)]
            patch = rect.difference(shapely.union_all(near)) if near else rect
            for piece in getattr(patch, "geoms", [patch]):
                if not isinstance(piece, Polygon) or piece.area < 0.05:
                    continue
                owner = (
                    swc if piece.distance(swc.polygon) < 1e-6 else swp if piece.distance(swp.polygon) < 1e-6 else None
                )
                if owner is None:
                    continue
                owner.polygon = _merge(owner.polygon, piece)
                added.append(piece)
    return added


def sidewalk_groups(sidewalks: list[Sidewalk]) -> list[int]:
    """Group label of every sidewalk: sidewalks sharing at least MIN_SHARED m of boundary are in one group."""
    from scipy.cluster.hierarchy import DisjointSet  # only here: importing scipy.cluster costs ~0.25 s

    groups = DisjointSet(range(len(sidewalks)))
    polys = [sw.polygon for sw in sidewalks]
    if polys:
        a, b = STRtree(polys).query(polys, predicate="dwithin", distance=1e-3)
        eps = 0.02
        grown: dict[int, Polygon] = {}
        for i, j in zip(a.tolist(), b.tolist()):
            if i < j and not groups.connected(i, j):
                if j not in grown:
                    grown[j] = polys[j].buffer(eps, join_style="mitre")
                # The overlap of one polygon with the other grown by eps is about eps times their common edge.
                if polys[i].intersection(grown[j]).area >= MIN_SHARED * eps:
                    groups.merge(i, j)
    return [int(groups[i]) for i in range(len(sidewalks))]


def connecting_picks(
    pairs: list[tuple[int, int]], chosen: list[bool], groups: list[int], order: np.ndarray
) -> list[bool]:
    """`chosen` plus the fewest candidates (tried in `order`) that join sidewalk groups not yet joined.

    `pairs` holds, per crosswalk candidate, the indices of the two sidewalks it would join.
    """
    from scipy.cluster.hierarchy import DisjointSet

    joined = DisjointSet(groups)
    out = list(chosen)
    for k, (i, j) in enumerate(pairs):
        if out[k]:
            joined.merge(groups[i], groups[j])
    for k in order.tolist():
        i, j = pairs[k]
        if not out[k] and not joined.connected(groups[i], groups[j]):
            joined.merge(groups[i], groups[j])
            out[k] = True
    return out
