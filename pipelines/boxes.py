"""Box geometry for the detect stage: non-maximum suppression and the sidewalk-overlap filter."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np


def iou_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pairwise intersection-over-union of (n, 4) and (m, 4) boxes given as x0, y0, x1, y1."""
    a, b = np.asarray(a, dtype=np.float64).reshape(-1, 4), np.asarray(b, dtype=np.float64).reshape(-1, 4)
    ix = np.clip(np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0]), 0, None)
    iy = np.clip(np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1]), 0, None)
    inter = ix * iy
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    return inter / np.maximum(area_a[:, None] + area_b[None, :] - inter, 1e-12)


def nms(boxes: np.ndarray, scores: np.ndarray, iou_threshold: float) -> np.ndarray:
    """Indices of the boxes kept by greedy NMS (class-agnostic: one object, one label), best score first."""
    boxes, scores = np.asarray(boxes, dtype=np.float64).reshape(-1, 4), np.asarray(scores, dtype=np.float64)
    # Stable sort on -score so ties keep input order: results do not depend on the sort implementation.
    order = np.argsort(-scores, kind="stable")
    keep: list[int] = []
    suppressed = np.zeros(len(boxes), dtype=bool)
    iou = iou_matrix(boxes, boxes)
    for i in order:
        if suppressed[i]:
            continue
        keep.append(int(i))
        suppressed |= iou[i] > iou_threshold
    return np.asarray(keep, dtype=np.int64)


def load_sidewalk_polygons(path: str | Path, labels: list[str]) -> list[Any]:
    """Sidewalk polygons (shapely) from a Cityscapes gtFine or Mapillary Vistas v2 polygon JSON file."""
    from shapely.geometry import Polygon

    p = Path(path)
    try:
        data = json.loads(p.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"annotation {p} is not readable JSON ({exc}); fix or remove it from the manifest") from None
    if "objects" not in data:
        raise ValueError(f"annotation {p} has no 'objects' list; expected Cityscapes or Mapillary Vistas polygon JSON")
    wanted = set(labels)
    polys = []
    for obj in data["objects"]:
        if obj.get("label") in wanted and len(obj.get("polygon", [])) >= 3:
            poly = Polygon(obj["polygon"])
            polys.append(poly if poly.is_valid else poly.buffer(0))
    return polys


def footprint(box: np.ndarray, bottom_fraction: float) -> tuple[float, float, float, float]:
    """The bottom strip of a box, where an object standing on the ground meets it (the top is occluding sky)."""
    x0, y0, x1, y1 = (float(v) for v in box)
    return x0, y1 - (y1 - y0) * bottom_fraction, x1, y1


def polygon_overlap(boxes: np.ndarray, polygons: list[Any], bottom_fraction: float) -> np.ndarray:
    """Fraction of each box's footprint strip covered by the union of the sidewalk polygons."""
    import shapely
    from shapely.geometry import box as shp_box

    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    if not polygons:
        return np.zeros(len(boxes))
    area = shapely.union_all(polygons)
    out = np.zeros(len(boxes))
    for i, b in enumerate(boxes):
        strip = shp_box(*footprint(b, bottom_fraction))
        out[i] = strip.intersection(area).area / strip.area if strip.area > 0 else 0.0
    return out


def mask_overlap(boxes: np.ndarray, mask: np.ndarray, bottom_fraction: float) -> np.ndarray:
    """Fraction of each box's footprint strip whose pixels are sidewalk in a boolean (h, w) mask."""
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    h, w = mask.shape
    out = np.zeros(len(boxes))
    for i, b in enumerate(boxes):
        x0, y0, x1, y1 = footprint(b, bottom_fraction)
        c0, c1 = int(np.clip(np.floor(x0), 0, w)), int(np.clip(np.ceil(x1), 0, w))
        r0, r1 = int(np.clip(np.floor(y0), 0, h)), int(np.clip(np.ceil(y1), 0, h))
        patch = mask[r0:r1, c0:c1]
        out[i] = float(patch.mean()) if patch.size else 0.0
    return out
