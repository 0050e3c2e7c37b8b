"""The one hand-built test scene: a straight street along x (road |y| < lane_width, one lane each way) with a
sidewalk on both sides, crosswalks with curb ramps, and street furniture: a `curbside.scene/1` spec
(docs/scene_spec.md) for tests that must not depend on the scene generator.

`street()` is the simulator tests' scene: wide sidewalks with buildings, one crosswalk, rows of lamps and benches
and a trash bin on the clear path. The agent tests narrow it with `NARROW` (one furnishing and one clear zone, no
buildings, benches and bollards scattered along the curbs) and put a crosswalk 8 m in from each end.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from shapely.geometry import Polygon

from sim.scene.grid import CROSSWALK, RAMP, SIDEWALK, encode_walkable, paint

CURB = 0.15  # curb height, m: objects stand on the sidewalk top
# Zones outward from the curb, (kind, width in m); a building zone lies beyond the sidewalk's polygon.
WIDE_ZONES = (("furnishing", 1.6), ("clear", 2.8), ("frontage", 0.6), ("building", 4.0))
NARROW_ZONES = (("furnishing", 1.2), ("clear", 2.8))
# The agent tests' street (pass `crosswalks` too): a 3.5 m lane each way and a 4 m sidewalk of two zones.
NARROW: dict[str, Any] = {"lane_width": 3.5, "zones": NARROW_ZONES, "ramp_depth": 1.0, "furniture": "scattered"}


def _rect(x0: float, y0: float, x1: float, y1: float) -> list[list[float]]:
    return [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]


def _band(length: float, a: float, b: float) -> list[list[float]]:
    """The rectangle along the street between lateral offsets a and b (either order)."""
    return _rect(0.0, min(a, b), length, max(a, b))


def _object(
    k: int,
    category: str,
    object_class: str,
    zone: str,
    sidewalk: int,
    x: float,
    y: float,
    yaw: float,
    size: tuple[float, float, float],
) -> dict[str, Any]:
    """One object of `size` (depth along its yaw, width, height) at (x, y); footprint to 0.1 mm like the generator."""
    c, s = math.cos(yaw), math.sin(yaw)
    corners = [
        (-size[0] / 2, -size[1] / 2),
        (size[0] / 2, -size[1] / 2),
        (size[0] / 2, size[1] / 2),
        (-size[0] / 2, size[1] / 2),
    ]
    return {
        "id": f"o{k}",
        "asset_id": None,
        "category": category,
        "object_class": object_class,
        "zone": zone,
        "sidewalk_id": f"r0-s{sidewalk}",
        "position": [x, y, CURB],
        "yaw": yaw,
        "size": list(size),
        "footprint": [[round(x + c * px - s * py, 4), round(y + s * px + c * py, 4)] for px, py in corners],
    }


def _rows(length: float, furnishing: float, clear: float) -> list[dict[str, Any]]:
    """Street lamps every 6 m along the left curb, benches (turned along the street) beside them on the right,
    and one trash bin on the left clear path at x = 15 m."""
    out: list[dict[str, Any]] = []
    for x in np.arange(3.0, length, 6.0):
        out.append(
            _object(len(out), "street_lamp", "standard", "furnishing", 1, float(x), furnishing, 0.0, (0.25, 0.25, 4.0))
        )
        out.append(
            _object(
                len(out),
                "bench",
                "non_standard",
                "furnishing",
                0,
                float(x) + 1.5,
                -furnishing,
                math.pi / 2,
                (0.6, 1.6, 0.9),
            )
        )
    out.append(_object(len(out), "trash_bin", "clutter", "clear", 1, 15.0, clear, 0.3, (0.6, 0.6, 1.0)))
    return out


def _scattered(length: float, furnishing: float, n: int, rng: np.random.Generator) -> list[dict[str, Any]]:
    """`n` benches and bollards alternating between the curbs, evenly spaced 14 m clear of the ends, jittered."""
    xs = np.linspace(14.0, length - 14.0, max(n // 2, 1))
    out = []
    for k in range(n):
        side = 1 if k % 2 else -1
        x = float(xs[(k // 2) % len(xs)] + rng.uniform(-1.5, 1.5))
        depth, width = (0.6, 1.6) if k % 3 else (0.5, 0.5)
        out.append(
            _object(
                k,
                "bench" if k % 3 else "bollard",
                "non_standard",
                "furnishing",
                int(side > 0),
                x,
                side * furnishing,
                0.0,
                (width, depth, 0.8),
            )
        )
    return out


def street(
    length: float = 60.0,
    *,
    lane_width: float = 4.0,
    zones: Sequence[tuple[str, float]] = WIDE_ZONES,
    crosswalks: Sequence[float] = (29.5,),
    ramp_depth: float = 1.2,
    furniture: str = "rows",
    n_objects: int = 8,
    seed: int = 0,
    res: float = 0.25,
) -> dict[str, Any]:
    """The straight-street spec: sidewalk r0-s0 on the right (y < 0), r0-s1 on the left, a 3 m crosswalk centred
    on each x of `crosswalks`; furniture "rows" (lamps, benches, a bin) or "scattered" (`n_objects`, from `seed`)."""
    if length < 30.0:
        raise ValueError(f"test street length {length} m is too short; use at least 30 m")
    edges = np.round(lane_width + np.cumsum([0.0] + [w for _, w in zones]), 4)  # zone edges from the curb out
    outer = float(edges[-1])
    walk = float(max(e for (kind, _), e in zip(zones, edges[1:]) if kind != "building"))
    mid = {kind: float(round((a + b) / 2, 4)) for (kind, _), a, b in zip(zones, edges[:-1], edges[1:])}
    sidewalks = []
    for k, sign in enumerate((-1.0, 1.0)):
        sidewalks.append(
            {
                "id": f"r0-s{k}",
                "road_id": "r0",
                "side": "left" if sign > 0 else "right",
                "template": "c",
                "polygon": _band(length, sign * lane_width, sign * walk),
                "edge": [[0.0, sign * lane_width], [length, sign * lane_width]],
                "zones": [
                    {"kind": kind, "polygon": _band(length, sign * float(a), sign * float(b)), "width": width}
                    for (kind, width), a, b in zip(zones, edges[:-1], edges[1:])
                ],
                "clear_path": [[0.0, sign * mid["clear"]], [length, sign * mid["clear"]]],
            }
        )
    cws = [
        {
            "id": f"c{k}",
            "road_id": "r0",
            "polygon": _rect(xc - 1.5, -lane_width, xc + 1.5, lane_width),
            "width": 3.0,
            "ends": [[xc, -lane_width], [xc, lane_width]],
            "sidewalks": ["r0-s0", "r0-s1"],
            "ramps": [
                {"sidewalk_id": "r0-s0", "polygon": _rect(xc - 1.5, -lane_width - ramp_depth, xc + 1.5, -lane_width)},
                {"sidewalk_id": "r0-s1", "polygon": _rect(xc - 1.5, lane_width, xc + 1.5, lane_width + ramp_depth)},
            ],
        }
        for k, xc in enumerate(float(x) for x in crosswalks)
    ]
    if furniture == "rows":
        objects = _rows(length, mid["furnishing"], mid["clear"])
    elif furniture == "scattered":
        objects = _scattered(length, mid["furnishing"], n_objects, np.random.default_rng(seed))
    else:
        raise ValueError(f"furniture {furniture!r}: use 'rows' or 'scattered'")
    origin = (0.0, -outer)
    cells = np.zeros((round(2 * outer / res), round(length / res)), dtype=np.uint8)
    for sw in sidewalks:
        paint(cells, origin, res, Polygon(sw["polygon"]), SIDEWALK)
    for cw in cws:
        paint(cells, origin, res, Polygon(cw["polygon"]), CROSSWALK)
        for ramp in cw["ramps"]:
            paint(cells, origin, res, Polygon(ramp["polygon"]), RAMP)
    return {
        "version": "curbside.scene/1",
        "seed": seed,
        "config": {"test_street": True, "length": length},
        "catalog": None,
        "bounds": [0.0, -outer, length, outer],
        "curb_height": CURB,
        "roads": [
            {
                "id": "r0",
                "block": "S",
                "polygon": _band(length, -lane_width, lane_width),
                "centerlines": [[[0.0, 0.0], [length, 0.0]]],
                "lanes": 1,
                "lane_width": lane_width,
                "lane_lines": [[[0.0, 0.0], [length, 0.0]]],
            }
        ],
        "sidewalks": sidewalks,
        "crosswalks": cws,
        "objects": objects,
        "walkable": encode_walkable(cells, origin, res),
        "stats": {"objects": len(objects)},
    }
