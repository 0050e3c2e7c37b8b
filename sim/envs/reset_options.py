"""`reset(options=...)` of the PointNav-family envs, checked like a config: a dict of known keys and finite points.

The one option pair is {"start": [x, y], "goal": [x, y]}: the route is planned between them instead of drawn (the
batched env also takes one pair per env, shape [num_envs, 2]).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

RESET_OPTIONS = ("start", "goal")
EXAMPLE = "{'start': [x, y], 'goal': [x, y]}"


def check_reset_options(options: Any, num_envs: int | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """(start, goal) of reset `options` as float arrays, or None when there are none; a ValueError naming the problem
    for anything else. With `num_envs` (the batched env) each point may also be one [x, y] per env."""
    if options is None:
        return None
    if not isinstance(options, Mapping):
        raise ValueError(f"reset options must be a dict such as {EXAMPLE}, got {type(options).__name__}")
    unknown = sorted(str(k) for k in set(options) - set(RESET_OPTIONS))
    if unknown:
        raise ValueError(f"unknown reset option(s) {unknown}; valid: {', '.join(RESET_OPTIONS)}")
    if not options:
        return None
    if set(options) != set(RESET_OPTIONS):
        raise ValueError(f"reset options need both 'start' and 'goal' ([x, y] each), or neither: {EXAMPLE}")
    shapes = [(2,)] + ([(num_envs, 2)] if num_envs is not None else [])
    points = []
    for key in RESET_OPTIONS:
        value = options[key]
        try:
            point = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            point = None
        if point is None or point.shape not in shapes or isinstance(value, (str, bytes)):
            want = " or one per env" if num_envs is not None else ""
            raise ValueError(f"reset option {key!r} must be [x, y] in metres{want}, got {str(value)[:60]!r}")
        if not np.isfinite(point).all():
            raise ValueError(f"reset option {key!r} must hold finite numbers, got {point.tolist()}")
        points.append(point)
    return points[0], points[1]
