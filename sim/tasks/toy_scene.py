"""A tiny hand-built `curbside.scene/1` spec (one straight road, two sidewalks with buildings, a crosswalk with
curb ramps, a row of lamps and benches, one trash bin on the clear path): for tests and examples that must
not depend on the scene generator."""

from __future__ import annotations

import math

import numpy as np

from sim.scene.grid import encode_walkable


def _rect(x0: float, y0: float, x1: float, y1: float) -> list[list[float]]:
    return [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]


def _footprint(x: float, y: float, yaw: float, d: float, w: float) -> list[list[float]]:
    c, s = math.cos(yaw), math.sin(yaw)
    pts = [(-d / 2, -w / 2), (d / 2, -w / 2), (d / 2, w / 2), (-d / 2, w / 2)]
    return [[round(x + c * px - s * py, 4), round(y + s * px + c * py, 4)] for px, py in pts]


def straight_street(length: float = 60.0) -> dict:
    """A hand-built straight-road scene: sidewalks y in [4, 9] and [-9, -4], crosswalk at x in [28, 31]."""
    res, y0 = 0.25, -13.0
    rows, cols = int(26 / res), int(length / res)
    labels = np.zeros((rows, cols), dtype=np.uint8)
    yc = y0 + (np.arange(rows) + 0.5) * res
    xc = (np.arange(cols) + 0.5) * res
    side = (np.abs(yc) > 4) & (np.abs(yc) < 9)
    labels[side, :] = 1
    cross_x = (xc > 28) & (xc < 31)
    labels[np.ix_(np.abs(yc) < 4, cross_x)] = 2
    labels[np.ix_((np.abs(yc) > 4) & (np.abs(yc) < 5.2), cross_x)] = 3
    sidewalks = []
    for sid, sign in (("r0-s0", 1), ("r0-s1", -1)):
        ys = sorted([4 * sign, 9 * sign])
        zones = [
            {"kind": "furnishing", "polygon": _rect(0, *sorted([4 * sign, 5.6 * sign])[:1], length, sorted([4 * sign, 5.6 * sign])[1]), "width": 1.6},
            {"kind": "clear", "polygon": _rect(0, min(5.6 * sign, 8.4 * sign), length, max(5.6 * sign, 8.4 * sign)), "width": 2.8},
            {"kind": "frontage", "polygon": _rect(0, min(8.4 * sign, 9 * sign), length, max(8.4 * sign, 9 * sign)), "width": 0.6},
            {"kind": "building", "polygon": _rect(0, min(9 * sign, 13 * sign), length, max(9 * sign, 13 * sign)), "width": 4.0},
        ]
        sidewalks.append({
            "id": sid, "road_id": "r0", "side": "left" if sign > 0 else "right", "template": "c",
            "polygon": _rect(0, ys[0], length, ys[1]),
            "edge": [[0.0, 4.0 * sign], [length, 4.0 * sign]],
            "zones": zones,
            "clear_path": [[0.0, 7.0 * sign], [length, 7.0 * sign]],
        })
    objects = []
    k = 0
    for x in np.arange(3.0, length, 6.0):
        objects.append({"id": f"o{k}", "asset_id": None, "category": "street_lamp", "object_class": "standard",
                        "zone": "furnishing", "sidewalk_id": "r0-s0", "position": [float(x), 4.8, 0.15], "yaw": 0.0,
                        "size": [0.25, 0.25, 4.0], "footprint": _footprint(float(x), 4.8, 0.0, 0.25, 0.25)})
        k += 1
        objects.append({"id": f"o{k}", "asset_id": None, "category": "bench", "object_class": "non_standard",
                        "zone": "furnishing", "sidewalk_id": "r0-s1", "position": [float(x) + 1.5, -4.8, 0.15],
                        "yaw": math.pi / 2, "size": [0.6, 1.6, 0.9],
                        "footprint": _footprint(float(x) + 1.5, -4.8, math.pi / 2, 0.6, 1.6)})
        k += 1
    objects.append({"id": f"o{k}", "asset_id": None, "category": "trash_bin", "object_class": "clutter",
                    "zone": "clear", "sidewalk_id": "r0-s0", "position": [15.0, 7.0, 0.15], "yaw": 0.3,
                    "size": [0.6, 0.6, 1.0], "footprint": _footprint(15.0, 7.0, 0.3, 0.6, 0.6)})
    return {
        "version": "curbside.scene/1", "seed": 0, "config": {}, "catalog": None,
        "bounds": [0.0, -13.0, length, 13.0], "curb_height": 0.15,
        "roads": [{"id": "r0", "block": "S", "polygon": _rect(0, -4, length, 4),
                   "centerlines": [[[0.0, -1.75], [length, -1.75]], [[length, 1.75], [0.0, 1.75]]],
                   "lanes": 2, "lane_width": 3.5, "lane_lines": [[[0.0, 0.0], [length, 0.0]]]}],
        "sidewalks": sidewalks,
        "crosswalks": [{"id": "c0", "road_id": "r0", "polygon": _rect(28, -4, 31, 4), "width": 3.0,
                        "ends": [[29.5, 4.0], [29.5, -4.0]], "sidewalks": ["r0-s0", "r0-s1"],
                        "ramps": [{"sidewalk_id": "r0-s0", "polygon": _rect(28, 4, 31, 5.2)},
                                  {"sidewalk_id": "r0-s1", "polygon": _rect(28, -5.2, 31, -4)}]}],
        "objects": objects,
        "walkable": encode_walkable(labels, (0.0, y0), res),
        "stats": {"objects": len(objects)},
    }
