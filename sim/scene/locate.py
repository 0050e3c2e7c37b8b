"""Projection onto a polyline's segments as a numba kernel: `Polyline.locate`, which the env's route tracker calls
every step (the numpy version cost ~20 small array calls a step). Kept out of `polyline.py` so that building
scenes does not import numba.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, error_model="numpy")
def locate_on_segments(
    points: np.ndarray, seg: np.ndarray, seg_len: np.ndarray, s: np.ndarray, k0: int, k1: int, x: float, y: float
) -> tuple[float, float]:  # pragma: no cover - numba
    """Polyline.locate on segments k0..k1: each segment's closest point, the nearest one's (arc length, offset)
    (the numpy version's float operations in its order; a NaN distance wins, as np.argmin picks it)."""
    best, k = np.inf, -1
    t_best = 0.0
    for j in range(k0, k1):
        qx, qy = x - points[j, 0], y - points[j, 1]
        t = (qx * seg[j, 0] + qy * seg[j, 1]) / (seg_len[j] * seg_len[j])
        if not math.isnan(t):
            t = min(max(t, 0.0), 1.0)
        ex, ey = qx - t * seg[j, 0], qy - t * seg[j, 1]
        dist2 = ex * ex + ey * ey
        if math.isnan(dist2):
            best, k, t_best = dist2, j, t
            break
        if k < 0 or dist2 < best:
            best, k, t_best = dist2, j, t
    qx, qy = x - points[k, 0], y - points[k, 1]
    cross = seg[k, 0] * qy - seg[k, 1] * qx
    lateral = math.sqrt(best) * (1.0 if cross >= 0 else -1.0)
    return s[k] + t_best * seg_len[k], lateral
