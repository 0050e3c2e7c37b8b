"""Sidewalks (templates and zone polygons), building zones, crosswalks and curb ramps."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely
from shapely.geometry import LineString, Polygon

from kernel.config import ConfigError
from sim.scene.config import TEMPLATES
from sim.scene.geometry import clean, largest, longest_line, strip
from sim.scene.network import connecting_picks, join_seams, sidewalk_groups
from sim.scene.roads import Block, Roadway


@dataclass
class Zone:
    """One functional zone: its lateral band [d0, d1] (absolute offsets from the centerline) and clipped polygon."""

    kind: str
    d0: float
    d1: float
    polygon: Polygon

    @property
    def width(self) -> float:
        """Nominal width of the zone in metres."""
        return self.d1 - self.d0


@dataclass
class Sidewalk:
    """A sidewalk along one side of a roadway, in that roadway's (s, d) frame."""

    id: str
    road_id: str
    roadway: Roadway
    roadway_index: int
    side: int
    template: str
    polygon: Polygon
    zones: list[Zone]
    edge: LineString
    clear_path: LineString
    s_range: tuple[float, float]
    building: Zone | None = None
    outer: float = 0.0  # lateral offset of the sidewalk's outer edge (all zones at their drawn widths)
    ramps: list[Polygon] = field(default_factory=list)
    keep_out: list[Polygon] = field(default_factory=list)

    def zone(self, kind: str) -> Zone | None:
        """The zone of `kind`, or None when the template lacks it."""
        return next((z for z in self.zones if z.kind == kind), None)

    @property
    def side_name(self) -> str:
        """'left' or 'right' of the roadway's direction of travel."""
        return "left" if self.side > 0 else "right"


@dataclass
class Crosswalk:
    """A zebra crossing over a roadway joining its two sidewalks."""

    id: str
    road_id: str
    polygon: Polygon
    width: float
    ends: list[np.ndarray]
    sidewalks: list[Sidewalk]
    ramps: list[tuple[str, Polygon]]


def _band(w: Roadway, side: int, d0: float, d1: float) -> Polygon:
    return strip(w.centerline, side * d0, side * d1)


class _Taken:
    """Polygons already claimed (roads, sidewalks, buildings), clipped against by bounding-box neighbourhood."""

    def __init__(self, polys: list[Polygon]) -> None:
        self.polys = list(polys)
        self.bounds = [p.bounds for p in self.polys]

    def add(self, poly: Polygon) -> None:
        """Claim `poly`."""
        self.polys.append(poly)
        self.bounds.append(poly.bounds)

    def clip(self, raw: Polygon) -> Polygon | None:
        """`raw` minus every claimed polygon whose interior it enters (cleaned), or `raw` itself when none does."""
        return self.clip_cut(raw)[0]

    def clip_cut(self, raw: Polygon) -> tuple[Polygon | None, shapely.Geometry | None]:
        """`clip` plus the claimed area that was cut away (None when `raw` came back untouched)."""
        x0, y0, x1, y1 = raw.bounds
        near = [p for p, b in zip(self.polys, self.bounds) if b[0] < x1 and b[2] > x0 and b[1] < y1 and b[3] > y0]
        if near:
            # Only interior overlaps cut; a band merely touching its own road needs neither difference nor clean-up.
            hit = shapely.relate_pattern(raw, near, "2********")
            near = [p for p, h in zip(near, hit) if h]
        if not near:
            return raw, None
        cut = near[0] if len(near) == 1 else shapely.union_all(near)
        return clean(raw.difference(cut)), cut


def build_sidewalks(blocks: list[Block], cfg: dict[str, Any], rng: np.random.Generator) -> list[Sidewalk]:
    """Sidewalks on every roadway side; earlier sidewalks claim shared corners, so no two overlap."""
    roads = [b.polygon for b in blocks] + [b.island for b in blocks if b.island is not None]
    taken = _Taken(roads)
    out: list[Sidewalk] = []
    raw_buildings: list[tuple[Sidewalk, float, float, Polygon]] = []
    for b in blocks:
        k = 0
        for wi, w in enumerate(b.roadways):
            for side in w.sides:
                t = cfg["templates"][int(rng.integers(len(cfg["templates"])))]
                widths = [(kind, float(rng.uniform(lo, hi))) for kind, lo, hi in TEMPLATES[t]]
                d = w.half_width
                bands = []
                for kind, wd in widths:
                    bands.append((kind, d, d + wd))
                    d += wd
                raw = _band(w, side, w.half_width, d)
                poly, cut = taken.clip_cut(raw)
                bdepth = float(rng.uniform(*cfg["building_depth"]))
                if poly is None or poly.area < 4.0:
                    continue
                zones = []
                for kind, d0, d1 in bands:
                    zb = _band(w, side, d0, d1)
                    # A zone band the cut does not enter is already exact; only cut zones need the overlay and clean-up.
                    hit = cut is not None and bool(shapely.relate_pattern(zb, cut, "2********"))
                    zp = clean(zb.intersection(poly)) if hit else zb
                    if zp is not None:
                        zones.append(Zone(kind, d0, d1, zp))
                clear = next((z for z in zones if z.kind == "clear"), None)
                if clear is None:
                    continue
                cl = w.centerline
                mid = next(((a + c) / 2 for kind, a, c in bands if kind == "clear"))
                cpath = longest_line(LineString(cl.offset(side * mid)).intersection(clear.polygon))
                edge = longest_line(LineString(cl.offset(side * w.half_width)).intersection(poly.buffer(1e-6)))
                if cpath is None or edge is None or cpath.length < 2.0:
                    continue
                ends = cl.project(np.asarray(edge.coords)[[0, -1]])
                sw = Sidewalk(
                    f"{b.id}-s{k}",
                    b.id,
                    w,
                    wi,
                    side,
                    t,
                    poly,
                    zones,
                    edge,
                    cpath,
                    (float(min(ends)), float(max(ends))),
                    outer=d,
                )
                k += 1
                out.append(sw)
                taken.add(poly)
                if cfg["buildings"]:
                    raw_buildings.append((sw, d, d + bdepth, _band(w, side, d, d + bdepth)))
    # Seam patches join sidewalks of neighbouring blocks whose roads differ in width; buildings yield to them.
    for patch in join_seams(blocks, out, roads):
        taken.add(patch)
    for sw, d0, d1, raw in raw_buildings:
        # Buildings come last: they yield to every sidewalk and to earlier buildings.
        bp = taken.clip(raw)
        if bp is not None and bp.area > 4.0:
            sw.building = Zone("building", d0, d1, bp)
            taken.add(bp)
    return out


def build_crosswalks(
    blocks: list[Block], sidewalks: list[Sidewalk], cfg: dict[str, Any], rng: np.random.Generator
) -> list[Crosswalk]:
    """Crosswalk candidates at both ends of every two-sided roadway; density or the explicit list picks them."""
    by_way: dict[str, dict[int, Sidewalk]] = {}
    for sw in sidewalks:
        by_way.setdefault(sw.roadway.id, {})[sw.side] = sw
    cw_w = float(cfg["crosswalk_width"])
    candidates: list[tuple[str, Block, Roadway, float, Sidewalk, Sidewalk]] = []
    for b in blocks:
        for w in b.roadways:
            pair = by_way.get(w.id, {})
            if 1 not in pair or -1 not in pair:
                continue
            left, right = pair[1], pair[-1]
            lo = max(left.s_range[0], right.s_range[0]) + cw_w / 2 + 0.5
            hi = min(left.s_range[1], right.s_range[1]) - cw_w / 2 - 0.5
            for end in w.crosswalk_ends:
                s = lo if end == "start" else hi
                if hi - lo < (cw_w + 1.0 if len(w.crosswalk_ends) > 1 else 0.0):
                    continue
                candidates.append((f"{w.id}:{end}", b, w, s, left, right))
    names = [c[0] for c in candidates]
    if cfg["crosswalks"] is not None:
        unknown = [c for c in cfg["crosswalks"] if c not in names]
        if unknown:
            raise ConfigError(f"unknown crosswalk candidate(s) {unknown}; candidates of this scene: {', '.join(names)}")
        chosen = [c in cfg["crosswalks"] for c in names]
    else:
        draws = rng.random(len(candidates))
        chosen = list(draws < float(cfg["crosswalk_density"]))
        if cfg["connect_crosswalks"] and candidates:
            # Without these extra crossings, streets whose draws all failed would split the network in two.
            index = {id(sw): i for i, sw in enumerate(sidewalks)}
            pairs = [(index[id(c[4])], index[id(c[5])]) for c in candidates]
            chosen = connecting_picks(pairs, chosen, sidewalk_groups(sidewalks), rng.permutation(len(candidates)))
    out: list[Crosswalk] = []
    ramp_depth = float(cfg["ramp_depth"])
    for (_name, b, w, s, left, right), pick in zip(candidates, chosen):
        if not pick:
            continue
        cl, hw = w.centerline, w.half_width
        poly = strip(cl, -hw, hw, s - cw_w / 2, s + cw_w / 2)
        ends_xy, _ = cl.to_world(np.array([s, s]), np.array([hw, -hw]))
        ramps = []
        for sw in (left, right):
            rp = largest(
                strip(cl, sw.side * hw, sw.side * (hw + ramp_depth), s - cw_w / 2, s + cw_w / 2).intersection(
                    sw.polygon
                )
            )
            if rp is not None:
                ramps.append((sw.id, rp))
                sw.ramps.append(rp)
            # Keep the way from the ramp to the clear path free of objects.
            clear = sw.zone("clear")
            reach = clear.d1 if clear is not None else hw + ramp_depth
            sw.keep_out.append(strip(cl, sw.side * hw, sw.side * reach, s - cw_w / 2 - 0.3, s + cw_w / 2 + 0.3))
        out.append(Crosswalk(f"c{len(out)}", b.id, poly, cw_w, [ends_xy[0], ends_xy[1]], [left, right], ramps))
    return out
