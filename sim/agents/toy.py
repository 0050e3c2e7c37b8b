"""A small hand-built scene spec (one straight street, two sidewalks, two crosswalks) for tests and benchmarks.

It follows docs/scene_spec.md so the agent engine can be exercised without the scene generator, the way
PettingZoo ships its conformance fixtures inside the package.
"""

from __future__ import annotations

import base64
import zlib
from typing import Any

import numpy as np
from shapely.geometry import Polygon

from sim.scene.grid import paint


def _rect(x0: float, y0: float, x1: float, y1: float) -> list[list[float]]:
    return [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]


def toy_street_spec(length: float = 60.0, seed: int = 0, n_objects: int = 8, res: float = 0.25) -> dict[str, Any]:
    """Return a straight-street scene spec: road |y| < 3.5 m, sidewalks 3.5 <= |y| <= 7.5 m, crosswalks near both ends."""
    if length < 30.0:
        raise ValueError(f"toy street length {length} m is too short; use at least 30 m")
    rng = np.random.default_rng(seed)
    half_road, walk = 3.5, 4.0
    road = _rect(0.0, -half_road, length, half_road)
    sidewalks = []
    for k, (side, y0, y1, curb) in enumerate((("right", -half_road - walk, -half_road, -half_road),
                                             ("left", half_road, half_road + walk, half_road))):
        sidewalks.append({
            "id": f"r0-s{k}", "road_id": "r0", "side": side, "template": "a",
            "polygon": _rect(0.0, y0, length, y1),
            "edge": [[0.0, curb], [length, curb]],
            "zones": [{"kind": "furnishing", "polygon": _rect(0.0, min(curb, np.sign(curb) * 4.7), length,
                                                             max(curb, np.sign(curb) * 4.7)), "width": 1.2},
                      {"kind": "clear", "polygon": _rect(0.0, min(y0, y1) if curb < 0 else 4.7, length,
                                                         -4.7 if curb < 0 else y1), "width": 2.8}],
            "clear_path": [[0.0, float(np.sign(curb) * 6.1)], [length, float(np.sign(curb) * 6.1)]],
        })
    crosswalks = []
    for k, xc in enumerate((8.0, length - 8.0)):
        crosswalks.append({
            "id": f"c{k}", "road_id": "r0", "polygon": _rect(xc - 1.5, -half_road, xc + 1.5, half_road), "width": 3.0,
            "ends": [[xc, -half_road], [xc, half_road]], "sidewalks": ["r0-s0", "r0-s1"],
            "ramps": [{"sidewalk_id": "r0-s0", "polygon": _rect(xc - 1.5, -half_road - 1.0, xc + 1.5, -half_road)},
                      {"sidewalk_id": "r0-s1", "polygon": _rect(xc - 1.5, half_road, xc + 1.5, half_road + 1.0)}],
        })
    objects = []
    # Furnishing-zone objects spaced along both curbs, clear of the crosswalk ramps.
    xs = np.linspace(14.0, length - 14.0, max(n_objects // 2, 1))
    for k in range(n_objects):
        side = 1.0 if k % 2 else -1.0
        x = float(xs[(k // 2) % len(xs)] + rng.uniform(-1.5, 1.5))
        y = side * 4.1
        d, w = (0.6, 1.6) if k % 3 else (0.5, 0.5)
        objects.append({
            "id": f"o{k}", "asset_id": None, "category": "bench" if k % 3 else "bollard",
            "object_class": "non_standard", "zone": "furnishing", "sidewalk_id": f"r0-s{int(side > 0)}",
            "position": [x, y, 0.15], "yaw": 0.0, "size": [w, d, 0.8],
            "footprint": _rect(x - w / 2, y - d / 2, x + w / 2, y + d / 2),
        })
    origin = np.array([0.0, -half_road - walk])
    shape = (int(round(2 * (half_road + walk) / res)), int(round(length / res)))
    cells = np.zeros(shape, dtype=np.uint8)
    for sw in sidewalks:
        paint(cells, tuple(origin), res, Polygon(sw["polygon"]), 1)
    for cw in crosswalks:
        paint(cells, tuple(origin), res, Polygon(cw["polygon"]), 2)
        for ramp in cw["ramps"]:
            paint(cells, tuple(origin), res, Polygon(ramp["polygon"]), 3)
    return {
        "version": "curbside.scene/1", "seed": seed, "config": {"toy": True, "length": length}, "catalog": None,
        "bounds": [0.0, -half_road - walk, length, half_road + walk], "curb_height": 0.15,
        "roads": [{"id": "r0", "block": "S", "polygon": road, "centerlines": [[[0.0, 0.0], [length, 0.0]]],
                   "lanes": 1, "lane_width": 3.5, "lane_lines": [[[0.0, 0.0], [length, 0.0]]]}],
        "sidewalks": sidewalks, "crosswalks": crosswalks, "objects": objects,
        "walkable": {"origin": origin.tolist(), "resolution": res, "shape": list(shape), "encoding": "zlib+base64:uint8",
                     "legend": {"0": "not walkable", "1": "sidewalk", "2": "crosswalk", "3": "curb ramp"},
                     "cells": base64.b64encode(zlib.compress(cells.tobytes())).decode("ascii")},
        "stats": {"objects": len(objects)},
    }
